"""The delivery mission's skills on the sim clock: orders and the inbox, wait_for, the monitors.

Skills run outside the engine through ``SkillExecution`` with a plain blackboard; the worker
pool is drained after every tick as the engine does on the sim clock. Nothing sleeps.
"""

from __future__ import annotations

import json
import random
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from botstage.missions.services import RobotServices
from botstage.robots.clock import SimClock
from botstage.robots.gridmap import load
from botstage.robots.interfaces import BatteryState, OdometryReading, Pose2D, SonarReading, Twist2D
from botstage.robots.profile import load_profile
from botstage.robots.sim.backend import SimBackend
from botstage.skills.base import Outcome, Skill, SkillContext, SkillLogger
from botstage.skills.delivery.inbox import ACCEPTS, OrderError, OrderInbox, parse_order
from botstage.skills.execution import SkillExecution
from botstage.skills.monitors import Odometer, WatchBattery, WatchSonar
from botstage.skills.orders import DropOrders, FinishOrder, TakeOrder
from botstage.skills.testing import DictBoard
from botstage.skills.wait_for import WaitFor
from botstage.skills.workers import Workers

RESTAURANT = load("robots/maps/restaurant.yaml")
TABLES = [f"table_{n}" for n in range(1, 7)]
KEYS = {"queue": "orders", "received": "received", "failed": "failed"}


class Rig:
    """A sim clock, a blackboard and a worker pool: what a skill needs to run outside the engine."""

    def __init__(self, interfaces: dict[str, Any] | None = None, rate_hz: float = 10.0) -> None:
        self.clock = SimClock(rate_hz)
        self.board = DictBoard()
        self.workers = Workers()
        self.interfaces = interfaces or {}
        self.logs: list[str] = []

    def start(self, skill: Skill, **inputs: Any) -> tuple[SkillExecution, Outcome | None]:
        ctx = SkillContext(
            clock=self.clock,
            params=skill.params,
            logger=SkillLogger(skill.name, sink=lambda node, level, message: self.logs.append(message)),
            blackboard=self.board,
            workers=self.workers,
            interfaces=self.interfaces,
            rng=random.Random(0),
        )
        execution = SkillExecution(skill, ctx)
        return execution, execution.start(inputs)

    def run(
        self, skill: Skill, limit: float = 60.0, each_tick: Callable[[float], None] | None = None, **inputs: Any
    ) -> Outcome:
        execution, outcome = self.start(skill, **inputs)
        deadline = self.clock.now() + limit
        while outcome is None:
            assert self.clock.now() < deadline, f"{skill.name} still running after {limit} s"
            self.workers.drain()
            self.clock.next_tick()
            if each_tick is not None:
                each_tick(self.clock.now())
            outcome = execution.step()
        return outcome

    def ticks(
        self, execution: SkillExecution, seconds: float, each_tick: Callable[[float], None] | None = None
    ) -> None:
        for _ in range(round(seconds / self.clock.period)):
            self.workers.drain()
            self.clock.next_tick()
            if each_tick is not None:
                each_tick(self.clock.now())
            assert execution.step() is None, "the skill ended"


def drop(inbox: Path, table: str, item: str, name: str) -> None:
    (inbox / name).write_text(json.dumps({"table": table, "item": item}), encoding="utf-8")


# -- orders ---------------------------------------------------------------------------------


def test_parse_order_accepts_mappings_and_pairs_and_says_what_is_wrong() -> None:
    assert parse_order({"table": "table_1", "item": "  tomato   soup "}, TABLES).item == "tomato soup"
    assert parse_order(["table_2", "tea"], TABLES).table == "table_2"
    with pytest.raises(OrderError, match="unknown table 'table_9'"):
        parse_order({"table": "table_9", "item": "tea"}, TABLES)
    with pytest.raises(OrderError, match="needs an item"):
        parse_order({"table": "table_1", "item": " "}, TABLES)
    with pytest.raises(OrderError, match="not colour"):
        parse_order({"table": "table_1", "item": "tea", "colour": "red"}, TABLES)
    with pytest.raises(OrderError, match="at most 80"):
        parse_order({"table": "table_1", "item": "x" * 81}, TABLES)
    with pytest.raises(OrderError, match=r"\{table: \.\.\., item: \.\.\.\}"):
        parse_order("table_1 tea", TABLES)
    assert parse_order({"table": "anywhere", "item": "tea"}, None).table == "anywhere"


