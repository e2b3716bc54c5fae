"""wander: patrol checkpoints, in order or at random, pausing at each (the paper's Wandering).

A patrol does not end because one checkpoint is out of reach (a group of visitors standing on
it): it logs the miss and goes on to the next. It fails only when a whole round reached
nothing. The checkpoint it last reached is written to ``checkpoint_key`` as it goes, so that
back_to_point can return there after an interaction; a patrol started again after being
preempted resumes after that checkpoint. With ``stops: 1`` it goes on to the next checkpoint and
returns: the paper's Wandering, one leg at a time, with Crowd Detection at each checkpoint.
"""

from __future__ import annotations

from typing import Any

from botstage.skills.base import In, Out, Outcome, Seconds, Skill, SkillContext, SkillRun
from botstage.skills.nav.navigator import NavParams, drive_to
from botstage.skills.navigate import CANCEL, cancel_condition, nav_stack


class Wander(Skill):
    name = "wander"
    description = "Patrol `checkpoints` (default: every place of the map) in order or at random, pausing at each."
    inputs = {
        "checkpoints": In(list[str], default=[], doc="places to visit; empty: every place of the map"),
        "order": In(str, default="sequence", doc="`sequence` or `random`"),
        "pause": In(Seconds, default=3.0, doc="s to stay at each checkpoint"),
        "rounds": In(int, default=0, doc="how many times round; 0: until stopped"),
        "stops": In(int, default=0, doc="return after reaching this many checkpoints (0: whole rounds)"),
        "checkpoint_key": In(
            str, default="last_checkpoint", doc="key to write each reached place to", names_key="write"
        ),
        "cancel": CANCEL,
    }
    outputs = {
        "visited": Out(int, doc="checkpoints reached"),
        "missed": Out(list[str], doc="checkpoints it could not reach, with the last reason in the log"),
    }
    outcomes = ("cancelled",)
    Params = NavParams

    def run(
        self,
        ctx: SkillContext,
        checkpoints: list[str],
        order: str,
        pause: float,
        rounds: int,
        stops: int,
        checkpoint_key: str,
        cancel: str,
    ) -> SkillRun:
        stack = nav_stack(ctx)
        names = list(checkpoints) or list(stack.places)
        if order not in ("sequence", "random"):
            return Outcome.failure(f"order must be `sequence` or `random`, got {order!r}")
        if not names:
            return Outcome.failure("no checkpoints: the map has no places and none were given")
        unknown = [n for n in names if n not in stack.places]
        if unknown:
            known = ", ".join(sorted(stack.places)) or "none"
            return Outcome.failure(f"unknown checkpoint(s) {', '.join(unknown)} (places: {known})")
        if pause < 0 or rounds < 0 or stops < 0:
            return Outcome.failure("pause, rounds and stops must not be negative")
        drive = ctx.interface("drive")
        cancelled = cancel_condition(ctx, cancel)
        visited, missed = 0, []
        last = self._last(ctx, checkpoint_key)
        index = names.index(last) + 1 if last in names else 0
        round_no = 0
        while rounds == 0 or round_no < rounds:
            reached = 0
            for _ in range(len(names)):
                if order == "random":
                    choices = [n for n in names if n != last] or names
                    name = choices[ctx.rng.randrange(len(choices))]
                else:
                    name = names[index % len(names)]
                    index += 1
                result = yield from drive_to(
                    stack,
                    drive,
                    stack.resolve(name),
                    self.params,  # type: ignore[arg-type]
                    tolerance=0.15,
                    heading_tolerance=0.15,
                    cancel=cancelled,
                    log=ctx.logger.info,
                )
                if result.outcome == "cancelled":
                    return Outcome("cancelled", result.reason, {"visited": visited, "missed": missed})
                if not result.succeeded:
                    ctx.logger.warning(f"skipping checkpoint {name}: {result.outcome}: {result.reason}")
                    missed.append(name)
                    continue
                reached += 1
                visited += 1
                last = name
                ctx.blackboard.set(checkpoint_key, name)
                until = ctx.clock.now() + pause - 1e-9
                while ctx.clock.now() < until:
                    if cancelled is not None and cancelled():
                        return Outcome("cancelled", "cancelled while pausing", {"visited": visited, "missed": missed})
                    yield
                if stops and visited >= stops:
                    return Outcome.success(f"{visited} checkpoint(s)", visited=visited, missed=missed)
            if not reached:
                return Outcome.failure(
                    f"round {round_no + 1} reached none of {len(names)} checkpoint(s)",
                    visited=visited,
                    missed=missed,
                )
            round_no += 1
        return Outcome.success(f"{round_no} round(s), {visited} checkpoint(s)", visited=visited, missed=missed)

    @staticmethod
    def _last(ctx: SkillContext, key: str) -> Any:
        try:
            return ctx.blackboard.get(key) if ctx.blackboard.exists(key) else None
        except Exception:  # no read access: start from the first checkpoint
            return None
