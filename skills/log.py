"""log: write a message to the run's log and trace."""

from __future__ import annotations

import logging

from botstage.skills.base import In, Outcome, Skill, SkillContext

_LEVELS = {"debug": logging.DEBUG, "info": logging.INFO, "warning": logging.WARNING, "error": logging.ERROR}


class Log(Skill):
    name = "log"
    description = "Log a message (it reaches the trace and the report)."
    inputs = {
        "message": In(str, doc="the text to log"),
        "level": In(str, default="info", doc="debug, info, warning or error"),
    }

    def run(self, ctx: SkillContext, message: str, level: str) -> Outcome:
        if level not in _LEVELS:
            return Outcome.failure(f"level must be one of {', '.join(_LEVELS)}, got {level!r}")
        ctx.logger.log(_LEVELS[level], message)
        return Outcome.success()
