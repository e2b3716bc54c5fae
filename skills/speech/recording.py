"""What a whole recording says: its utterances tried in turn until the recogniser accepts one, as
`botstage speech recognize` reports it for a WAV file."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from botstage.skills.speech.recognizer import CommandRecognizer
from botstage.skills.speech.vad import find_utterances


@dataclass(frozen=True, slots=True)
class Heard:
    found: str | None  # the command (free mode: the words) of the first accepted utterance; None if none
    clipped: float  # the largest clipped share among the utterances tried: a recording made too loud


def recognize_recording(recognizer: CommandRecognizer, samples: np.ndarray, mode: str = "command") -> Heard:
    clipped = 0.0
    for utterance in find_utterances(samples):
        result = recognizer.recognize(utterance.samples, mode)
        clipped = max(clipped, result.clipped)
        if result.accepted:
            return Heard(result.command if mode == "command" else result.text, clipped)
    return Heard(None, clipped)
