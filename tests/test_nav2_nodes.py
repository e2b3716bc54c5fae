"""Nav2's control and decorator nodes, tick by tick, against Nav2's own tick()/halt().

As tests/test_btcpp_nodes.py: each case scripts its children (``S``, ``F``, ``R``: one status per
tick of that child, the last repeated) and lists, per tick of the tree, the root's status and what
happened to the children (``A`` ticked, ``A!`` halted while running). The expectations are read
off nav2_behavior_tree/plugins/control/*.cpp and plugins/decorator/*.cpp and their unit tests.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import pytest

from botstage.behaviors.builder import SpecError
from botstage.behaviors.kinds import NodeKinds
from tests.scripted_nodes import LOG, A, B, C, Hook, Scripted, leaf, run


@dataclass
class Pose:
    x: float
    y: float
    theta: float = 0.0


class FakeStack:
    """The navigation stack as DistanceController reads it: the robot's pose, moved by the test."""

    def __init__(self) -> None:
        self.at = Pose(0.0, 0.0)

    def pose(self) -> Pose:
        return self.at


@dataclass
class Twist:
    v: float
    w: float = 0.0


class FakeOdometry:
    """Odometry as SpeedController reads it: the robot's speed, set by the test."""

    def __init__(self) -> None:
        self.v = 0.0

    def read(self) -> Any:
        return type("Reading", (), {"twist": Twist(self.v)})()


@pytest.fixture
def stack() -> FakeStack:
    return FakeStack()


@pytest.fixture
def odometry() -> FakeOdometry:
    return FakeOdometry()


@pytest.fixture(scope="module")
def kinds() -> NodeKinds:
    kinds = NodeKinds.default("btcpp")  # Nav2's set is a plug-in of the XML scope: installed, so there
    kinds.register(Scripted)
    return kinds


@pytest.fixture
def engine(make_engine: Any, stack: FakeStack, odometry: FakeOdometry, kinds: NodeKinds) -> Iterator[Any]:
    LOG.clear()
    yield make_engine(rate_hz=10, kinds=kinds, interfaces={"navigation": stack, "odometry": odometry})


CASES: list[tuple[str, dict[str, Any], list[tuple[str, str]], int | None]] = [
    # -- PipelineSequence: every child up to the running one, each tick
    (
        "pipeline ticks earlier running children with the later one",
        {"PipelineSequence": [leaf(A, "RSR"), leaf(B, "RRS"), leaf(C, "RS")]},
        [("R", "A"), ("R", "A B"), ("R", "A B"), ("R", "A B C"), ("S", "A B C A!")],
        None,
    ),
    (
        "pipeline: a failure halts the earlier running children and restarts",
        {"PipelineSequence": [leaf(A, "SR"), leaf(B, "RF")]},
        [("R", "A B"), ("F", "A B A!"), ("R", "A")],
        None,
    ),
    (
        "pipeline: the first child running holds the rest back",
        {"PipelineSequence": [leaf(A, "RRS"), leaf(B, "S")]},
        [("R", "A"), ("R", "A"), ("S", "A B")],
        None,
    ),
    (
        "a halt resets the pipeline",
        {"PipelineSequence": [leaf(A, "SR"), leaf(B, "R")]},
        [("R", "A B"), ("halt", "B!"), ("R", "A")],
        1,
    ),
    # -- RecoveryNode: action, recovery; retried in the same tick
    (
        "recovery node succeeds with its first child",
        {"RecoveryNode": [leaf(A, "S"), leaf(B, "S")]},
        [("S", "A")],
        None,
    ),
    (
        "recovery node runs the recovery and retries the action in the same tick",
        {"RecoveryNode": [leaf(A, "FS"), leaf(B, "S")]},
        [("S", "A B A")],
        None,
    ),
    (
        "recovery node fails once number_of_retries are spent",
        {"RecoveryNode": [leaf(A, "F"), leaf(B, "S")], "number_of_retries": 2},
        [("F", "A B A B A")],
        None,
    ),
    (
        "recovery node with no retries fails with its action",
        {"RecoveryNode": [leaf(A, "F"), leaf(B, "S")], "number_of_retries": 0},
        [("F", "A")],
        None,
    ),
    (
        "recovery node fails when the recovery fails",
        {"RecoveryNode": [leaf(A, "F"), leaf(B, "F")], "number_of_retries": 3},
        [("F", "A B")],
        None,
    ),
    (
        "recovery node waits for a running recovery, then retries",
        {"RecoveryNode": [leaf(A, "FS"), leaf(B, "RS")]},
        [("R", "A B"), ("S", "B A")],
        None,
    ),
    (
        "a halt resets the retries",
        {"RecoveryNode": [leaf(A, "FR"), leaf(B, "S")], "number_of_retries": 1},
        [("R", "A B A"), ("halt", "A!"), ("R", "A")],
        1,
    ),
    # -- RoundRobin: the next child each time, failures move on in the same tick
    (
        "round robin takes its children in turn, then fails instead of wrapping",
        {"RoundRobin": [leaf(A, "S"), leaf(B, "S"), leaf(C, "S")]},
        [("S", "A"), ("S", "B"), ("S", "C"), ("F", ""), ("S", "A")],
        None,
    ),
    (
        "round robin with wrap_around starts over",
        {"RoundRobin": [leaf(A, "S"), leaf(B, "S")], "wrap_around": True},
        [("S", "A"), ("S", "B"), ("S", "A")],
        None,
    ),
    (
        "round robin moves past a failure in the same tick; all failing fails",
        {"RoundRobin": [leaf(A, "F"), leaf(B, "SF"), leaf(C, "F")], "wrap_around": True},
        [("S", "A B"), ("F", "C A B")],
        None,
    ),
    (
        "round robin keeps its running child",
        {"RoundRobin": [leaf(A, "RS"), leaf(B, "S")]},
        [("R", "A"), ("S", "A"), ("S", "B")],
        None,
    ),
    # -- RateController (10 Hz ticks): the child at most hz times a second, RUNNING in between
    (
        "rate controller ticks its child at hz",
        {"RateController": leaf(A, "S"), "hz": 2.5},
        [("S", "A"), ("R", ""), ("R", ""), ("R", ""), ("S", "A"), ("R", "")],
        None,
    ),
    (
        "rate controller ticks a running child every tick",
        {"RateController": leaf(A, "RRS"), "hz": 1.0},
        [("R", "A"), ("R", "A"), ("S", "A"), ("R", "")],
        None,
    ),
    (
        "a halted rate controller starts afresh",
        {"RateController": leaf(A, "S"), "hz": 1.0},
        [("S", "A"), ("R", ""), ("halt", ""), ("S", "A")],
        2,
    ),
    # -- SingleTrigger: once per iteration
    (
        "single trigger runs its child once, then fails",
        {"SingleTrigger": leaf(A, "RS")},
        [("R", "A"), ("S", "A"), ("F", ""), ("F", "")],
        None,
    ),
    (
        "single trigger runs again after a reset",
        {"SingleTrigger": leaf(A, "S")},
        [("S", "A"), ("F", ""), ("halt", ""), ("S", "A")],
        2,
    ),
    (
        "a pipeline resets its single trigger with its other children",
        {"PipelineSequence": [{"SingleTrigger": leaf(A, "S")}, leaf(B, "S")]},
        [("S", "A B"), ("S", "A B")],
        None,
    ),
]


