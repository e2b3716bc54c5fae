"""set: write a value to a blackboard key."""

from __future__ import annotations

from typing import Any

from botstage.skills.base import In, Outcome, Skill, SkillContext


class Set(Skill):
    name = "set"
    description = "Write `value` to the blackboard key `key`."
    inputs = {
        "key": In(str, doc="the blackboard key to write (namespaces separated by '/')", names_key="write"),
        "value": In(Any, doc="the value to write"),
    }

    def run(self, ctx: SkillContext, key: str, value: Any) -> Outcome:
        ctx.blackboard.set(key, value)
        return Outcome.success()
