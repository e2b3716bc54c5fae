"""Remote devices without a network: the host, the proxies and the values between them.

A mission whose robot's devices are proxies (every call one request through the wire's fields,
``DirectDeviceLink``) must leave the local run's trace byte for byte: readings, arrays and
floats arrive exactly, and calls reach the simulated sensors in the same order.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from botstage.missions.runner import run
from botstage.robots.backend import BackendOptions, OpenRequest
from botstage.robots.backend_registry import BackendRegistry
from botstage.robots.interfaces import INTERFACES, LaserScan, OdometryReading, Pose2D, Twist2D
from botstage.robots.remote import values
from botstage.robots.remote.devices import (
    DeviceHost,
    DirectDeviceLink,
    RemoteDeviceError,
    members_json,
    members_of,
    remote_devices,
)
from botstage.robots.sim.kind import SimKind

ROOT = Path(__file__).resolve().parent.parent


def test_readings_and_arrays_cross_exactly() -> None:
    scan = LaserScan(1.5, -1.0, 0.011, 0.05, 8.0, np.array([1.0, np.inf, 0.1 + 0.2]))
    odom = OdometryReading(2.0, Pose2D(1.0, 2.0, 0.3), Twist2D(0.1, -0.2), np.eye(3) * 1e-3)
    back = values.loads(values.dumps([scan, odom, np.arange(6, dtype=np.int16).reshape(2, 3)]))
    assert type(back[0]) is LaserScan and back[0].ranges.tobytes() == scan.ranges.tobytes()
    assert back[1].pose == odom.pose and np.array_equal(back[1].covariance, odom.covariance)
    assert back[2].dtype == np.int16 and back[2].shape == (2, 3)


def test_object_arrays_and_unknown_classes_do_not_cross() -> None:
    with pytest.raises(values.ValueCodecError, match="array of object"):
        values.dumps(np.array([object()]))
    with pytest.raises(values.ValueCodecError, match="a PosixPath cannot be sent"):
        values.dumps(Path("/etc/passwd"))
    with pytest.raises(values.ValueCodecError):
        values.loads('{"$reading": ["Popen", {}]}')


class Speaker:
    spoken: list[str]

    def __init__(self) -> None:
        self.spoken = []
        self.volume = 0.5

    def say(self, text: str) -> None:
        if not text:
            raise ValueError("nothing to say")
        self.spoken.append(text)

    def busy(self) -> bool:
        return bool(self.spoken)

    def jam(self) -> None:
        class Jammed(Exception):
            pass

        raise Jammed("the cone is stuck")


def proxies(devices: dict[str, Any]) -> dict[str, Any]:
    host = DeviceHost(devices)
    return remote_devices(DirectDeviceLink(host, "robot_pc"), members_of(members_json(host.members)))


def test_proxies_offer_what_the_device_has_and_raise_what_it_raised() -> None:
    real = Speaker()
    speaker = proxies({"speaker": real})["speaker"]
    assert isinstance(speaker, INTERFACES["speaker"]) and not hasattr(speaker, "play")
    speaker.say("hello")
    assert real.spoken == ["hello"] and speaker.busy() is True and speaker.volume == 0.5
    with pytest.raises(ValueError, match=r"^nothing to say$"):
        speaker.say("")
    with pytest.raises(RemoteDeviceError, match="Jammed: the cone is stuck"):
        speaker.jam()
    assert "robot_pc" in repr(speaker)


def test_a_host_refuses_private_and_unknown_members() -> None:
    host = DeviceHost({"speaker": Speaker()})
    assert host.answer("speaker", "_lock", "")[1] == "AttributeError"
    assert host.answer("camera", "frame", "")[1:] == (
        "LookupError",
        "this robot has no 'camera' interface (it has: speaker)",
    )


class ProxiedSim(SimKind):
    """The simulator, its devices seen through proxies as a mission in another process sees them."""

    name = "proxied_sim"
    calls: dict[str, int] = {}

    def open(self, request: OpenRequest, options: BackendOptions) -> Any:
        backend = super().open(request, options)
        host = DeviceHost(backend.devices)
        counted = CountingLink(host, self.calls)
        backend.devices = remote_devices(counted, members_of(members_json(host.members)))
        return backend


class CountingLink(DirectDeviceLink):
    def __init__(self, host: DeviceHost, calls: dict[str, int]) -> None:
        super().__init__(host, "robot_pc")
        self.calls = calls

    def call(self, interface: str, member: str, args_json: str) -> tuple[str, str, str]:
        self.calls[interface] = self.calls.get(interface, 0) + 1
        return super().call(interface, member, args_json)


@pytest.mark.parametrize(
    ("mission", "until"), [("peoplebot_entertainer.yaml", 240.0), ("chefbot_delivery.yaml", 120.0)]
)
def test_a_mission_on_remote_devices_leaves_the_local_runs_trace(tmp_path: Path, mission: str, until: float) -> None:
    backends = BackendRegistry.default()
    backends.register(ProxiedSim)
    ProxiedSim.calls = {}
    run(ROOT / "missions" / "examples" / mission, seed=5, until=until, out=tmp_path / "local")
    run(
        ROOT / "missions" / "examples" / mission,
        seed=5,
        until=until,
        out=tmp_path / "remote",
        backend="proxied_sim",
        backends=backends,
    )
    assert {"drive", "odometry", "laser"} <= set(ProxiedSim.calls), ProxiedSim.calls
    assert (tmp_path / "remote/trace.jsonl").read_bytes() == (tmp_path / "local/trace.jsonl").read_bytes()
    summaries = [json.loads((tmp_path / f"{r}/summary.json").read_text()) for r in ("local", "remote")]
    assert summaries[0]["counters"] == summaries[1]["counters"]