def test_take_order_serves_the_file_orders_in_order_and_counts_each_once() -> None:
    rig = Rig()
    rig.board.set("orders", [{"table": "table_2", "item": "soup"}, ["table_5", "tea"], {"table": "attic", "item": "x"}])
    first = rig.run(TakeOrder(), tables=TABLES, **KEYS)
    assert first.name == "success" and first.outputs["table"] == "table_2" and first.outputs["item"] == "soup"
    assert first.outputs["order"] == {"id": 1, "table": "table_2", "item": "soup", "source": "mission"}
    assert first.outputs["announcement"] == "Here is your soup for table 2. Please take it and say yes?"
    # the unknown table is received and failed at once, with its reason; the pair stays queued
    assert rig.board.get("received") == 3
    assert rig.board.get("failed") == [
        {"id": 3, "table": "attic", "item": "x", "reason": rig.board.get("failed")[0]["reason"]}
    ]
    assert "unknown table 'attic'" in rig.board.get("failed")[0]["reason"]
    second = rig.run(TakeOrder(), tables=TABLES, **KEYS)
    assert second.outputs["order"]["id"] == 2 and second.outputs["table"] == "table_5"
    assert rig.board.get("received") == 3  # nothing counted twice
    empty = rig.run(TakeOrder(), tables=TABLES, **KEYS)
    assert empty.name == "empty" and rig.clock.now() == 0.0


def test_take_order_waits_for_inbox_orders_and_takes_them_in_arrival_order(tmp_path: Path) -> None:
    inbox = OrderInbox(tmp_path / "inbox")
    rig = Rig({"orders": inbox})

    def arrivals(now: float) -> None:
        if abs(now - 3.0) < 1e-9:  # two orders arrive together; the names say which came first
            drop(inbox.folder, "table_4", "cake", "00000000000000000002-1-b.json")
            drop(inbox.folder, "table_1", "tea", "00000000000000000001-1-a.json")
            (inbox.folder / "not-an-order.json").write_text("{oops", encoding="utf-8")
            (inbox.folder / ".half-written.tmp").write_text('{"table": "tab', encoding="utf-8")

    outcome = rig.run(TakeOrder(), each_tick=arrivals, tables=TABLES, wait=10.0, **KEYS)
    assert outcome.outputs["table"] == "table_1" and outcome.outputs["order"]["source"].endswith("-a.json")
    assert 3.0 <= rig.clock.now() <= 3.6  # seen at the next look (every 0.5 s), long before the wait ended
    assert json.loads((inbox.folder / ACCEPTS).read_text())["tables"] == TABLES
    assert rig.board.get("orders")[0]["table"] == "table_4" and rig.board.get("received") == 2
    # the malformed file is set aside with its reason, the half-written one is left alone
    assert (inbox.folder / "rejected" / "not-an-order.json").exists()
    assert "JSONDecodeError" in (inbox.folder / "rejected" / "not-an-order.json.reason").read_text()
    assert inbox.rejected[0]["file"] == "not-an-order.json"
    assert (inbox.folder / ".half-written.tmp").exists()
    assert sorted(p.name for p in (inbox.folder / "taken").iterdir()) == [
        "00000000000000000001-1-a.json",
        "00000000000000000002-1-b.json",
    ]
    nothing = rig.run(TakeOrder(), tables=TABLES, wait=2.0, **{**KEYS, "queue": "other"})
    assert nothing.name == "empty" and "no order in 2 s" in nothing.reason


def test_take_order_defaults_to_the_maps_tables_and_refuses_a_negative_wait() -> None:
    class Navigation:
        places = RESTAURANT.places

    rig = Rig({"navigation": Navigation()})
    rig.board.set("orders", [["kitchen", "soup"], ["table_6", "tea"]])
    outcome = rig.run(TakeOrder(), **KEYS)
    assert outcome.outputs["table"] == "table_6"
    assert "unknown table 'kitchen'" in rig.board.get("failed")[0]["reason"]
    assert rig.run(TakeOrder(), wait=-1.0, **KEYS).name == "failure"


def test_finish_order_counts_deliveries_and_lists_failures_with_reasons() -> None:
    rig = Rig()
    order = {"id": 4, "table": "table_3", "item": "soup", "source": "cli"}
    keys = {"delivered": "delivered", "failed": "failed"}
    assert rig.run(FinishOrder(), order=order, result="delivered", **keys).name == "success"
    assert rig.run(FinishOrder(), order=order, result="delivered", **keys).name == "success"
    assert rig.board.get("delivered") == 2
    failed = rig.run(
        FinishOrder(), order=order, result="failed", reason="could not reach the table", detail="blocked", **keys
    )
    assert failed.name == "success"
    assert rig.board.get("failed") == [
        {"id": 4, "table": "table_3", "item": "soup", "reason": "could not reach the table: blocked"}
    ]
    wrong = rig.run(FinishOrder(), order=order, result="eaten", **keys)
    assert wrong.name == "failure" and "delivered or failed" in wrong.reason