@pytest.mark.parametrize(("spec", "expected", "halt_after"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_nav2_node(engine: Any, spec: dict[str, Any], expected: list[tuple[str, str]], halt_after: int | None) -> None:
    assert run(engine, spec, len(expected) - (halt_after is not None), halt_after) == expected


def goal_changes(at: dict[int, Any], key: str = "goal") -> Hook:
    def before(engine: Any, n: int) -> None:
        if n in at:
            engine.blackboard.set(key, at[n])

    return before


def test_goal_updated_notes_the_goal_then_sees_it_change(engine: Any) -> None:
    spec = {"ReactiveFallback": [{"GoalUpdated": {}}, leaf(A, "R")]}
    got = run(engine, spec, 4, before=goal_changes({0: "exhibit_a", 2: "exhibit_b"}))
    assert got == [("R", "A"), ("R", "A"), ("S", "A!"), ("R", "A")]  # noted afresh after it fired


def test_global_updated_goal_notes_once_for_the_tree(engine: Any) -> None:
    spec = {"Inverter": {"GlobalUpdatedGoal": {}}}
    got = run(engine, spec, 4, before=goal_changes({0: "exhibit_a", 2: "exhibit_b"}))
    assert [status for status, _ in got] == ["S", "S", "F", "S"]  # Inverter: F = the goal changed


def test_goal_updated_reads_a_goal_port_and_tolerates_an_unwritten_goals(engine: Any) -> None:
    spec = {"Inverter": {"GoalUpdated": {"goal": "{target}"}}}
    got = run(engine, spec, 3, before=goal_changes({0: [1.0, 2.0], 1: [3.0, 4.0]}, "target"))
    assert [status for status, _ in got] == ["S", "F", "S"]


def test_goal_updated_controller_ticks_its_child_when_the_goal_changes(engine: Any) -> None:
    spec = {"GoalUpdatedController": leaf(A, "S")}
    got = run(engine, spec, 4, before=goal_changes({0: "exhibit_a", 2: "exhibit_b"}))
    assert got == [("S", "A"), ("R", ""), ("S", "A"), ("R", "")]


def test_distance_controller_ticks_its_child_every_distance(engine: Any, stack: FakeStack) -> None:
    def drive(engine: Any, n: int) -> None:
        stack.at = Pose(0.3 * n, 0.0)

    got = run(engine, {"DistanceController": leaf(A, "S"), "distance": 1.0}, 6, before=drive)
    assert got == [("S", "A"), ("R", ""), ("R", ""), ("R", ""), ("S", "A"), ("R", "")]  # 0, then 1.2 m on


def test_path_longer_on_approach_ticks_its_child_only_for_a_much_longer_new_path(engine: Any) -> None:
    short = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]
    detour = [[0.0, 0.0], [0.0, 3.0], [2.0, 3.0], [2.0, 0.0]]
    spec = {"PathLongerOnApproach": leaf(A, "S"), "path": "{path}", "prox_len": 3.0, "length_factor": 2.0}
    got = run(engine, spec, 3, before=goal_changes({0: short, 2: detour}, "path"))
    assert got == [("S", ""), ("S", ""), ("S", "A")]


def test_goal_updater_copies_its_goal_to_its_output(engine: Any) -> None:
    spec = {"GoalUpdater": leaf(A, "S"), "input_goal": "{goal}", "output_goal": "{updated_goal}"}
    run(engine, spec, 1, before=goal_changes({0: "exhibit_c"}))
    assert engine.blackboard.get("updated_goal") == "exhibit_c"


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ({"RecoveryNode": [leaf(A, "S")]}, "RecoveryNode takes 2 children"),
        ({"RateController": leaf(A, "S"), "hz": 0}, "hz"),
        ({"RecoveryNode": [leaf(A, "S"), leaf(B, "S")], "number_of_retries": "many"}, "number_of_retries"),
        ({"GoalUpdated": {"gaol": "{goal}"}}, "has no port 'gaol'"),
        ({"PathLongerOnApproach": leaf(A, "S"), "path": "path"}, "names a blackboard key"),
    ],
)
def test_bad_nav2_nodes_are_located_errors(engine: Any, spec: dict[str, Any], message: str) -> None:
    with pytest.raises(SpecError) as error:
        engine.builder().tree(spec)
    assert message in str(error.value)


