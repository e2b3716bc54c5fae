"""missions/examples/gesture_demo.yaml over the emulators, against the simulator's run.

With ``--backend emulator`` every byte takes the real path: the emulated Arduino plays the book's
sketch on a pty (rosserial, its scripted hand on a wall clock), the rosserial driver reads it, the
gesture_drive skill converts it, and Chefbot's driver sends the speeds to the emulated Launchpad,
whose firmware moves the simulated robot, in real time. The run cannot be the simulator's byte
for byte (the hand is sampled on the wall clock), so what is compared is what the demo's
scenarios say of the simulator's run and what does not depend on timing: the outcome and the
calls, every sample the Arduino sent counted once, about as many as on the simulator, about the
same distance, the same motions in the same order (forward, back, left, right), and the robot
stopped at the end.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import pytest

from botstage.missions.runner import run

ROOT = Path(__file__).resolve().parent.parent
DEMO = ROOT / "missions" / "examples" / "gesture_demo.yaml"


def events(folder: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in (folder / "trace.jsonl").read_text(encoding="utf-8").splitlines()]


def calls(folder: Path) -> dict[str, int]:
    found: dict[str, int] = {}
    for event in events(folder):
        if event["ev"] == "skill_start":
            found[event["skill"]] = found.get(event["skill"], 0) + 1
    return found


def motions(folder: Path) -> list[str]:
    """The hand's motions as the robot's true path shows them, in the order they began."""
    with (folder / "trajectory.csv").open(newline="") as rows:
        path = [(float(r["t"]), float(r["x"]), float(r["theta"])) for r in csv.DictReader(rows)]
    _, x0, _ = path[0]
    began: dict[str, float] = {}
    for t, x, theta in path:
        if x - x0 > 0.05:
            began.setdefault("forward", t)
        if "forward" in began and x - x0 < 0.01:
            began.setdefault("back", t)
        if theta > 0.3:
            began.setdefault("left", t)
        if theta < -1.0:
            began.setdefault("right", t)
    return sorted(began, key=began.__getitem__)


def test_the_gesture_demo_over_the_emulators_drives_chefbot_as_on_the_simulator(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from botstage.robots.emulators import backend as emulator_backend
    from botstage.robots.emulators import imu_arduino

    made: dict[str, list[Any]] = {"board": [], "glove": []}

    def keeping(cls: type, kind: str) -> None:
        real_init = cls.__init__

        def init(self: Any, *args: Any, **kwargs: Any) -> None:
            real_init(self, *args, **kwargs)
            made[kind].append(self)

        monkeypatch.setattr(cls, "__init__", init)

    keeping(emulator_backend.EmulatorBackend, "board")
    keeping(imu_arduino.ImuArduino, "glove")
    monkeypatch.delenv("BOTSTAGE_IMU_PORT", raising=False)  # the emulated Arduino, as a user's first run

    simulated = run(DEMO, out=tmp_path / "sim")
    emulated = run(DEMO, backend="emulator", out=tmp_path / "emulator")

    assert simulated.outcome == emulated.outcome == "success", emulated.reason
    expected = {"gesture_drive": 1, "log": 1, "odometer": 1}
    assert calls(tmp_path / "sim") == calls(tmp_path / "emulator") == expected
    assert len(made["board"]) == 1 and len(made["glove"]) == 1  # the Launchpad's emulator and the Arduino's
    published = len(made["glove"][0].samples)
    sim, emu = simulated.summary["counters"], emulated.summary["counters"]
    assert published - 3 <= emu["hand_samples"] <= published  # each sample the Arduino sent, counted once
    assert abs(emu["hand_samples"] - sim["hand_samples"]) <= 8  # 2.5 a second for 30 s either way
    assert emu["travelled"] > 0.2 and abs(emu["travelled"] - sim["travelled"]) <= 0.15
    assert motions(tmp_path / "sim") == motions(tmp_path / "emulator") == ["forward", "back", "left", "right"]
    assert made["board"][0].emulator.speeds == (0, 0)  # the last speeds the board applied: stopped
    serial = emulated.summary["emulator"]["serial"]
    assert serial["speed_commands"] > 100 and not serial["lines_bad"]  # driven over the line, and cleanly
