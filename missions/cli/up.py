"""`botstage up DEPLOYMENT`: every process of a deployment started on this machine over loopback (the ros2 set).

It checks the deployment, then starts every process (the router process listening on a free port
unless the file says where), relays each one's log prefixed with its name, reports how each ended,
and stops them all when the mission ends or on Ctrl-C.
"""

from __future__ import annotations

from pathlib import Path

import typer

from botstage.missions.cli.common import NON_NEGATIVE, console
from botstage.missions.cli.distributed import (
    check,
    deployment_overview,
    free_port,
    loopback_certificates,
    process_commands,
)


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

    check(deployment)
    checked = check_deployment(deployment)
    assert checked.deployment is not None
    router = checked.router
    endpoint = f"{'tls' if secure else 'tcp'}/127.0.0.1:{port or free_port()}"
    certs = loopback_certificates(out / "certs", list(checked.deployment.processes)) if secure else None
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
    overview = deployment_overview(checked, supervisor, watched, monitor_port) if watched is not None else None
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