NONBLOCKING = [
    (
        "nonblocking sequence ticks every child every tick, running or not",
        {"NonblockingSequence": [leaf(A, "RS"), leaf(B, "S"), leaf(C, "RRS")]},
        [("R", "A B C"), ("R", "A B C"), ("S", "A B C")],
    ),
    (
        "nonblocking sequence: a failure halts the running children",
        {"NonblockingSequence": [leaf(A, "R"), leaf(B, "SF")]},
        [("R", "A B"), ("F", "A B A!")],
    ),
]


@pytest.mark.parametrize(("spec", "expected"), [c[1:] for c in NONBLOCKING], ids=[c[0] for c in NONBLOCKING])
def test_nonblocking_sequence(engine: Any, spec: dict[str, Any], expected: list[tuple[str, str]]) -> None:
    assert run(engine, spec, len(expected)) == expected


def test_time_expired_fires_every_seconds(engine: Any) -> None:
    got = run(engine, {"Inverter": {"TimeExpired": {"seconds": 0.3}}}, 7)  # 10 Hz ticks
    assert [status for status, _ in got] == ["S", "S", "S", "F", "S", "S", "F"]  # Inverter: F = expired


def test_distance_traveled_fires_every_distance(engine: Any, stack: FakeStack) -> None:
    def drive(engine: Any, n: int) -> None:
        stack.at = Pose(0.4 * n, 0.0)

    got = run(engine, {"Inverter": {"DistanceTraveled": {"distance": 1.0}}}, 6, before=drive)
    assert [status for status, _ in got] == ["S", "S", "S", "F", "S", "S"]  # 1.2 m after the start


def test_path_expiring_timer_starts_over_with_a_new_path(engine: Any) -> None:
    spec = {"Inverter": {"PathExpiringTimer": {"seconds": 0.2, "path": "{path}"}}}
    got = run(engine, spec, 6, before=goal_changes({0: [[0.0, 0.0]], 2: [[1.0, 1.0]]}, "path"))
    assert [status for status, _ in got] == ["S", "S", "S", "S", "F", "S"]


# -- the skills, on the simulated PeopleBot in the museum ------------------------------------


@pytest.fixture(scope="module")
def sim() -> Any:
    from tests.bench.navsim import NavSim

    return NavSim("museum", "peoplebot", "hall_centre")


