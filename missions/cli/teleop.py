"""`botstage teleop`: drive a robot by keyboard or the gesture glove, opened here or served elsewhere."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import typer

from botstage.missions.cli.common import NON_NEGATIVE, POSITIVE, _fail, console, number
from botstage.missions.cli.opening import backend_help, open_backend, robot_place
from botstage.robots.backend_registry import DEFAULT

RATE = number(gt=0, le=1000)


def _gesture_teleop(
    backend: Any,
    profile: Any,
    clock: Any,
    imu_port: str | None,
    config_file: Path | None,
    until: float | None,
    show: Any,
) -> None:
    """Drive ``backend``'s robot from the gesture IMU (its emulator unless ``imu_port``) until ``until`` or Ctrl-C."""
    import contextlib

    from botstage.robots.drivers.rosserial import RosserialDriver
    from botstage.robots.emulators.imu_arduino import ImuArduino
    from botstage.robots.teleop import drive_loop
    from botstage.skills.gesture import GestureCommands, load_config

    try:
        config = load_config(config_file) if config_file is not None else None
    except ValueError as error:
        raise _fail(f"error: {error}", 2) from None
    with contextlib.ExitStack() as stack:
        if imu_port is None:
            glove = stack.enter_context(ImuArduino())
            imu_port = glove.path
            console.print(f"gesture IMU emulator on {imu_port}: replaying a hand (home, forward, back, left, right)")
        driver = stack.enter_context(RosserialDriver(imu_port))
        commands = GestureCommands(driver, profile.base.max_linear, profile.base.max_angular, config)
        console.print(
            "tilt forward to speed up, back to slow down, turn the hand to turn; level it to stop; Ctrl-C quits"
        )
        drive_loop(
            backend.devices["drive"],
            commands,
            clock,
            step=backend.step,
            odometry=backend.devices.get("odometry"),
            show=show,
            until=until,
        )


def _open_served(
    profile: Any, pose: Any, clock: Any, connect: list[str], domain_id: int, namespace: str, certs: Path | None
) -> Any:
    """The served robot, or exit with the reason (a bad endpoint, namespace or certificate: 2; nobody answering: 1)."""
    from pydantic import ValidationError

    from botstage.robots.ros2.teleop import open_served

    security = None
    if certs is not None:
        from botstage.missions.deployment import OPERATOR
        from botstage.missions.distributed.security import SecurityError, credentials, secured
        from botstage.robots.ros2.security import security_options

        try:
            found = credentials(certs, OPERATOR)  # the operator's folder, or the one `botstage certs` wrote
            secured(connect, connect)
        except SecurityError as error:
            raise _fail(f"error: {error}", 2) from None
        security = security_options(found)
    try:
        backend = open_served(
            profile, pose, clock, connect, domain_id=domain_id, namespace=namespace, security=security
        )
    except ValidationError as error:
        raise _fail([f"error: {e['msg']}" for e in error.errors()], 2) from None
    except ConnectionError as error:
        raise _fail(f"error: {error}", 1) from None
    console.print(f"driving {profile.name} served on {', '.join(connect)} (cmd_vel, odom)", highlight=False)
    return backend


