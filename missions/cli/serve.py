"""`botstage serve`: run part of a robot system as its own process on a ROS 2 graph (over Zenoh).

``serve robot PROFILE`` runs a robot's devices on a backend and serves each interface as ROS 2
topics (robots/ros2/robot_server.py), until Ctrl-C or SIGTERM: then the drive gets zero velocity,
the node leaves the graph and the process exits 0. ``serve process DEPLOYMENT NAME`` runs one
process of a deployment by its role (missions/distributed/process.py). Both are the ros2 set's.
"""

from __future__ import annotations

import contextlib
import logging
import signal
import sys
import time
from pathlib import Path
from typing import Any

import typer

from botstage.missions.cli.common import NON_NEGATIVE, _fail, number
from botstage.missions.cli.distributed import CONNECT_HELP, check
from botstage.missions.cli.live import HOST_HELP, live_monitor
from botstage.missions.cli.opening import backend_help, backend_options, open_backend, robot_place

serve_app = typer.Typer(
    no_args_is_help=True,
    help="Serve part of a robot system to other processes as ordinary ROS 2 nodes (rmw_zenoh's format over Zenoh).",
)

DEFAULT_RATE_HZ = 20.0
RATE = number(gt=0, le=1000)
DOMAIN = number(ge=0)  # rmw_zenoh puts it in every key: any non-negative integer


def _endpoints(values: list[str], option: str) -> list[str]:
    from botstage.robots.ros2.endpoints import check_endpoint

    try:
        return [check_endpoint(value) for value in values]
    except ValueError as error:
        raise typer.BadParameter(str(error), param_hint=f"'{option}'") from None


def _log_to_stderr() -> None:
    """The robot's own log (watchdog trips, rejected commands) on stderr, one line each."""
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
    logger = logging.getLogger("robots")
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)


