"""The Chefbot delivery mission, whole: in the simulator, with orders from the command line, and
over the emulated Launchpad's pty (with the board unplugged mid-drive).

The simulator runs carry everything for real (navigation, the speaker, the seated guests'
spoken YES through pocketsphinx, the monitors); they are on the sim clock. The emulator run is
in real time, as it must be: it is kept to one order and checks outcomes, never timings.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from botstage.behaviors.engine import Engine
from botstage.missions.cli import app
from botstage.missions.runner import RunResult, run
from botstage.robots.gridmap import load

ROOT = Path(__file__).resolve().parent.parent
MISSION = ROOT / "missions/examples/chefbot_delivery.yaml"
PLACES = load(ROOT / "robots/maps/restaurant.yaml").places


def served(result: RunResult) -> list[str]:
    """The tables the robot reached, in order (navigate succeeded with a table as its goal)."""
    goals: dict[str, Any] = {}
    tables = []
    for line in (result.folder / "trace.jsonl").read_text(encoding="utf-8").splitlines():
        event = json.loads(line)
        if event["ev"] == "skill_start" and event["skill"] == "navigate":
            goals[event["node"]] = event["inputs"]["goal"]
        elif event["ev"] == "skill_outcome" and event["skill"] == "navigate" and event["outcome"] == "succeeded":
            goal = goals[event["node"]]
            if isinstance(goal, str) and goal.startswith("table"):
                tables.append(goal)
    return tables


def at_dock(pose: list[float], tolerance: float = 0.1) -> bool:
    x, y, _ = PLACES["dock"]
    return math.hypot(pose[0] - x, pose[1] - y) < tolerance


@pytest.fixture(scope="module")
def simulated(tmp_path_factory: pytest.TempPathFactory) -> RunResult:
    return run(MISSION, out=tmp_path_factory.mktemp("delivery") / "run")


def test_three_orders_to_three_tables_and_it_ends_at_the_dock(simulated: RunResult) -> None:
    summary = simulated.summary
    assert simulated.outcome == "docked", simulated.reason
    assert summary["counters"]["orders_received"] == 3
    assert summary["counters"]["delivered"] == 3
    assert summary["counters"]["failed"] == []
    assert served(simulated) == ["table_2", "table_4", "table_6"]  # in the order they were given
    assert summary["states_visited"][-1].endswith("/docked")
    assert at_dock(summary["sim"]["final_pose"])
    assert summary["sim"]["bumps"] == 0
    # each guest confirmed by voice: the seated guests' YES through the real recogniser
    assert summary["skill_outcomes"]["listen"] == {"heard": 3}
    # distance from the wheel odometry, against the simulator's true path (wheels slip a little)
    assert summary["counters"]["distance_m"] == pytest.approx(summary["sim"]["distance_m"], rel=0.03)
    assert summary["counters"]["distance_m"] > 60


def test_battery_low_mid_delivery_in_the_simulator(tmp_path: Path) -> None:
    """The real battery monitor on the simulated battery: the threshold is set just under the
    charge the robot starts with, so it is crossed on the first trip."""
    result = run(MISSION, out=tmp_path / "run", blackboard={"battery_low_pct": 99.6})
    counters = result.summary["counters"]
    assert result.outcome == "docked", result.reason
    assert counters["delivered"] == 1  # the soup on board is served...
    assert [f["table"] for f in counters["failed"]] == ["table_4", "table_6"]  # ...the rest are not
    assert {f["reason"] for f in counters["failed"]} == {"battery low: the robot docked"}
    assert counters["battery_pct"] < 99.6
    states = [s.rsplit("/", 1)[-1] for s in result.summary["states_visited"]]
    assert states[states.index("serving") + 1] == "closing"  # no trip back to the kitchen
    assert at_dock(result.summary["sim"]["final_pose"])


def test_orders_from_the_command_line_join_the_queue_in_arrival_order(tmp_path: Path) -> None:
    """`botstage order` against the running mission: once as a real subprocess, once through the
    CLI function; both while the mission runs (the hook runs between ticks), then bad orders."""
    folder = tmp_path / "run"
    said: dict[str, Any] = {}

    def orders(engine: Engine) -> None:
        now = engine.clock.now()
        if "first" not in said and now >= 50.0:
            said["first"] = subprocess.run(
                [sys.executable, "-m", "botstage.missions.cli", "order", "table_5", "ice cream", "--run", str(folder)],
                cwd=ROOT,
                capture_output=True,
                text=True,
                timeout=120,
            )
        if "second" not in said and now >= 60.0:
            runner = CliRunner()
            said["second"] = runner.invoke(app, ["order", "table_1", "espresso", "--runs", str(tmp_path)])
            said["unknown"] = runner.invoke(app, ["order", "table_9", "tea", "--run", str(folder)])
            said["empty"] = runner.invoke(app, ["order", "table_1", "  ", "--run", str(folder)])

    result = run(
        MISSION,
        out=folder,
        blackboard={"orders": [{"table": "table_2", "item": "soup"}, {"table": "table_3", "item": "bread"}]},
        before_tick=orders,
    )
    assert said["first"].returncode == 0, said["first"].stderr
    assert "order for table_5: ice cream" in said["first"].stdout
    assert said["second"].exit_code == 0, said["second"].output
    assert said["unknown"].exit_code == 2 and "unknown table 'table_9'" in said["unknown"].output
    assert said["empty"].exit_code == 2 and "needs an item" in said["empty"].output
    assert result.outcome == "docked", result.reason
    assert result.summary["counters"]["orders_received"] == 4
    assert result.summary["counters"]["delivered"] == 4
    assert served(result) == ["table_2", "table_3", "table_5", "table_1"]
    taken = sorted(p.name for p in (folder / "inbox" / "taken").iterdir())
    assert len(taken) == 2 and not list((folder / "inbox" / "rejected").iterdir())
    # the run has finished: the inbox takes no more orders
    finished = CliRunner().invoke(app, ["order", "table_1", "tea", "--run", str(folder)])
    assert finished.exit_code == 2 and "has finished" in finished.output
    nothing = CliRunner().invoke(app, ["order", "table_1", "tea", "--runs", str(tmp_path)])
    assert nothing.exit_code == 2 and "no running mission takes orders" in nothing.output


def test_over_the_emulated_board_the_mission_survives_an_unplug(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """One order over the pty, in real time. On the way to the table the board's USB goes away
    for 1.5 s: the driver reports the loss, navigate drives on when the link is back (the tree
    has it wait), the driver's first command on the new link is zero speed, and the order is
    delivered and the robot docks."""
    from botstage.robots.emulators import backend as emulator_backend

    made: list[Any] = []
    real_init = emulator_backend.EmulatorBackend.__init__

    def keep(self: Any, *args: Any, **kwargs: Any) -> None:
        real_init(self, *args, **kwargs)
        made.append(self)

    monkeypatch.setattr(emulator_backend.EmulatorBackend, "__init__", keep)
    unplugged: list[float] = []

    def unplug(engine: Engine) -> None:
        state = engine.blackboard.get("nav_goal", None)
        if not unplugged and state == "table_1" and engine.clock.now() > 1.0:
            unplugged.append(engine.clock.now())
            made[0].emulator.disconnect(1.5)

    result = run(
        MISSION,
        backend="emulator",
        out=tmp_path / "run",
        blackboard={"orders": [{"table": "table_1", "item": "tea"}], "order_wait": 0.0, "load_wait": 1.0},
        before_tick=unplug,
    )
    summary = result.summary
    serial, board = summary["emulator"]["serial"], summary["emulator"]["board"]
    assert unplugged, "the drive to the table never started"
    assert result.outcome == "docked", result.reason
    assert summary["counters"]["delivered"] == 1 and summary["counters"]["failed"] == []
    assert serial["disconnects"] >= 1 and serial["connects"] >= 2  # the loss, reported, and the return
    assert board["unplugs"] >= 1 and board["plugs"] >= 2
    emulator = made[0].emulator
    assert len(emulator.first_speeds) >= 2 and set(emulator.first_speeds) == {(0, 0)}
    assert at_dock(summary["emulator"]["final_pose"], tolerance=0.15)
