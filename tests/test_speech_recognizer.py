"""The recogniser (skills/speech/recognizer.py) on the committed espeak-ng WAVs.

tests/data/speech/ holds espeak-ng's en-us voice at 160 words a minute, resampled to 16 kHz
and trimmed: the five commands, a phrase that is none ("good morning") and a sentence for
free mode. They were made with tests/bench/bench_speech.py's ``synthesise``, so these tests
need no espeak-ng.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from botstage.skills.speech.recognizer import COMMANDS, Recognizer, garbage_words, shared_recognizer
from botstage.skills.speech.vad import find_utterances
from botstage.skills.speech.wav import read_wav

DATA = Path(__file__).parent / "data" / "speech"


def recognise(name: str, **options: object):
    samples = read_wav(DATA / f"{name}.wav")
    return shared_recognizer().recognize(samples, **options)  # type: ignore[arg-type]


@pytest.mark.parametrize("command", COMMANDS)
def test_each_command_is_recognised(command: str) -> None:
    result = recognise(command.lower())
    assert result.accepted, result.reason
    assert result.command == command and result.text == command.lower()
    assert result.confidence >= 0.7


def test_a_phrase_that_is_no_command_is_rejected() -> None:
    result = recognise("good_morning")
    assert not result.accepted and result.command == ""
    assert result.text  # decoded as garbage words, which is why it is rejected
    assert "no command" in result.reason


def test_a_command_not_asked_for_is_rejected_with_why() -> None:
    result = recognise("photo", commands=("YES", "CANCEL"))
    assert not result.accepted and result.command == "PHOTO"
    assert result.reason == "PHOTO is not wanted now"


def test_free_mode_returns_words_and_no_command() -> None:
    result = recognise("nice_weather", mode="free")
    assert result.accepted and result.command == ""
    assert len(result.text.split()) >= 3
    assert 0.0 <= result.confidence <= 1.0


def test_empty_audio_is_not_accepted() -> None:
    for samples in (np.zeros(0, np.int16), np.zeros(800, np.int16)):
        result = shared_recognizer().recognize(samples)
        assert not result.accepted and result.reason in ("no audio", "too short")


def test_silence_and_room_noise_are_not_accepted() -> None:
    rng = np.random.default_rng(0)
    for samples in (np.zeros(16000, np.int16), rng.normal(0, 100, 32000).astype(np.int16)):
        assert not shared_recognizer().recognize(samples).accepted


def test_clipped_speech_is_still_recognised_and_the_clipping_measured() -> None:
    samples = read_wav(DATA / "yes.wav").astype(np.int32)
    loud = np.clip(samples * 6, -32768, 32767).astype(np.int16)  # recorded far too loud
    result = shared_recognizer().recognize(loud)
    assert result.clipped > 0.03  # of all samples, the pauses included
    assert result.accepted and result.command == "YES", result.reason


def test_a_full_scale_square_wave_is_not_a_command() -> None:
    t = np.arange(16000)
    square = np.where((t // 40) % 2 == 0, 32767, -32768).astype(np.int16)  # 200 Hz, all clipped
    result = shared_recognizer().recognize(square)
    assert result.clipped > 0.9 and not result.accepted


def test_results_do_not_depend_on_what_was_decoded_before() -> None:
    recognizer = Recognizer()
    audio = {name: read_wav(DATA / f"{name}.wav") for name in ("cancel", "good_morning", "ciao")}
    forwards = [recognizer.recognize(audio[n]) for n in ("cancel", "good_morning", "ciao")]
    backwards = [recognizer.recognize(audio[n]) for n in ("ciao", "good_morning", "cancel")][::-1]
    assert forwards == backwards


def test_a_file_goes_through_the_vad_as_the_cli_does() -> None:
    samples = read_wav(DATA / "ciao.wav")
    padded = np.concatenate([np.zeros(16000, np.int16), samples, np.zeros(16000, np.int16)])
    utterances = find_utterances(padded)
    assert len(utterances) == 1
    assert shared_recognizer().recognize(utterances[0].samples).command == "CIAO"


def test_bad_arguments_raise() -> None:
    with pytest.raises(ValueError, match="int16"):
        shared_recognizer().recognize(np.zeros(16000))
    with pytest.raises(ValueError, match="mode"):
        shared_recognizer().recognize(np.zeros(16000, np.int16), mode="chat")
    with pytest.raises(ValueError):
        Recognizer(command_mass=1.0)


def test_the_garbage_model_holds_no_command_and_is_ordered_by_frequency() -> None:
    words = garbage_words()
    assert len(words) == 2000
    names = {w for w, _ in words}
    assert not names & {"photo", "yes", "whatsup", "cancel", "ciao", "chow"}
    probabilities = [p for _, p in words]
    assert probabilities == sorted(probabilities, reverse=True)
    model = Recognizer(garbage=50).arpa()
    assert "ngram 1=57" in model and " whatsup" in model and "\\end\\" in model