@serve_app.command("robot")
def robot(
    profile: str = typer.Argument(..., help="the robot's profile: a shipped one (peoplebot, chefbot) or a YAML path"),
    backend: str = typer.Option("sim", help=backend_help()),
    port: str | None = typer.Option(None, help="the robot's serial port (hardware; --backend-opt port=...)"),
    backend_opt: list[str] = typer.Option(
        [], "--backend-opt", metavar="KEY=VALUE", help="a backend option (repeatable); see `botstage backends`"
    ),
    world: str = typer.Option("restaurant", help="the map the simulated robot is on (sim and emulator)"),
    start: str = typer.Option("dock", help="a place of the map, or x,y,theta"),
    seed: int = typer.Option(0, help="the simulated world's seed", callback=NON_NEGATIVE),
    people: int = typer.Option(0, help="simulated people walking about", callback=number(ge=0, le=1000)),
    rate_hz: float = typer.Option(DEFAULT_RATE_HZ, "--rate", help="the robot loop's ticks a second", callback=RATE),
    listen: list[str] = typer.Option(
        [],
        metavar="ENDPOINT",
        help="where it listens (repeatable); default tcp/127.0.0.1:7447, loopback on the port where ROS 2 "
        "nodes look for their router, so they and `botstage run --backend ros2` find it",
    ),
    connect: list[str] = typer.Option(
        [], metavar="ENDPOINT", help="a Zenoh endpoint to connect to (repeatable), e.g. rmw_zenohd's"
    ),
    domain_id: int = typer.Option(0, envvar="ROS_DOMAIN_ID", help="the ROS 2 domain", callback=DOMAIN),
    namespace: str = typer.Option("/", help="the node's namespace: its topics go under it (/robot1/cmd_vel)"),
    name: str | None = typer.Option(None, help="the node's name; default: the profile's"),
) -> None:
    """Run a robot's devices and serve each interface as ROS 2 topics (cmd_vel, odom, scan, ...) until Ctrl-C.

    A simulated robot runs in real time and publishes /clock. With no cmd_vel for the profile's
    watchdog time (0.5 s), the drive stops.
    """
    import zenoh

    from botstage.robots.backend import OpenRequest
    from botstage.robots.backend_registry import BackendRegistry
    from botstage.robots.ros2.endpoints import ROUTER_LISTEN
    from botstage.robots.ros2.names import node_fqn
    from botstage.robots.ros2.node import Ros2Node
    from botstage.robots.ros2.robot_server import RobotServer, realtime_clock
    from botstage.robots.ros2.topics import routes

    listen = _endpoints(listen, "--listen") or [ROUTER_LISTEN]
    connect = _endpoints(connect, "--connect")
    name = name or profile_name(profile)
    try:
        node_fqn(namespace, name)
    except ValueError as error:
        raise _fail(f"error: {error}", 2) from None
    registry = BackendRegistry.default()
    if backend == "ros2":
        raise _fail("error: --backend ros2 drives a robot already on the graph: there is nothing to serve", 2)
    simulated = backend in registry and registry.get(backend).simulated
    robot_profile, grid, pose = robot_place(profile, world, start)
    clock, waiter = realtime_clock(rate_hz)
    request = OpenRequest(robot_profile, pose, clock, seed=seed, grid=grid, people=people)
    opened = open_backend(backend, request, backend_opt, port, profile)
    try:
        node = Ros2Node(name, namespace, domain_id=domain_id, listen=listen, connect=connect)
    except zenoh.ZError as error:
        opened.close()
        hint = f" (rmw_zenohd or another robot holds it? give --listen tcp/127.0.0.1:0 --connect {ROUTER_LISTEN})"
        raise _fail(f"error: cannot open the ROS 2 node on {', '.join(listen)}: {error}{hint}", 1) from None
    offset = 0.0 if simulated else time.time() - clock.now()  # ROS time for a real robot
    server = RobotServer(
        opened,
        node,
        clock,
        routes(robot_profile),
        publish_clock=simulated,
        stamp_offset=offset,
        watchdog_s=robot_profile.control.watchdog_s,
    )
    _log_to_stderr()
    previous = _stop_on_signals(waiter.stop.set)
    try:
        _announce(server, backend, listen, connect, domain_id)
        server.run(waiter)
    finally:
        _restore(previous)
        server.close()
    trips = server.watchdog.trips
    print(f"stopped ({len(trips)} watchdog stop{'s' if len(trips) != 1 else ''})", flush=True)


@serve_app.command("process")
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
    from botstage.missions.distributed.process import BackendGiven, DeploymentError, serve_process

    check(deployment)
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


def profile_name(profile: str) -> str:
    """A node name from a profile's name or path: its file's stem, made a valid ROS 2 name."""
    from pathlib import Path

    stem = Path(profile).stem or "robot"
    cleaned = "".join(c if c.isalnum() or c == "_" else "_" for c in stem)
    return cleaned if not cleaned[0].isdigit() else f"robot_{cleaned}"


def _announce(server: Any, backend: str, listen: list[str], connect: list[str], domain_id: int) -> None:
    node = server.node
    where = f"listening on {', '.join(listen)}" + (f", connecting to {', '.join(connect)}" if connect else "")
    lines = [f"serving {node.fqn} ({backend}) on ROS 2 domain {domain_id}, {where}; Ctrl-C stops"]
    lines += [f"  {direction:>3} {topic} [{type_name}]" for direction, topic, type_name in server.topics()]
    sys.stdout.write("".join(line + "\n" for line in lines))  # never wrapped: scripts read these lines
    sys.stdout.flush()


def _stop_on_signals(stop: Any) -> dict[int, Any]:
    """SIGINT and SIGTERM end the loop (the robot is then stopped and the node undeclared)."""

    def handler(signum: int, frame: Any) -> None:
        stop()

    return {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}


def _restore(previous: dict[int, Any]) -> None:
    for sig, handler in previous.items():
        signal.signal(sig, handler)