def teleop(
    robot: str = typer.Argument("chefbot", help="the robot's profile"),
    backend: str = typer.Option(DEFAULT, help=backend_help()),
    port: str | None = typer.Option(None, help="the robot's serial port, e.g. /dev/ttyACM0 (--backend-opt port=...)"),
    backend_opt: list[str] = typer.Option(
        [], "--backend-opt", metavar="KEY=VALUE", help="a backend option (repeatable); see `botstage backends`"
    ),
    world: str = typer.Option("restaurant", help="the map (sim and emulator)"),
    start: str = typer.Option("dock", help="a place of the map, or x,y,theta"),
    seed: int = typer.Option(0, help="the simulated world's seed", callback=NON_NEGATIVE),
    rate_hz: float = typer.Option(10.0, "--rate", help="commands a second (at most 1000)", callback=RATE),
    linear_step: float = typer.Option(0.05, help="m/s a key adds", callback=POSITIVE),
    angular_step: float = typer.Option(0.2, help="rad/s a key adds", callback=POSITIVE),
    input_: str = typer.Option(
        "keys", "--input", help="keys (the keyboard) or gesture (the book's IMU glove over rosserial)"
    ),
    imu_port: str | None = typer.Option(
        None, help="the gesture IMU's serial port (rosserial, 57600); default: its emulator, replaying a hand"
    ),
    gesture_config: Path | None = typer.Option(
        None, metavar="FILE", help="the chapter's teleop_config.yaml (step_size, low/high speed and turn)"
    ),
    until: float | None = typer.Option(None, help="stop after this many seconds (Ctrl-C stops too)", min=0),
    connect: list[str] = typer.Option(
        [],
        "--connect",
        metavar="ENDPOINT",
        help="drive a robot another process serves as ROS 2 topics (botstage serve robot, a deployment's robot "
        "process, a ROS 2 robot): publish its cmd_vel through this Zenoh endpoint, e.g. tcp/127.0.0.1:7447 "
        "(repeatable); its own watchdog stops it if teleop goes away",
    ),
    domain_id: int = typer.Option(
        0, envvar="ROS_DOMAIN_ID", help="the served robot's ROS 2 domain (with --connect)", callback=NON_NEGATIVE
    ),
    namespace: str = typer.Option("/", help="the served robot's namespace (with --connect), e.g. /robot1"),
    certs: Path | None = typer.Option(
        None,
        metavar="DIR",
        help="with --connect to a secured deployment: mutual TLS with the certificate in DIR: the operator's "
        "folder `botstage certs --deployment` wrote (certs/operator, or certs itself), which the deployment lets "
        "drive the robot; tls/ endpoints only",
    ),
) -> None:
    """Drive a robot with the keyboard, as the book's keyboard teleop: w/x a/d (or arrows), s stops, q quits;
    or with the book's gesture controller (--input gesture): tilt forward to speed up, turn the hand to turn.
    The robot is opened here (--backend), or served by another process (--connect)."""
    from botstage.robots.backend import OpenRequest
    from botstage.robots.clock import WallClock
    from botstage.robots.teleop import HELP, StreamKeys, Teleop, TerminalKeys, run_teleop

    if input_ not in ("keys", "gesture"):
        raise typer.BadParameter(f"{input_!r}: keys or gesture", param_hint="'--input'")
    if certs is not None and not connect:
        raise _fail("error: --certs is for --connect: a secured deployment's robot process", 2)
    if connect and (backend != DEFAULT or port is not None or backend_opt):
        raise _fail(
            "error: --connect drives a robot another process serves; --backend, --port and "
            "--backend-opt open one here: give one or the other",
            2,
        )
    profile, grid, pose = robot_place(robot, world, start)
    clock = WallClock(rate_hz)
    if connect:
        robot_backend = _open_served(profile, pose, clock, connect, domain_id, namespace, certs)
    else:
        request = OpenRequest(profile, pose, clock, seed=seed, grid=grid)
        robot_backend = open_backend(backend, request, backend_opt, port, robot)
    devices = robot_backend.devices
    if "drive" not in devices:
        robot_backend.close()
        raise _fail(f"error: robot {robot!r} has no drive", 2)
    state = Teleop(profile.base.max_linear, profile.base.max_angular, linear_step, angular_step)
    interactive = sys.stdin.isatty() and sys.stdout.isatty()

    def show(line: str) -> None:
        if interactive:
            sys.stdout.write("\r\x1b[K" + line)
            sys.stdout.flush()
        else:
            console.print(line, highlight=False)

    try:
        if input_ == "gesture":
            _gesture_teleop(robot_backend, profile, clock, imu_port, gesture_config, until, show)
        elif interactive:
            with TerminalKeys.opened() as keys:
                console.print(HELP, highlight=False)  # once keys are read one by one: none typed is lost
                run_teleop(
                    devices["drive"],
                    keys,
                    clock,
                    state,
                    step=robot_backend.step,
                    odometry=devices.get("odometry"),
                    show=show,
                    until=until,
                )
        else:
            console.print(HELP, highlight=False)
            run_teleop(
                devices["drive"],
                StreamKeys(sys.stdin),
                clock,
                state,
                step=robot_backend.step,
                odometry=devices.get("odometry"),
                show=show,
                until=until,
            )
    except KeyboardInterrupt:
        pass
    finally:
        robot_backend.close()
    if interactive:
        sys.stdout.write("\n")
    console.print("stopped", highlight=False)
