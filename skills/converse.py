"""converse: answer what a visitor said as Maya, or hand a robot command to the mission.

As in chapter 3 of *ROS Robotics Projects*: recognised speech is either a robot command or
conversation for the AIML kernel. A command (PHOTO, YES, WHATSUP, CANCEL, CIAO, or a phrasing
such as "take a picture of us") ends the skill with the outcome ``command`` and the command in
the ``command`` output, so a machine takes it as a transition (``command: photo_ready``) and a
tree branches on ``{command}``; anything else is answered, outcome ``replied`` with the answer
in ``reply`` (and ``command`` None), ready for ``speak``. Missions ask for Maya's own lines with
``cue`` instead of ``text``: ``converse: {cue: COMPLIMENT}`` after a photo.

The kernel's brain is the process's (loaded once, from the brain cache when it can be); the
visitors' memories (``visitor`` picks one) belong to the run. Loading and replying run in the
worker pool: a tick never waits for them.
"""

from __future__ import annotations

import logging
import random
import weakref
from collections.abc import MutableMapping
from concurrent.futures import Future
from dataclasses import dataclass
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from botstage.skills.base import In, Out, Outcome, Seconds, Skill, SkillContext, SkillRun
from botstage.skills.chat.cache import LoadedBrain, shared_brain
from botstage.skills.chat.chatbot import Chatbot
from botstage.skills.chat.kernel import calendar
from botstage.skills.chat.persona import aiml_files
from botstage.skills.chat.routing import route

_log = logging.getLogger("botstage.skills.converse")
CUE = "CUE "  # Maya's lines are categories no visitor says: CUE GREETING, CUE COMPLIMENT...


class ConverseParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    alice: bool = Field(True, description="learn the A.L.I.C.E. set python-aiml ships (small talk)")
    aiml: list[str] = Field(
        default_factory=list,
        description="more AIML files or folders, learnt last so they win (paths from the working directory)",
    )
    predicates: dict[str, str] = Field(
        default_factory=dict, description="bot predicates over Maya's (name, attraction, location...)"
    )
    cache_dir: str | None = Field(
        None, description="brain cache folder (default: $BOTSTAGE_CACHE_DIR, $XDG_CACHE_HOME/botstage/chat...)"
    )


@dataclass
class _RunMaya:
    """One run's Maya for one set of parameters: the future of her loading, then her.

    Replies are answered in the order they were asked (each waits for the one before), so two
    nodes talking to her in the same tick leave the same conversation history in every run.
    """

    future: Future[tuple[Chatbot, LoadedBrain]]
    reported: bool = False
    last: Future[str] | None = None

    def ask(self, ctx: SkillContext, prompt: str, visitor: str, rng: random.Random) -> Future[str]:
        chatbot, _ = self.future.result()
        before = self.last

        def reply() -> str:
            if before is not None:
                before.exception()  # wait for it; its failure is its own asker's to report
            return chatbot.reply(prompt, visitor, rng)

        self.last = ctx.submit(reply)
        return self.last


# a run's Mayas, found through the run's worker pool: the one object every skill of a run shares
_runs: MutableMapping[Any, dict[str, _RunMaya]] = weakref.WeakKeyDictionary()


def _load(params: ConverseParams, now: Any) -> tuple[Chatbot, LoadedBrain]:
    brain = shared_brain(aiml_files(params.alice, params.aiml), params.cache_dir)
    if brain.trie.template_count == 0:
        found = "; ".join(str(p) for p in brain.problems[:3]) or "no AIML files"
        raise RuntimeError(f"no AIML category was learnt ({found})")
    return Chatbot(brain.trie, params.predicates, now), brain


def run_maya(ctx: SkillContext, params: ConverseParams, fallback: dict[str, _RunMaya]) -> _RunMaya:
    """This run's Maya, her loading started on the worker pool the first time she is asked for.

    ``fallback`` holds her when the worker pool cannot be weakly referenced (then she is the node's).
    """
    try:
        mayas = _runs.setdefault(ctx.workers, {})
    except TypeError:
        mayas = fallback
    key = params.model_dump_json()
    maya = mayas.get(key)
    if maya is None:
        maya = mayas[key] = _RunMaya(ctx.submit(_load, params, calendar(ctx.clock)))
    return maya


def _outputs(reply: str, command: str | None, heard: str) -> dict[str, Any]:
    return {"reply": reply, "command": command, "heard": heard}


class Converse(Skill):
    name = "converse"
    description = "Answer `text` as Maya (AIML chatbot), or end with outcome `command` when it is a robot command."
    inputs = {
        "text": In(str, default="", doc="what the visitor said (listen's `text`)"),
        "cue": In(
            str,
            default="",
            doc="instead of `text`: ask for one of Maya's lines (GREETING, INFORMATION, PHOTO READY, "
            "COMPLIMENT, PHOTO CANCELLED, GOODBYE)",
        ),
        "visitor": In(str, default="visitor", doc="who said it: each visitor has a memory of their own"),
        "timeout": In(Seconds, default=10.0, doc="s of mission time to wait for the chatbot to load and answer"),
    }
    outputs = {
        "reply": Out(str, doc="Maya's answer; '' after a command or no input"),
        "command": Out(str | None, doc="PHOTO, YES, WHATSUP, CANCEL or CIAO; None when answered"),
        "heard": Out(str, doc="the visitor's text answered or routed, '' for a cue (it goes to the transcript)"),
    }
    outcomes = ("replied", "command", "no_input", "timeout")
    success_outcomes = ("replied",)
    Params = ConverseParams

    def __init__(self, params: Any = None) -> None:
        super().__init__(params)
        self._mayas: dict[str, _RunMaya] = {}

    def run(self, ctx: SkillContext, text: str, cue: str, visitor: str, timeout: float) -> SkillRun:
        heard, cue = " ".join(text.split()), " ".join(cue.split()).upper()
        if heard and cue:
            return Outcome.failure("give `text` (a visitor spoke) or `cue` (Maya's line), not both")
        if cue:
            prompt = cue if cue.startswith(CUE) else f"{CUE}{cue}"
        elif not heard:
            return Outcome("no_input", "nothing was heard", _outputs("", None, ""))
        else:
            command = route(heard)
            if command is not None:  # commands never wait for the chatbot
                return Outcome("command", f"{command}: {heard!r}", _outputs("", command, heard))
            prompt = heard
        maya = run_maya(ctx, self.params, self._mayas)  # type: ignore[arg-type]
        deadline = ctx.clock.now() + timeout
        while not maya.future.done():
            if ctx.clock.now() >= deadline:
                return Outcome("timeout", f"the chatbot was not loaded within {timeout:g} s")
            yield
        try:
            _, brain = maya.future.result()
        except Exception as error:
            return Outcome.failure(f"the chatbot could not load: {error}")
        if not maya.reported:
            maya.reported = True
            for problem in brain.problems:  # deterministic: the same AIML gives the same problems
                ctx.logger.warning(str(problem))
            for note in brain.notes:  # about this machine's cache: python logging, not the trace
                _log.warning(note)
        rng = random.Random(ctx.rng.getrandbits(64))  # drawn on the engine's thread: same every run
        reply = yield maya.ask(ctx, prompt, visitor, rng)
        return Outcome("replied", "", _outputs(reply, None, heard))
