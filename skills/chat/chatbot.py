"""Maya for one run or one terminal chat: the shared brain, her predicates, a session per visitor.

The brain (the learnt patterns) is the process's, loaded once; what Maya remembers about
visitors (names, the last thing she said, the topic) lives in python-aiml sessions, one per
visitor id, and belongs to this Chatbot alone, so two missions never share a visitor's memory.
"""

from __future__ import annotations

import random
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from datetime import datetime

from botstage.skills.chat.brain import FlatTrie
from botstage.skills.chat.kernel import SafeKernel
from botstage.skills.chat.persona import MAYA_PREDICATES
from botstage.skills.chat.routing import route

FALLBACK_CUE = "CUE FALLBACK"  # Maya's line when no category matches (see aiml/maya-fallback.aiml)


@dataclass(frozen=True, slots=True)
class Turn:
    """What a visitor said and what came of it: a command for the mission, or Maya's reply."""

    text: str
    command: str | None
    reply: str


class Chatbot:
    def __init__(
        self,
        trie: FlatTrie,
        predicates: Mapping[str, str] | None = None,
        now: Callable[[], datetime] = datetime.now,
        seed: int | str = 0,
    ) -> None:
        self.kernel = SafeKernel(trie, {**MAYA_PREDICATES, **(predicates or {})}, now)
        self._rng = random.Random(seed)

    @staticmethod
    def session(visitor: str) -> str:
        """A visitor's python-aiml session id (kept apart from the kernel's own ``_global``)."""
        return f"visitor:{visitor}"

    def reply(self, text: str, visitor: str, rng: random.Random | None = None) -> str:
        """Maya's answer to ``text`` from ``visitor``; her fallback line when nothing matches."""
        rng = rng or self._rng
        session = self.session(visitor)
        answer = self.kernel.reply(text, session, rng)
        if not answer.strip():
            answer = self.kernel.reply(FALLBACK_CUE, session, rng)
        return " ".join(answer.split())  # A.L.I.C.E.'s templates leave runs of spaces

    def turn(self, text: str, visitor: str, rng: random.Random | None = None) -> Turn:
        """A command goes to the mission unanswered; anything else gets Maya's reply."""
        command = route(text)
        if command is not None:
            return Turn(text, command, "")
        return Turn(text, None, self.reply(text, visitor, rng))

    def predicate(self, visitor: str, name: str) -> str:
        """What Maya remembers about a visitor (``name``, ``topic``...): "" when nothing."""
        return self.kernel.getPredicate(name, self.session(visitor))

    @property
    def visitors(self) -> list[str]:
        prefix = self.session("")
        return sorted(s[len(prefix) :] for s in self.kernel.getSessionData() if s.startswith(prefix))