def test_would_a_recovery_help_reads_nav2s_codes(sim: Any) -> None:
    from botstage.skills.nav2.conditions import WouldAControllerRecoveryHelp, WouldAPlannerRecoveryHelp

    controller, planner = WouldAControllerRecoveryHelp(), WouldAPlannerRecoveryHelp()
    assert sim.run(controller, error_code=105).name == "success"  # FAILED_TO_MAKE_PROGRESS
    assert sim.run(controller, error_code=103).name == "failure"  # INVALID_PATH: no recovery helps
    assert sim.run(controller, error_code=0).name == "failure"
    assert sim.run(controller, error_code=103, error_codes_to_check="101;103").name == "success"
    assert sim.run(planner, error_code=208).name == "success"  # NO_VALID_PATH
    bad = sim.run(planner, error_code=208, error_codes_to_check="208;lots")
    assert bad.name == "failure" and "numbers separated by ';'" in bad.reason


def test_selectors_write_their_default(sim: Any) -> None:
    from botstage.skills.nav2.selectors import ControllerSelector, PlannerSelector

    assert sim.run(PlannerSelector(), default_planner="GridBased").outputs == {"selected_planner": "GridBased"}
    assert sim.run(ControllerSelector(), default_controller="FollowPath").outputs["selected_controller"] == "FollowPath"


def test_compute_path_to_pose_plans_and_says_why_it_cannot(sim: Any) -> None:
    from botstage.skills.nav2.planning import ComputePathToPose

    ok = sim.run(ComputePathToPose(), goal="exhibit_a")
    path = ok.outputs["path"]
    assert ok.name == "success" and ok.outputs["error_code_id"] == 0
    assert path[-1] == [6.0, 11.5, -1.57]  # the place, with its heading
    assert abs(path[0][0] - sim.truth.x) < 0.1 and abs(path[0][1] - sim.truth.y) < 0.1
    inside = sim.run(ComputePathToPose(), goal=[11.0, 6.0])  # exhibit_d's plinth
    assert (inside.name, inside.outputs["error_code_id"]) == ("failure", 206)  # GOAL_OCCUPIED
    assert sim.run(ComputePathToPose(), goal=[500.0, 6.0]).outputs["error_code_id"] == 204  # GOAL_OUTSIDE_MAP
    unknown = sim.run(ComputePathToPose(), goal="exhibit_z")
    assert unknown.name == "failure" and "exhibit_a" in unknown.reason  # the places it knows


def test_path_utilities(sim: Any) -> None:
    from botstage.skills.nav2.paths import IsGoalNearby, TruncatePath, TruncatePathLocal
    from botstage.skills.nav2.utilities import GetPoseFromPath

    x, y = sim.truth.x, sim.truth.y
    path = [[x, y], [x + 1.0, y], [x + 2.0, y], [x + 3.0, y, 0.0]]
    assert sim.run(IsGoalNearby(), path=path, proximity_threshold=3.5).name == "success"
    assert sim.run(IsGoalNearby(), path=path, proximity_threshold=2.5).name == "failure"
    kept = sim.run(TruncatePathLocal(), input_path=path, distance_forward=1.5, distance_backward=0.0)
    assert kept.outputs["output_path"] == path[:2]
    assert sim.run(TruncatePathLocal(), input_path=path, distance_forward=-1.0).outputs["output_path"] == path
    assert sim.run(TruncatePath(), input_path=path, distance=1.5).outputs["output_path"] == path[:2]
    assert sim.run(GetPoseFromPath(), path=path, index=-1).outputs["pose"] == [x + 3.0, y, 0.0]
    assert sim.run(GetPoseFromPath(), path=path, index=4).name == "failure"


def test_speed_controller_ticks_faster_the_faster_the_robot_goes(engine: Any, odometry: FakeOdometry) -> None:
    spec = {"SpeedController": leaf(A, "S"), "min_rate": 1.0, "max_rate": 5.0, "min_speed": 0.0, "max_speed": 0.5}
    # the first period is 2 / (1 + 5) s (4 ticks at 10 Hz); then the robot's speed sets it
    odometry.v = 0.0  # standing: 1 Hz, the child 10 ticks later
    slow = run(engine, spec, 16)
    assert [n for n, (_, log) in enumerate(slow) if log == "A"] == [0, 4, 14]
    LOG.clear()
    odometry.v = 0.5  # full speed: 5 Hz, every 2 ticks
    fast = run(engine, spec, 9)
    assert [n for n, (_, log) in enumerate(fast) if log == "A"] == [0, 4, 6, 8]


def test_drive_on_heading_drives_straight_and_refuses_mixed_signs(sim: Any) -> None:
    from botstage.skills.nav2.motions import DriveOnHeading

    start = sim.truth
    done = sim.run(DriveOnHeading(), dist_to_travel=0.5, speed=0.25)
    assert done.name == "success" and done.outputs["error_code_id"] == 0
    assert 0.45 <= math.hypot(sim.truth.x - start.x, sim.truth.y - start.y) <= 0.6
    bad = sim.run(DriveOnHeading(), dist_to_travel=0.5, speed=-0.25)
    assert (bad.name, bad.outputs["error_code_id"]) == ("failure", 704)  # INVALID_INPUT
