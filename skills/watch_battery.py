"""watch_battery: keep the battery's charge on the blackboard, for guards such as ``battery_pct < 20``.

It runs beside the mission (a branch of the root's ``parallel``) and writes the Battery
interface's percentage, rounded to ``step``, whenever that rounded value changes: a guard sees
the charge within a step while the trace stays free of a write every tick. A reading that
fails (a board that stopped reporting) is logged once and the last value kept; the skill never
ends on its own.
"""

from __future__ import annotations

from skills.base import In, Outcome, Skill, SkillContext, SkillRun


class WatchBattery(Skill):
    name = "watch_battery"
    description = "Write the battery's charge (%) to `key` whenever it changes by a `step`; runs until cancelled."
    inputs = {
        "key": In(str, default="battery_pct", doc="the float key to write the charge to", names_key="write"),
        "step": In(float, default=1.0, doc="% the charge is rounded to before it is written"),
    }
    outcomes = ("cancelled",)

    def run(self, ctx: SkillContext, key: str, step: float) -> SkillRun:
        if not step > 0:
            return Outcome.failure(f"step must be positive, got {step}")
        battery = ctx.interface("battery")
        written: float | None = None
        failing = False
        while True:
            try:
                percent = round(round(battery.read().percent / step) * step, 6)
            except Exception as error:  # a board that stopped reporting: keep the last value
                if not failing:
                    ctx.logger.warning(f"cannot read the battery: {error}")
                failing = True
            else:
                failing = False
                if percent != written:
                    ctx.blackboard.set(key, float(percent))
                    written = percent
            yield
