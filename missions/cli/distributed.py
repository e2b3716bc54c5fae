"""`botstage up DEPLOYMENT` and `botstage serve process DEPLOYMENT NAME`: one mission, several processes.

``serve process`` runs one process of a deployment by its role (missions/distributed/process.py);
``up`` checks the deployment, then starts every process on this machine over loopback (the router
process listening on a free port unless the file says where), relays each one's log prefixed
with its name, reports how each ended, and stops them all when the mission ends or on Ctrl-C.
"""

from __future__ import annotations

import contextlib
import socket
import sys
from pathlib import Path
from typing import Any

import typer
from botstage.missions.cli.common import NON_NEGATIVE, _fail, console
from botstage.missions.cli.monitor import HOST_HELP, live_monitor

CONNECT_HELP = "the Zenoh endpoint of the deployment's router process, e.g. tcp/192.168.1.10:7447"


def _check(deployment: Path) -> None:
    from botstage.missions.deployment import check_deployment

    checked = check_deployment(deployment)
    if not checked.ok:
        raise _fail([str(problem) for problem in checked.problems], 2)


def process(
    deployment: Path = typer.Argument(..., help="the deployment file (missions/deployments/*.yaml)"),
    name: str = typer.Argument(..., help="the process of the deployment to run here"),
    out: Path = typer.Option(Path("runs/deployment"), help="the run folder (shared by the processes of one run)"),
    seed: int | None = typer.Option(None, help="the mission's seed (default: the mission's)", callback=NON_NEGATIVE),
    until: float | None = typer.Option(None, help="stop the mission after this many seconds of mission time"),
    connect: list[str] = typer.Option([], "--connect", metavar="ENDPOINT", help=CONNECT_HELP),
    listen: list[str] = typer.Option([], "--listen", metavar="ENDPOINT", help="where this process listens"),
    certs: Path | None = typer.Option(
        None,
        metavar="DIR",
        help="speak only mutual TLS with this process's certificate (its folder, or the one `botstage certs` "
        "wrote) under the deployment's access policy; then it may listen beyond loopback (--listen tls/0.0.0.0:7447)",
    ),
    backend: str | None = typer.Option(
        None,
        help="the robot process's backend on this machine instead of the file's, e.g. hardware on the robot's "
        "own computer (the mission follows its clock: lockstep when simulated, real time otherwise)",
    ),
    port: str | None = typer.Option(None, help="the robot's serial port (hardware), e.g. /dev/serial0"),
    backend_opt: list[str] = typer.Option(
        [], "--backend-opt", metavar="KEY=VALUE", help="a backend option (repeatable); see `botstage backends`"
    ),
    monitor_port: int | None = typer.Option(
        None, help="the mission's process: serve the live monitor on this port (0: a free one)", min=0, max=65535
    ),
    monitor_host: str = typer.Option("127.0.0.1", help=HOST_HELP),
) -> None:
    """Run one process of a deployment (its robot, skills or mission) and serve it until Ctrl-C."""
    from botstage.missions.cli.backends import backend_options
    from botstage.missions.distributed.process import BackendGiven, DeploymentError, serve_process

    _check(deployment)
    given = BackendGiven(backend, backend_options(backend_opt), port)
    watching = live_monitor(monitor_host, monitor_port, False) if monitor_port is not None else contextlib.nullcontext()
    try:
        with watching as observer:
            code = serve_process(
                deployment,
                name,
                out=out,
                seed=seed,
                until=until,
                connect=connect,
                listen=listen or None,
                ready=lambda line: print(line, flush=True),
                certs=certs,
                backend=given,
                observers=[observer] if observer is not None else [],
            )
    except DeploymentError as error:
        raise _fail(str(error), 2) from None
    raise typer.Exit(code)


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


def _loopback_certificates(folder: Path, processes: list[str]) -> Path:
    """``folder`` with a certificate for each process and the operator (loopback hosts), made if missing;
    its authority kept. The operator's is teleop's: ``botstage teleop --certs OUT/certs/operator``."""
    from botstage.missions.deployment import OPERATOR
    from botstage.robots.ros2.certs import Credentials, make_certificates

    missing = [name for name in [*processes, OPERATOR] if Credentials.in_folder(folder / name).missing()]
    if missing:
        make_certificates(folder, missing)
    return folder


def _deployment_overview(checked: Any, supervisor: Any, mission_port: int, port: int) -> Any:
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


def up(
    deployment: Path = typer.Argument(..., help="the deployment file (missions/deployments/*.yaml)"),
    out: Path = typer.Option(Path("runs/deployment"), help="the run folder the processes share"),
    seed: int | None = typer.Option(None, help="the mission's seed (default: the mission's)", callback=NON_NEGATIVE),
    until: float | None = typer.Option(None, help="stop the mission after this many seconds of mission time"),
    port: int = typer.Option(0, help="the router's loopback port (0: a free one)", min=0, max=65535),
    secure: bool = typer.Option(
        False,
        help="mutual TLS and the deployment's access policy, certificates made in OUT/certs (kept for next runs; "
        "OUT/certs/operator is teleop's)",
    ),
    monitor: bool = typer.Option(
        False, "--monitor", help="serve a page with the processes and the mission's live monitor"
    ),
    monitor_port: int = typer.Option(8470, help="that page's port (loopback)", min=0, max=65535),
) -> None:
    """Start every process of a deployment on this machine (loopback) and stop them together."""
    from botstage.missions.deployment import check_deployment
    from botstage.missions.distributed.supervisor import Supervisor

    _check(deployment)
    checked = check_deployment(deployment)
    assert checked.deployment is not None
    router = checked.router
    endpoint = f"{'tls' if secure else 'tcp'}/127.0.0.1:{port or free_port()}"
    certs = _loopback_certificates(out / "certs", list(checked.deployment.processes)) if secure else None
    watched = free_port() if monitor else None  # the mission's process serves its monitor there
    commands = process_commands(
        deployment, endpoint, out=out, seed=seed, until=until, certs=certs, monitor_port=watched
    )
    names = list(commands)
    width = max(len(name) for name in names)

    def show(name: str, line: str) -> None:
        print(f"{name:<{width}} | {line}", flush=True)

    supervisor = Supervisor(commands, show)
    mission = checked.mission_process
    title = f"{checked.deployment.name}: {len(names)} processes on {endpoint} (router: {router})"
    console.print(title, highlight=False)
    code = 1
    overview = _deployment_overview(checked, supervisor, watched, monitor_port) if watched is not None else None
    try:
        supervisor.start()
        while True:
            ended = supervisor.wait_any(3600.0)
            if ended is None:
                continue
            if ended.name == mission:
                code = supervisor.wait(mission)
            else:
                console.print(f"{ended.name}: {ended.state}: stopping the others", highlight=False)
            break
    except KeyboardInterrupt:
        code = 130
    finally:
        if overview is not None:
            overview.stop()
        supervisor.stop()
        for name, state in supervisor.states().items():
            console.print(f"  {name:<{width}}  {state}", highlight=False)
    raise typer.Exit(code)
