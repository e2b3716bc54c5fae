"""speak: say a text through the robot's speaker, as espeak-ng speech when it can.

With espeak-ng installed and a speaker that plays audio (``AudioSpeaker``), the text is
synthesised in the worker pool and the samples are played; otherwise the speaker gets the text
alone (a plain ``Speaker`` speaks or shows it its own way). With ``wait`` the skill runs until
the speaker is done; cancelled meanwhile, it stops the speech. What was said is the ``said``
output, which the run's transcript collects.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from botstage.robots.interfaces import AudioSpeaker
from botstage.skills.base import In, Out, Outcome, Skill, SkillContext, SkillRun
from botstage.skills.tts import MAYA_VOICE, Speech, SpeechError, espeak_ng, synthesise


class SpeakParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    engine: Literal["auto", "espeak-ng", "text"] = Field(
        "auto", description="auto: espeak-ng when installed, else text; espeak-ng: fail without it; text: never audio"
    )
    voice: str = Field(MAYA_VOICE, description="an espeak-ng voice (espeak-ng --voices)")
    words_per_minute: int = Field(160, ge=80, le=450, description="espeak-ng's speed")
    max_wait: float = Field(120.0, gt=0, description="s of mission time to wait for the speaker (with wait)")


def _synthesise(text: str, params: SpeakParams) -> Speech | str:
    """Speech, or why there is none (a reason, so the skill decides what to make of it)."""
    try:
        return synthesise(text, params.voice, params.words_per_minute)
    except SpeechError as error:
        return str(error)


class Speak(Skill):
    name = "speak"
    description = "Say `text` through the speaker (espeak-ng speech when installed); with `wait`, until it is said."
    inputs = {
        "text": In(str, doc="what to say; '' says nothing and succeeds"),
        "wait": In(bool, default=True, doc="run until the speaker is done (false: return once it started)"),
    }
    outputs = {"said": Out(str, doc="the text handed to the speaker (it goes to the run's transcript)")}
    Params = SpeakParams

    def run(self, ctx: SkillContext, text: str, wait: bool) -> SkillRun:
        text = " ".join(text.split())
        if not text:
            return Outcome.success("nothing to say", said="")
        params: SpeakParams = self.params  # type: ignore[assignment]
        speaker = ctx.interface("speaker")
        speech: Speech | None = None
        if params.engine != "text":
            if not isinstance(speaker, AudioSpeaker):
                if params.engine == "espeak-ng":
                    return Outcome.failure(f"the speaker ({type(speaker).__name__}) does not play audio")
            elif espeak_ng() is None:
                if params.engine == "espeak-ng":
                    return Outcome.failure("espeak-ng is not installed (apt-get install espeak-ng)")
            else:
                made = yield ctx.submit(_synthesise, text, params)
                if isinstance(made, Speech):
                    speech = made
                elif params.engine == "espeak-ng":
                    return Outcome.failure(made)
                else:
                    ctx.logger.debug(f"speaking as text: {made}")
        ctx.logger.info(f"says: {text}")
        started = ctx.clock.now()
        if speech is not None:
            speaker.play(speech.samples, speech.rate_hz, text)
        else:
            speaker.say(text)
        if not wait:
            return Outcome.success(said=text)
        finished = False
        try:
            while speaker.busy():
                if ctx.clock.now() - started >= params.max_wait:
                    return Outcome.failure(f"the speaker was still busy after {params.max_wait:g} s", said=text)
                yield
            finished = True
        finally:
            if not finished and isinstance(speaker, AudioSpeaker):
                speaker.stop()  # cancelled (or given up on): the robot stops talking
        return Outcome.success(said=text)
