"""Missions with a robot and a world run on the simulator: devices, trajectory, report, safety."""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

import pytest

from botstage.missions.runner import RunError, run


def test_drive_demo_moves_the_simulated_chefbot(tmp_path: Path) -> None:
    result = run("missions/examples/drive_demo.yaml", out=tmp_path)
    assert result.outcome == "success"
    sim = result.summary["sim"]
    assert sim["bumps"] == 0 and sim["not_simulated"] == []
    # 0.9 + 3.0 m straight, plus the final arc; the straight ends short of the wall it heads for
    assert 4.5 < sim["distance_m"] < 6.0
    assert "trajectory.csv" in result.summary["artefacts"]
    lines = (tmp_path / "trajectory.csv").read_text().splitlines()
    assert lines[0] == "t,x,y,theta" and len(lines) == result.summary["ticks"] + 2
    assert lines[1] == "0,6.000000,1.000000,-1.570000"  # the dock
    assert 'alt="map with the trajectory" src="data:image/png;base64,' in (tmp_path / "report.html").read_text()


def test_same_seed_same_trajectory(tmp_path: Path) -> None:
    for name in ("a", "b"):
        run("missions/examples/drive_demo.yaml", out=tmp_path / name)
    assert (tmp_path / "a" / "trajectory.csv").read_bytes() == (tmp_path / "b" / "trajectory.csv").read_bytes()
    run("missions/examples/drive_demo.yaml", out=tmp_path / "c", seed=99)
    assert (tmp_path / "a" / "trajectory.csv").read_bytes() != (tmp_path / "c" / "trajectory.csv").read_bytes()


def mission(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "m.yaml"
    path.write_text(textwrap.dedent(text))
    return path


def test_motors_stop_when_the_run_is_interrupted(tmp_path: Path) -> None:
    path = mission(
        tmp_path,
        """\
        robot: chefbot
        world: restaurant
        start: kitchen_door
        trees:
          main: {move: {v: 0.3, duration: 100}}
    """,
    )

    def interrupt(snapshot) -> None:
        if snapshot().sim_time_s >= 2.0:
            raise KeyboardInterrupt

    result = run(path, out=tmp_path / "run", progress=interrupt, progress_interval_s=0)
    assert result.outcome == "interrupted"
    events = [json.loads(line) for line in (tmp_path / "run" / "trace.jsonl").read_text().splitlines()]
    assert [e["reason"] for e in events if e["ev"] == "skill_cancel"] == ["interrupted by the operator"]
    final = (tmp_path / "run" / "trajectory.csv").read_text().splitlines()[-1]
    assert float(final.split(",")[0]) == pytest.approx(2.0, abs=0.06)


def test_a_move_towards_a_wall_stops_short_of_it(tmp_path: Path) -> None:
    path = mission(
        tmp_path,
        """\
        robot: chefbot
        world: restaurant
        start: dock
        trees:
          main: {move: {v: 0.3, duration: 5}}
    """,
    )
    result = run(path, out=tmp_path / "run")
    assert result.outcome == "success"
    assert result.summary["sim"]["bumps"] == 0  # the move checks its way on the map (tests/test_open_loop_motion.py)
    assert result.summary["sim"]["final_pose"][1] >= 0.2 - 0.05  # never through the south wall at y = 0
    events = [json.loads(line) for line in (tmp_path / "run" / "trace.jsonl").read_text().splitlines()]
    reasons = [e["reason"] for e in events if e["ev"] == "skill_outcome" and e["skill"] == "move"]
    assert len(reasons) == 1 and reasons[0].startswith("stopped after") and "short of an obstacle" in reasons[0]


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("robot: chefbot\ntrees: {main: {wait: {duration: 1}}}\n", "names robot 'chefbot' but no world"),
        (
            "robot: chefbot\nworld: restaurant\nstart: [4.8, 3.0]\ntrees: {main: {wait: {duration: 1}}}\n",
            "cannot start at (4.8, 3)",
        ),
    ],
)
def test_a_robot_that_cannot_be_simulated_is_a_clear_error(tmp_path: Path, text: str, message: str) -> None:
    with pytest.raises(RunError, match=message.replace("(", r"\(").replace(")", r"\)")):
        run(mission(tmp_path, text), out=tmp_path / "run")


def test_move_without_a_drive_fails_with_a_reason(tmp_path: Path) -> None:
    result = run(mission(tmp_path, "trees: {main: {move: {v: 0.1, duration: 1}}}\n"), out=tmp_path / "run")
    assert result.outcome == "failure"
    assert "this robot has no 'drive' interface" in result.reason


@pytest.mark.parametrize("name", ["museum_patrol", "restaurant_patrol"])
def test_patrol_missions_complete_with_the_trajectory_in_the_report(tmp_path: Path, name: str) -> None:
    result = run(f"missions/examples/{name}.yaml", out=tmp_path)
    assert result.outcome == "success", result.reason
    sim = result.summary["sim"]
    assert sim["bumps"] == 0
    assert sim["distance_m"] > 30
    navigations = result.summary["skill_outcomes"].get("navigate", {})
    if name == "museum_patrol":
        assert result.summary["counters"]["visited"] >= 12  # of 14: people may stand on a checkpoint
        assert navigations == {"succeeded": 1}  # back to the entrance
    else:
        assert navigations == {"succeeded": 8}  # every leg, no recovery needed with these people
        assert result.summary["counters"]["nav_result"] == "succeeded"
    assert 'alt="map with the trajectory" src="data:image/png;base64,' in (tmp_path / "report.html").read_text()
