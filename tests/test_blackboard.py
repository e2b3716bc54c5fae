import pytest

from botstage.behaviors.blackboard import AccessError, Blackboard, BlackboardError, KeyTypeError, MissingKeyError
from botstage.behaviors.trace import Trace
from botstage.robots.clock import SimClock


@pytest.fixture
def board() -> Blackboard:
    bb = Blackboard(Trace(SimClock()))
    yield bb
    bb.close()


def test_namespaced_keys_and_snapshot(board: Blackboard) -> None:
    board.set("robot/battery_pct", 80)
    board.set("/robot/mode", "idle")
    board.set("goal", [1.0, 2.0])
    assert board.get("robot/battery_pct") == 80
    assert board.snapshot() == {"goal": [1.0, 2.0], "robot/battery_pct": 80, "robot/mode": "idle"}


def test_two_blackboards_in_one_process_are_isolated() -> None:
    a, b = Blackboard(), Blackboard()
    try:
        a.set("x", 1)
        assert not b.exists("x")
        b.set("x", 2)
        assert a.get("x") == 1
    finally:
        a.close()
        b.close()


def test_close_forgets_keys() -> None:
    bb = Blackboard()
    bb.set("x", 1)
    bb.close()
    assert not bb.exists("x")


@pytest.mark.parametrize("key", ["", "a b", "1x", "a//b", "a.b", 3])
def test_invalid_keys_are_refused(board: Blackboard, key: object) -> None:
    with pytest.raises(BlackboardError):
        board.set(key, 1)  # type: ignore[arg-type]


def test_declared_types_are_checked_on_write(board: Blackboard) -> None:
    board.declare("battery_pct", float, default=100)
    board.set("battery_pct", 55)  # an int is a valid float
    with pytest.raises(KeyTypeError, match="'battery_pct' is declared float: expected float, got str 'low'"):
        board.set("battery_pct", "low")
    assert board.get("battery_pct") == 55  # the bad write lost nothing
    board.declare("goal", list[float])
    with pytest.raises(KeyTypeError, match=r"list\[float\]"):
        board.set("goal", [1.0, "x"])


def test_per_node_access(board: Blackboard) -> None:
    board.set("speed", 0.3)
    node = board.client("approach", reads=["speed"], writes=["distance"])
    assert node.get("speed") == 0.3
    node.set("distance", 1.2)
    with pytest.raises(AccessError, match="may not write 'speed'"):
        node.set("speed", 9)
    with pytest.raises(AccessError, match="may not read 'secret'"):
        node.get("secret")
    reader = board.client("reader", reads=["never_written"])
    with pytest.raises(MissingKeyError, match="'never_written' was read by 'reader' but nothing has written it"):
        reader.get("never_written")


def test_activity_stream_and_trace_record_writes_with_their_writer(board: Blackboard) -> None:
    board.set("mode", "idle", writer="init")
    node = board.client("planner", writes=["mode"])
    node.set("mode", "moving")
    with pytest.raises(AccessError):
        node.set("other", 1)
    kinds = [(a.kind, a.key, a.client) for a in board.activity]
    assert kinds == [("write", "mode", "init"), ("write", "mode", "planner"), ("denied", "other", "planner")]
    writes = [e for e in board.trace.events if e["ev"] == "bb_write"]
    assert [(e["key"], e["old"], e["new"], e["writer"]) for e in writes] == [
        ("mode", None, "idle", "init"),
        ("mode", "idle", "moving", "planner"),
    ]
