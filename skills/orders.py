"""Orders of a delivery mission: take the next one, record how one ended, drop what is left.

The queue is a blackboard list of orders (``{table, item}`` mappings or ``[table, item]``
pairs): the mission file fills it, and ``take_order`` appends what arrived in the run's order
inbox (``botstage order TABLE ITEM``, see ``skills/delivery/inbox.py``) before taking the head,
so orders are served in arrival order. An order is counted as received once, when it is first
seen (it then carries an ``id``); one that cannot be served (an unknown table) is recorded as
failed with its reason at once. The three keys the skills keep (the queue, the received count,
the failed list) are named by the mission, so the summary's counters are plain keys.
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from botstage.skills.base import In, Out, Outcome, Seconds, Skill, SkillContext, SkillRun
from botstage.skills.delivery.inbox import Order, OrderError, parse_order

# Times are products of tick counts and periods; compare with a tolerance far below one tick.
_EPSILON = 1e-9


def _key(doc: str) -> Any:
    return In(str, doc=doc, names_key="write")


QUEUE = _key("the blackboard key of the order queue (a list)")
RECEIVED = _key("the int key counting the orders received")
FAILED = _key("the list key of failed orders: {id, table, item, reason}")


def served_tables(ctx: SkillContext, tables: list[str]) -> list[str] | None:
    """The tables orders may name: those given, else the map's places named table_*, else any."""
    if tables:
        return list(tables)
    navigation = ctx.interfaces.get("navigation")
    places = getattr(navigation, "places", None)
    if places:
        return sorted(name for name in places if name.startswith("table"))
    return None


def _read_list(ctx: SkillContext, key: str) -> list[Any]:
    value = ctx.blackboard.get(key) if ctx.blackboard.exists(key) else None
    return list(value or [])


def _read_int(ctx: SkillContext, key: str) -> int:
    value = ctx.blackboard.get(key) if ctx.blackboard.exists(key) else None
    return value if isinstance(value, int) else 0


class _Book:
    """The three keys as one ledger, read at the start of a run and written back at once."""

    def __init__(self, ctx: SkillContext, queue: str, received: str, failed: str) -> None:
        self.ctx, self.keys = ctx, (queue, received, failed)
        self.queue = _read_list(ctx, queue)
        self.received = _read_int(ctx, received)
        self.failed = _read_list(ctx, failed)
        self._saved: tuple[Any, ...] | None = None  # what the blackboard holds, once written

    def admit(self, tables: list[str] | None) -> None:
        """Give every order not seen before an id, and fail at once those that cannot be served."""
        kept = []
        for entry in self.queue:
            if isinstance(entry, dict) and "id" in entry:
                kept.append(entry)
                continue
            self.received += 1
            try:
                order = parse_order(entry, tables)
            except OrderError as exc:
                unserved = {"id": self.received, "table": _field(entry, "table"), "item": _field(entry, "item")}
                self.fail(unserved, str(exc))
                continue
            kept.append({"id": self.received, **order.as_dict()})
        self.queue = kept

    def add(self, orders: list[Order]) -> None:
        for order in orders:
            self.received += 1
            self.queue.append({"id": self.received, **order.as_dict()})

    def fail(self, order: dict[str, Any], reason: str) -> None:
        entry = {key: order.get(key) for key in ("id", "table", "item")}
        self.failed.append({**entry, "reason": reason})
        self.ctx.logger.warning(f"order {entry['id']} ({entry['item']} for {entry['table']}) failed: {reason}")

    def save(self) -> None:
        """Write the three keys, unless nothing changed since the last write (a waiting
        take_order saves every look into the inbox: the trace keeps only changes)."""
        state = (list(self.queue), self.received, list(self.failed))
        if state == self._saved:
            return
        queue, received, failed = self.keys
        self.ctx.blackboard.set(queue, self.queue)
        self.ctx.blackboard.set(received, self.received)
        self.ctx.blackboard.set(failed, self.failed)
        self._saved = state


def _field(entry: Any, name: str) -> Any:
    if isinstance(entry, dict):
        return entry.get(name)
    if isinstance(entry, list | tuple) and len(entry) == 2:
        return entry[0 if name == "table" else 1]
    return None


def _inbox(ctx: SkillContext) -> Any:
    """The run's order inbox, or None (a mission run without a run folder: a unit test)."""
    return ctx.interfaces.get("orders")


class TakeOrderParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    poll_every: float = Field(default=0.5, gt=0, description="s between looks into the inbox while waiting")
    announcement: str = Field(
        default="Here is your {item} for {table}. Please take it and say yes?",
        description="what `announcement` says; {table} (spaces for underscores) and {item} are filled in",
    )


