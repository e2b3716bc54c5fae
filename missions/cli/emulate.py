"""`botstage emulate BOARD`: a robot's board on a pseudo-terminal, for its driver (the hardware set)."""

from __future__ import annotations

import sys

import typer

from botstage.missions.cli.common import NON_NEGATIVE, _fail, console, number
from botstage.missions.cli.opening import robot_place


def emulate(
    board: str = typer.Argument(..., help="the board to emulate: launchpad (Chefbot's Tiva C), nyboard (Bittle's)"),
    world: str = typer.Option("restaurant", help="the map the simulated robot drives on"),
    start: str = typer.Option("dock", help="a place of the map, or x,y,theta"),
    seed: int = typer.Option(0, help="the simulated world's seed", callback=NON_NEGATIVE),
    counter_start: int = typer.Option(
        0,
        help="the encoders' first count, a 32-bit signed value (near 2147483647 to test wrap-around)",
        callback=number(ge=-(2**31), le=2**31 - 1),
    ),
) -> None:
    """Play a robot's board on a pseudo-terminal, driving the simulated robot; until Ctrl-C.

    Connect a driver (or `miniterm.py`) to the path it prints. Faults, typed on standard input:
    `garbage N`, `drop N`, `stall left|right|none`, `unplug SECONDS`, `reset`, `status`.
    """
    import threading

    robots = {"launchpad": "chefbot", "nyboard": "bittle"}
    if board not in robots:
        raise _fail(f"error: unknown board {board!r}; boards: {', '.join(robots)}", 2)
    from botstage.robots.emulators.fault_console import FAULTS, apply_fault
    from botstage.robots.emulators.launchpad import LaunchpadEmulator
    from botstage.robots.emulators.nyboard import NyBoardEmulator
    from botstage.robots.emulators.pty_board import PtyBoard
    from botstage.robots.sim.world import World

    profile, grid, pose = robot_place(robots[board], world, start)
    body = World(grid, profile, pose, seed)
    if board == "launchpad":
        emulator: PtyBoard = LaunchpadEmulator(body, counter_start=counter_start).start()
    elif counter_start:
        raise _fail("error: --counter-start is the Launchpad's encoders' first count; the NyBoard has none", 2)
    else:
        emulator = NyBoardEmulator(body).start()
    name = {"launchpad": "Launchpad", "nyboard": "NyBoard (OpenCat 2)"}[board]
    console.print(f"{name} emulator: connect to {emulator.path} (now {emulator.pty_path}), 115200 8N1", highlight=False)
    console.print(f"Ctrl-C stops; faults: {FAULTS}")
    stop = threading.Event()

    def faults() -> None:
        for line in sys.stdin:
            reply = apply_fault(emulator, line)  # never raises: a bad line gets a reply, the console goes on
            if reply is not None:
                console.print(reply, highlight=False, markup=False)
        stop.wait()  # end of input: keep running until Ctrl-C

    try:  # the console starts inside: once it answers, Ctrl-C ends the run cleanly
        threading.Thread(target=faults, daemon=True).start()
        while not stop.wait(0.5):
            pass
    except KeyboardInterrupt:
        pass
    finally:
        emulator.close()
