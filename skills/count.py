"""count: add to a counter on the blackboard (crowds visited, photos taken, orders delivered)."""

from __future__ import annotations

from botstage.skills.base import In, Outcome, Skill, SkillContext


class Count(Skill):
    name = "count"
    description = "Add `by` (default 1) to the int blackboard key `key`; a key not yet set counts from 0."
    inputs = {
        "key": In(str, doc="the counter's blackboard key", names_key="write"),
        "by": In(int, default=1, doc="how much to add (negative counts down)"),
    }

    def run(self, ctx: SkillContext, key: str, by: int) -> Outcome:
        current = ctx.blackboard.get(key) if ctx.blackboard.exists(key) else 0
        if current is None:
            current = 0
        if isinstance(current, bool) or not isinstance(current, int):
            return Outcome.failure(f"{key!r} holds {current!r}, not a count")
        ctx.blackboard.set(key, current + by)
        return Outcome.success()
