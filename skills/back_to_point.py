"""back_to_point: return to the last checkpoint (the paper's Back to Point after an interaction)."""

from __future__ import annotations

from typing import Any

from botstage.skills.base import In, SkillContext, SkillRun
from botstage.skills.navigate import CANCEL, GOAL, NAV_OUTPUTS, TIMEOUT, Navigate


class BackToPoint(Navigate):
    name = "back_to_point"
    description = "Drive back to `point`, usually the last checkpoint wander reached (`{last_checkpoint}`)."
    inputs = {
        "point": In(GOAL, doc="a place of the map or [x, y(, theta)]: bind it to `{last_checkpoint}`"),
        "tolerance": In(float, default=0.1, doc="m"),
        "heading_tolerance": In(float, default=0.1, doc="rad"),
        "timeout": TIMEOUT,
        "cancel": CANCEL,
    }
    outputs = NAV_OUTPUTS

    def run(  # type: ignore[override]
        self, ctx: SkillContext, point: Any, tolerance: float, heading_tolerance: float, timeout: float, cancel: str
    ) -> SkillRun:
        return (yield from super().run(ctx, point, tolerance, heading_tolerance, timeout, cancel))
