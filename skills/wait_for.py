"""wait_for: run until a blackboard condition holds (a button pressed, a way cleared) or a timeout.

``check`` looks once; this one looks every tick, for events that arrive on the blackboard while
a mission waits (a scenario's event, a monitor's flag, an operator's button).
"""

from __future__ import annotations

from botstage.skills.base import In, Outcome, Seconds, Skill, SkillContext, SkillRun
from botstage.skills.expression import EvaluationError, compile_expression

# Times are products of tick counts and periods; compare with a tolerance far below one tick.
_EPSILON = 1e-9


class WaitFor(Skill):
    name = "wait_for"
    description = "Succeed as soon as `condition` holds on the blackboard; `timeout` after `timeout` s of mission time."
    inputs = {
        "condition": In(str, doc="e.g. `guest_button` or `not front_blocked`", expression=True),
        "timeout": In(Seconds, doc="s of mission time to wait"),
    }
    outcomes = ("timeout",)

    def run(self, ctx: SkillContext, condition: str, timeout: float) -> SkillRun:
        if timeout < 0:
            return Outcome.failure(f"timeout must not be negative, got {timeout}")
        expression = compile_expression(condition)
        deadline = ctx.clock.now() + timeout - _EPSILON
        while True:
            try:
                if expression.test(ctx.blackboard.get):
                    return Outcome.success(f"{expression.source!r} holds")
            except LookupError:
                pass  # a key nobody wrote yet: the event has not happened
            except EvaluationError as exc:
                return Outcome.failure(str(exc))
            if ctx.clock.now() >= deadline:
                return Outcome("timeout", f"{expression.source!r} did not hold within {timeout:g} s")
            yield
