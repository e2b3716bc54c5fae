"""python-aiml's Kernel made fit for a robot that talks to the public.

- ``<system>`` would run a shell command (with the visitor's words in it, through ``<star/>``),
  ``<learn>`` would read files from the working directory into the shared brain: both answer
  nothing here.
- ``<random>`` draws from the Random given with each reply, not the process-wide one, so a
  seeded mission gives the same replies every run.
- ``<date>`` reads a calendar function: on a simulated clock a fixed day plus the mission time
  (same trace every run), on a real-time clock the real date, which is what a visitor asks.
- The brain is a ``FlatBrain`` over a shared trie; sessions, predicates and history are the
  kernel's own, python-aiml's session API unchanged.
"""

from __future__ import annotations

import random
from collections.abc import Callable, Mapping
from datetime import datetime, timedelta
from typing import Any

from aiml import Kernel

from botstage.robots.clock import Clock
from botstage.skills.chat.brain import FlatBrain, FlatTrie

SIM_EPOCH = datetime(2026, 5, 18, 10, 0, 0)  # a simulated mission starts at opening time on a Monday
_REFUSED = ("system", "learn")


def calendar(clock: Clock) -> Callable[[], datetime]:
    """The date and time ``<date>`` tells: deterministic in simulation, real on a robot."""
    if clock.simulated:
        return lambda: SIM_EPOCH + timedelta(seconds=clock.now())
    return datetime.now


class SafeKernel(Kernel):
    """A python-aiml kernel over a shared flat brain, with its own bot predicates and sessions."""

    def __init__(
        self,
        trie: FlatTrie,
        predicates: Mapping[str, str],
        now: Callable[[], datetime] = datetime.now,
    ) -> None:
        super().__init__()
        self.verbose(False)  # python-aiml prints every unmatched input to stderr otherwise
        self._brain = FlatBrain(trie)
        for name, value in predicates.items():
            self.setBotPredicate(name, value)
        self._rng = random.Random(0)
        self._now = now
        for tag in _REFUSED:
            self._elementProcessors[tag] = self._refuse
        self._elementProcessors["random"] = self._process_random
        self._elementProcessors["date"] = self._process_date

    def reply(self, text: str, session: str, rng: random.Random) -> str:
        """``respond`` with ``rng`` behind every ``<random>`` of this reply."""
        with self._respondLock:  # re-entrant: respond takes it again
            self._rng = rng
            return self.respond(text, session)

    def _refuse(self, elem: list[Any], session: str) -> str:
        return ""

    def _process_random(self, elem: list[Any], session: str) -> str:
        items = [e for e in elem[2:] if e[0] == "li"]
        if not items:
            return ""
        return self._processElement(self._rng.choice(items), session)

    def _process_date(self, elem: list[Any], session: str) -> str:
        return self._now().strftime("%a %b %d %H:%M:%S %Y")  # time.asctime()'s format, as python-aiml