def test_drop_orders_fails_the_queue_and_the_inbox_with_the_reason(tmp_path: Path) -> None:
    inbox = OrderInbox(tmp_path / "inbox")
    inbox.open(TABLES)
    rig = Rig({"orders": inbox})
    rig.board.set("orders", [{"id": 1, "table": "table_1", "item": "tea"}, ["table_2", "cake"]])
    rig.board.set("received", 1)
    drop(inbox.folder, "table_3", "soup", "00000000000000000001-1-a.json")
    outcome = rig.run(DropOrders(), reason="battery low", **KEYS)
    assert outcome.outputs == {"dropped": 3}
    assert rig.board.get("orders") == [] and rig.board.get("received") == 3
    assert [(f["id"], f["table"], f["reason"]) for f in rig.board.get("failed")] == [
        (1, "table_1", "battery low"),
        (2, "table_2", "battery low"),
        (3, "table_3", "battery low"),
    ]


# -- wait_for -------------------------------------------------------------------------------


def test_wait_for_succeeds_when_the_condition_holds_and_times_out_otherwise() -> None:
    rig = Rig()

    def press(now: float) -> None:
        if abs(now - 1.5) < 1e-9:
            rig.board.set("guest_button", True)

    pressed = rig.run(WaitFor(), each_tick=press, condition="guest_button", timeout=5.0)
    assert pressed.name == "success" and abs(rig.clock.now() - 1.5) < 1e-9  # a key not written yet is no error
    start = rig.clock.now()
    late = rig.run(WaitFor(), condition="not guest_button", timeout=2.0)
    assert late.name == "timeout" and abs(rig.clock.now() - start - 2.0) < 1e-9
    assert rig.run(WaitFor(), condition="guest_button", timeout=-1.0).name == "failure"


# -- monitors -------------------------------------------------------------------------------


class Battery:
    def __init__(self, percents: list[float]) -> None:
        self.percents = percents

    def read(self) -> BatteryState:
        percent = self.percents.pop(0) if len(self.percents) > 1 else self.percents[0]
        return BatteryState(0.0, 10.5 + 2.1 * percent / 100, percent)


def test_watch_battery_latches_low_only_after_it_stayed_low() -> None:
    # a dip under 20 % for 1 s (a voltage sag), back up, then under for good
    percents = [25.0] * 10 + [19.0] * 10 + [21.0] * 10 + [18.0] * 40 + [30.0] * 10
    rig = Rig({"battery": Battery(percents)})
    execution, outcome = rig.start(WatchBattery(), low=20.0, confirm=3.0, percent_key="pct", low_key="low")
    assert outcome is None
    rig.ticks(execution, 5.9)
    assert rig.board.get("low") is False and rig.board.get("pct") == 18.0  # 3.0 s under not reached yet
    rig.ticks(execution, 0.2)
    assert rig.board.get("low") is True
    rig.ticks(execution, 2.0)
    assert rig.board.get("low") is True and rig.board.get("pct") == 30.0  # latched: it does not change its mind
    execution.cancel()


def test_watch_battery_keeps_its_values_while_the_battery_cannot_be_read() -> None:
    class Silent(Battery):
        def read(self) -> BatteryState:
            if self.percents[0] < 0:
                self.percents.pop(0)
                raise ConnectionError("board silent")
            return super().read()

    rig = Rig({"battery": Silent([50.0, -1, -1, -1, 49.0])})
    execution, _ = rig.start(WatchBattery(), low=20.0, confirm=3.0, percent_key="pct", low_key="low")
    rig.ticks(execution, 0.3)
    assert rig.board.get("pct") == 50.0 and rig.board.get("low") is False
    rig.ticks(execution, 0.5)
    assert rig.board.get("pct") == 49.0
    assert sum("cannot read the battery: board silent" in line for line in rig.logs) == 1
    execution.cancel()


class Sonar:
    def __init__(self, ranges: list[float]) -> None:
        self.ranges = ranges

    def read(self) -> SonarReading:
        value = self.ranges.pop(0) if len(self.ranges) > 1 else self.ranges[0]
        return SonarReading(0.0, value, 0.26, 4.0)


def chefbot_services(at: Pose2D) -> tuple[SimBackend, RobotServices, SimClock]:
    profile, problems, _ = load_profile("robots/profiles/chefbot.yaml")
    assert profile is not None, problems
    clock = SimClock(10)
    sim = SimBackend(profile, RESTAURANT, at, 1, clock)
    return sim, RobotServices.for_sim(sim, clock), clock


def test_watch_sonar_flags_what_is_not_on_the_map_and_ignores_walls() -> None:
    # in the open dining room, an echo at 0.3 m is something in the way
    sim, services, _ = chefbot_services(Pose2D(11.0, 7.0, 0.0))
    sonar = Sonar([2.0] * 5 + [0.3] * 5 + [3.0])
    rig = Rig({"sonar": sonar, "navigation": services.interfaces["navigation"]})
    execution, _ = rig.start(WatchSonar(), threshold=0.4, blocked_key="blocked", range_key="range")
    assert rig.board.get("blocked") is False
    rig.ticks(execution, 0.5)
    assert rig.board.get("blocked") is True and rig.board.get("range") == 0.3
    rig.ticks(execution, 0.5)
    assert rig.board.get("blocked") is False
    execution.cancel()
    # facing the east wall 0.3 m away, with the simulator's own sonar: the wall is the map's
    sim, services, _ = chefbot_services(Pose2D(19.45, 3.0, 0.0))
    reading = sim.devices["sonar"].read()
    assert reading.range < 0.4
    rig = Rig({"sonar": sim.devices["sonar"], "navigation": services.interfaces["navigation"]})
    execution, _ = rig.start(WatchSonar(), threshold=0.4, blocked_key="blocked", range_key="range")
    rig.ticks(execution, 1.0)
    assert rig.board.get("blocked") is False
    execution.cancel()
    # without a map every near echo counts
    rig = Rig({"sonar": Sonar([0.2])})
    execution, _ = rig.start(WatchSonar(), threshold=0.4, blocked_key="blocked", range_key="range")
    assert rig.board.get("blocked") is True
    execution.cancel()


class Odometry:
    def __init__(self) -> None:
        self.x = 0.0

    def read(self) -> OdometryReading:
        return OdometryReading(0.0, Pose2D(self.x, 0.0, 0.0), Twist2D(0.0, 0.0))


def test_odometer_adds_up_the_distance_and_writes_it_when_cancelled() -> None:
    odometry = Odometry()
    rig = Rig({"odometry": odometry})

    def drive(now: float) -> None:
        odometry.x += 0.03  # 0.3 m/s

    execution, _ = rig.start(Odometer(), key="distance", every=1.0)
    rig.ticks(execution, 1.0, drive)
    assert rig.board.get("distance") == pytest.approx(0.3)
    rig.ticks(execution, 0.5, drive)
    assert rig.board.get("distance") == pytest.approx(0.3)  # written once a second
    execution.cancel()
    assert rig.board.get("distance") == pytest.approx(0.45)


def test_post_order_checks_the_order_against_the_inbox_before_writing(tmp_path: Path) -> None:
    from botstage.missions.orders import find_inbox, post_order

    with pytest.raises(OrderError, match="no open order inbox"):
        find_inbox(tmp_path / "run")
    inbox = OrderInbox(tmp_path / "run" / "inbox")
    inbox.open(TABLES)
    assert find_inbox(tmp_path / "run") == inbox.folder
    assert find_inbox(None, runs=tmp_path) == inbox.folder
    path = post_order(inbox.folder, "table_3", "  hot   chocolate ")
    assert json.loads(path.read_text()) == {"table": "table_3", "item": "hot chocolate"}
    assert not list(inbox.folder.glob(".*.tmp"))  # written aside, then renamed
    with pytest.raises(OrderError, match="unknown table 'table_7'"):
        post_order(inbox.folder, "table_7", "tea")
    assert [o.item for o in inbox.take()] == ["hot chocolate"]  # nothing else was written
    anywhere = OrderInbox(tmp_path / "other" / "inbox")
    anywhere.open(None)  # a mission on a map without tables serves any place
    post_order(anywhere.folder, "terrace", "tea")
    assert [o.table for o in anywhere.take()] == ["terrace"]
    (inbox.folder / ACCEPTS).write_text("{broken", encoding="utf-8")
    with pytest.raises(OrderError, match="cannot read"):
        post_order(inbox.folder, "table_1", "tea")
