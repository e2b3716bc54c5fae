"""How a run can refuse to start or end early: an invalid mission, a run that cannot be done, a stop."""

from __future__ import annotations

from collections.abc import Sequence

from botstage.missions.loader import Problem


class MissionInvalid(Exception):
    def __init__(self, problems: list[Problem]) -> None:
        self.problems = problems
        super().__init__("\n".join(str(p) for p in problems))


class RunError(Exception):
    """The mission is valid but cannot run as asked (for example, no hardware for it).

    ``problems`` are located in a file (a robot profile's backend options) and printed as they
    are; the message, if any, gets an ``error:`` prefix.
    """

    def __init__(self, message: str, problems: Sequence[Problem] = ()) -> None:
        self.message = message
        self.problems = list(problems)
        super().__init__("\n".join([*([message] if message else []), *map(str, self.problems)]))

    def lines(self) -> list[str]:
        """What a command line prints, one line per problem."""
        return [str(p) for p in self.problems] + [f"error: {line}" for line in self.message.splitlines()]


class StopRun(Exception):
    """Raised by a ``before_tick`` hook to end a run early (a scenario's `never` condition held)."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason
