"""listen: wait for a spoken command (PHOTO, YES, WHATSUP, CANCEL, CIAO) or free speech.

The microphone is read every tick and its audio goes through voice activity detection in the
tick (a few microseconds of numpy a chunk); an utterance that has ended goes to the recogniser
through ``ctx.submit``, so decoding never blocks a tick. Commands go to the speech-embedding
recogniser (skills/speech/embedding.py) unless the ``recognizer`` parameter says
``pocketsphinx``; free speech always goes to pocketsphinx. An utterance the recogniser rejects
(out of the grammar, too unsure) does not end the skill: it listens on until ``timeout``.

Outcomes: ``heard`` (the success outcome; outputs command, text, confidence), ``silence``
(nothing that sounded like speech before ``timeout``), ``timeout`` (speech was heard, but none of
it was accepted before ``timeout``), ``failure`` (no microphone, bad inputs).
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, Field

from botstage.skills.base import In, Out, Outcome, Seconds, Skill, SkillContext, SkillRun
from botstage.skills.speech.recognizer import COMMANDS, MODES, Recognition
from botstage.skills.speech.recognizers import recognizer_named
from botstage.skills.speech.vad import VoiceActivityDetector
from botstage.skills.speech.wav import RATE

# Times are products of tick counts and periods; compare with a tolerance far below one tick.
_EPSILON = 1e-9


class ListenParams(BaseModel):
    """How utterances are cut from the stream (see skills/speech/vad.py for why these values)."""

    onset_db: float = Field(default=6.0, gt=0, description="dB above the noise floor that starts speech")
    offset_db: float = Field(default=3.0, gt=0, description="dB above the noise floor that still counts as speech")
    end_silence: float = Field(default=0.5, gt=0, description="s of quiet that ends an utterance")
    max_utterance: float = Field(default=5.0, gt=0, description="s: a longer utterance is cut and decoded")
    context: float = Field(default=0.3, ge=0, description="s of audio from before the skill started that it keeps")
    recognizer: Literal["embedding", "pocketsphinx"] = Field(
        default="embedding",
        description="commands: the speech-embedding classifier or pocketsphinx (free speech: always pocketsphinx)",
    )


class Listen(Skill):
    name = "listen"
    description = "Listen for a spoken command (PHOTO, YES, WHATSUP, CANCEL, CIAO) or, with mode `free`, any speech."
    inputs = {
        "mode": In(str, default="command", doc="`command`: one of `commands`; `free`: any English (language model)"),
        "commands": In(list[str], default=[], doc="the commands to accept (default: all five)"),
        "timeout": In(Seconds, default=10.0, doc="s of mission time to wait for an accepted utterance"),
    }
    outputs = {
        "command": Out(str, doc="the command heard, upper case (empty in free mode when none was said)"),
        "text": Out(str, doc="what was recognised, lower case"),
        "confidence": Out(float, doc="0-1: how sure the recogniser is (command mode: see recognizer.py)"),
        "heard": Out(str, doc="what was accepted, for the run's transcript ('' when nothing was)"),
    }
    outcomes = ("heard", "silence", "timeout")
    success_outcomes = ("heard",)
    Params = ListenParams

    def run(self, ctx: SkillContext, mode: str, commands: list[str], timeout: float) -> SkillRun:
        if mode not in MODES:
            return Outcome.failure(f"mode must be one of {', '.join(MODES)}, got {mode!r}")
        wanted = tuple(c.upper() for c in commands) or COMMANDS
        unknown = [c for c in wanted if c not in COMMANDS]
        if unknown:
            return Outcome.failure(f"unknown command(s) {', '.join(unknown)} (known: {', '.join(COMMANDS)})")
        if timeout <= 0:
            return Outcome.failure(f"timeout must be positive, got {timeout}")
        microphone = ctx.interface("microphone")
        params: ListenParams = self.params  # type: ignore[assignment]
        vad = VoiceActivityDetector(
            onset_db=params.onset_db,
            offset_db=params.offset_db,
            end_silence=params.end_silence,
            max_utterance=params.max_utterance,
        )
        recognizer = recognizer_named(params.recognizer)
        earlier = microphone.read()  # what it heard before we listened: only the room's level matters
        keep = round(params.context * RATE)
        if keep and earlier.size:
            vad.feed(earlier[-keep:])
        deadline = ctx.clock.now() + timeout - _EPSILON
        rejected: list[Recognition] = []
        while True:
            over = ctx.clock.now() >= deadline
            utterances = vad.feed(microphone.read())
            if over:
                last = vad.flush()  # speech cut off by the deadline is still worth decoding
                utterances += [last] if last is not None else []
            for utterance in utterances:
                result: Recognition = yield ctx.submit(recognizer.recognize, utterance.samples, mode, wanted)
                if result.accepted:
                    return Outcome(
                        "heard",
                        f"heard {result.command or result.text!r} ({result.confidence:.2f})",
                        {**result.outputs(), "heard": result.text},
                    )
                rejected.append(result)
                ctx.logger.info(f"not accepted: {result.reason}")
            if over:
                return self._nothing(vad.heard, rejected, timeout)
            yield

    @staticmethod
    def _nothing(heard: bool, rejected: list[Recognition], timeout: float) -> Outcome:
        empty: dict[str, Any] = {"command": "", "text": "", "confidence": 0.0, "heard": ""}
        if not heard:
            return Outcome("silence", f"no speech in {timeout:g} s", empty)
        if not rejected:
            return Outcome("timeout", f"speech but no complete utterance in {timeout:g} s", empty)
        best = max(rejected, key=lambda r: r.confidence)
        return Outcome(
            "timeout",
            f"{len(rejected)} utterance(s) in {timeout:g} s, none accepted (best: {best.reason})",
            {"command": "", "text": best.text, "confidence": best.confidence, "heard": ""},
        )
