"""check: succeed when a condition over blackboard values holds, fail otherwise."""

from __future__ import annotations

from botstage.skills.base import In, Outcome, Skill, SkillContext
from botstage.skills.expression import EvaluationError, compile_expression


def _shown(value: object) -> str:
    """A value as the reason shows it, the same in every run (sets are sorted)."""
    if isinstance(value, set | frozenset):
        return "{" + ", ".join(sorted(repr(v) for v in value)) + "}"
    return repr(value)


class Check(Skill):
    name = "check"
    description = "Succeed if `condition` holds on the blackboard, fail (with the values) if not."
    kind = "condition"
    inputs = {
        "condition": In(str, doc="e.g. `battery_pct > 20 and not estop`", expression=True),
    }

    def run(self, ctx: SkillContext, condition: str) -> Outcome:
        expression = compile_expression(condition)
        get = ctx.blackboard.get
        try:
            if expression.test(get):
                return Outcome.success()
            values = ", ".join(f"{k}={_shown(get(k))}" for k in sorted(expression.keys))
        except (LookupError, EvaluationError) as exc:  # a key nobody wrote is a plain failure
            return Outcome.failure(str(exc))
        return Outcome.failure(f"{expression.source!r} is false" + (f" ({values})" if values else ""))
