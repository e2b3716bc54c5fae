"""What `botstage up` and `botstage serve process` share: a deployment checked, each process's
command line, its certificates on loopback and the page that shows them all."""

from __future__ import annotations

import socket
import sys
from pathlib import Path
from typing import Any

from botstage.missions.cli.common import _fail, console

CONNECT_HELP = "the Zenoh endpoint of the deployment's router process, e.g. tcp/192.168.1.10:7447"


def check(deployment: Path) -> None:
    """The deployment checked whole, or exit 2 with its problems."""
    from botstage.missions.deployment import check_deployment

    checked = check_deployment(deployment)
    if not checked.ok:
        raise _fail([str(problem) for problem in checked.problems], 2)


def process_commands(
    deployment: Path,
    endpoint: str,
    *,
    out: Path,
    seed: int | None = None,
    until: float | None = None,
    certs: Path | None = None,
    monitor_port: int | None = None,
) -> dict[str, list[str]]:
    """Each process's ``serve process`` command, the router first: it listens on ``endpoint``, the others
    connect; ``monitor_port``: the mission's process serves the live monitor there."""
    from botstage.missions.deployment import check_deployment

    checked = check_deployment(deployment)
    assert checked.deployment is not None, checked.problems
    base = [sys.executable, "-m", "botstage.missions.cli", "serve", "process", str(deployment), "--out", str(out)]
    base += ["--seed", str(seed)] if seed is not None else []
    base += ["--until", str(until)] if until is not None else []
    base += ["--certs", str(certs)] if certs is not None else []
    router = checked.router
    names = [router, *[n for n in checked.deployment.processes if n != router]]
    commands = {name: [*base, name, "--listen" if name == router else "--connect", endpoint] for name in names}
    if monitor_port is not None:
        commands[checked.mission_process] += ["--monitor-port", str(monitor_port)]
    return commands


def loopback_certificates(folder: Path, processes: list[str]) -> Path:
    """``folder`` with a certificate for each process and the operator (loopback hosts), made if missing;
    its authority kept. The operator's is teleop's: ``botstage teleop --certs OUT/certs/operator``."""
    from botstage.missions.deployment import OPERATOR
    from botstage.robots.ros2.certs import Credentials, make_certificates

    missing = [name for name in [*processes, OPERATOR] if Credentials.in_folder(folder / name).missing()]
    if missing:
        make_certificates(folder, missing)
    return folder


def deployment_overview(checked: Any, supervisor: Any, mission_port: int, port: int) -> Any:
    """The overview page on ``port``: the deployment's processes as the supervisor sees them, and
    the mission's run (its process's monitor on ``mission_port``, proxied)."""
    from botstage.missions.monitor.server import MonitorError, start_overview
    from botstage.missions.monitor.sources import remote_source

    deployment = checked.deployment

    def processes() -> list[dict[str, Any]]:
        states = supervisor.states()
        return [
            {
                "name": name,
                "state": states.get(name, "not started"),
                "description": spec.description,
                "mission": spec.mission,
                "skills": spec.skills or [],
                "interfaces": spec.interfaces or [],
                "gallery": spec.gallery,
            }
            for name, spec in deployment.processes.items()
        ]

    mission = remote_source(f"http://127.0.0.1:{mission_port}", [], None, name=checked.mission_process)
    try:
        running = start_overview([mission], port=port, processes=processes, title=deployment.name)
    except MonitorError as exc:
        raise _fail(f"error: {exc}", 2) from None
    console.print(
        f"monitor: {running.url}/  (the mission: {running.url}/s/{mission.name}/)", highlight=False, soft_wrap=True
    )
    return running


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])