class TakeOrder(Skill):
    name = "take_order"
    description = "Take the next order from the queue (after adding those that arrived in the inbox); `empty` if none."
    inputs = {
        "queue": QUEUE,
        "received": RECEIVED,
        "failed": FAILED,
        "tables": In(list[str], default=[], doc="the tables served (default: the map's places named table_*)"),
        "wait": In(Seconds, default=0.0, doc="s of mission time to wait for an order when there is none"),
    }
    outputs = {
        "order": Out(dict[str, Any], doc="the order taken: {id, table, item, source}"),
        "table": Out(str, doc="its table (a place of the map)"),
        "item": Out(str, doc="what to bring"),
        "announcement": Out(str, doc="what to say at the table (the `announcement` parameter, filled in)"),
    }
    outcomes = ("empty",)
    Params = TakeOrderParams

    def run(
        self, ctx: SkillContext, queue: str, received: str, failed: str, tables: list[str], wait: float
    ) -> SkillRun:
        if wait < 0:
            return Outcome.failure(f"wait must not be negative, got {wait}")
        params: TakeOrderParams = self.params  # type: ignore[assignment]
        book = _Book(ctx, queue, received, failed)
        served = served_tables(ctx, tables)
        inbox = _inbox(ctx)
        if inbox is not None and not inbox.opened:
            yield ctx.submit(inbox.open, served)
        book.admit(served)
        deadline = ctx.clock.now() + wait - _EPSILON
        while True:
            if inbox is not None:
                arrived = yield ctx.submit(inbox.take)
                book.add(arrived)
            if book.queue or ctx.clock.now() >= deadline:
                break
            book.save()  # the failed and received counts are visible while it waits
            next_look = min(deadline, ctx.clock.now() + params.poll_every)
            while ctx.clock.now() < next_look:
                yield
        if not book.queue:
            book.save()
            return Outcome("empty", "no order" + (f" in {wait:g} s" if wait else ""))
        order = book.queue.pop(0)
        book.save()
        announcement = params.announcement.format(table=order["table"].replace("_", " "), item=order["item"])
        return Outcome.success(
            f"order {order['id']}: {order['item']} for {order['table']}",
            order=order,
            table=order["table"],
            item=order["item"],
            announcement=announcement,
        )


class FinishOrder(Skill):
    name = "finish_order"
    description = "Record how an order ended: `delivered` counts it, `failed` lists it with its reason."
    inputs = {
        "order": In(dict[str, Any], doc="the order, as take_order gave it"),
        "result": In(str, doc="delivered or failed"),
        "reason": In(str, default="", doc="why it failed"),
        "detail": In(Any, default="", doc="appended to the reason, e.g. the navigation result"),
        "delivered": _key("the int key counting delivered orders"),
        "failed": FAILED,
    }

    def run(
        self,
        ctx: SkillContext,
        order: dict[str, Any],
        result: str,
        reason: str,
        detail: Any,
        delivered: str,
        failed: str,
    ) -> Outcome:
        label = f"order {order.get('id')} ({order.get('item')} for {order.get('table')})"
        if result == "delivered":
            ctx.blackboard.set(delivered, _read_int(ctx, delivered) + 1)
            return Outcome.success(f"{label} delivered")
        if result != "failed":
            return Outcome.failure(f"result must be delivered or failed, got {result!r}")
        why = ": ".join(str(part) for part in (reason or "failed", detail) if part not in ("", None))
        entries = _read_list(ctx, failed)
        entries.append({**{key: order.get(key) for key in ("id", "table", "item")}, "reason": why})
        ctx.blackboard.set(failed, entries)
        ctx.logger.warning(f"{label} failed: {why}")
        return Outcome.success(f"{label} failed: {why}")


class DropOrders(Skill):
    name = "drop_orders"
    description = "Fail every order still queued (and those in the inbox) with `reason`, e.g. when the battery is low."
    inputs = {"queue": QUEUE, "received": RECEIVED, "failed": FAILED, "reason": In(str, doc="why they are dropped")}
    outputs = {"dropped": Out(int, doc="how many orders were dropped")}

    def run(self, ctx: SkillContext, queue: str, received: str, failed: str, reason: str) -> SkillRun:
        book = _Book(ctx, queue, received, failed)
        inbox = _inbox(ctx)
        book.admit(None)
        if inbox is not None and inbox.opened:
            book.add((yield ctx.submit(inbox.take)))
        dropped = len(book.queue)
        for order in book.queue:
            book.fail(order, reason)
        book.queue = []
        book.save()
        return Outcome.success(f"{dropped} order(s) dropped: {reason}", dropped=dropped)
