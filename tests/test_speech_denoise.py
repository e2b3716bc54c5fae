"""Noise suppression before decoding (skills/speech/denoise.py) and where the recogniser uses it."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from botstage.skills.speech.denoise import estimate_snr, suppress_noise
from botstage.skills.speech.recognizer import Recognizer, shared_recognizer
from botstage.skills.speech.wav import read_wav

DATA = Path(__file__).parent / "data" / "speech"


def noisy(name: str, snr_db: float, seed: int) -> np.ndarray:
    """A committed clip with half a second of room silence either side, in white noise at ``snr_db``
    over the speech's active part (as the benchmark mixes it)."""
    speech = read_wav(DATA / f"{name}.wav").astype(float)
    active = np.abs(speech) > 0.02 * np.abs(speech).max()
    power = np.mean(speech[active] ** 2)
    x = np.concatenate([np.zeros(8000), speech, np.zeros(8000)])
    x += np.random.default_rng(seed).normal(0.0, np.sqrt(power / 10 ** (snr_db / 10)), x.size)
    return np.clip(np.round(x), -32768, 32767).astype(np.int16)


def test_the_snr_estimate_tells_noisy_from_clean_speech() -> None:
    clean = read_wav(DATA / "cancel.wav")
    assert estimate_snr(clean) > 30
    assert 8 < estimate_snr(noisy("cancel", 10.0, 0)) < 14
    assert estimate_snr(np.zeros(100, np.int16)) == 0.0  # too short to tell


def test_suppression_removes_the_noise_and_keeps_the_speech() -> None:
    x = noisy("photo", 10.0, 1)
    y = suppress_noise(x)
    assert y.dtype == np.int16 and y.size == x.size
    lead = slice(0, 6000)  # noise only
    assert np.mean(y[lead].astype(float) ** 2) < np.mean(x[lead].astype(float) ** 2) / 10  # over 10 dB less
    speech = read_wav(DATA / "photo.wav").astype(float)
    kept = y[8000 : 8000 + speech.size].astype(float)
    assert np.corrcoef(kept, speech)[0, 1] > 0.8
    assert np.array_equal(suppress_noise(np.ones(10, np.int16)), np.ones(10, np.int16))  # too short: untouched


def test_noisy_speech_is_denoised_and_recognised() -> None:
    x = noisy("whatsup", 10.0, 0)
    assert shared_recognizer().recognize(x).command == "WHATSUP"
    without = Recognizer(denoise_below=None).recognize(x)
    assert not without.accepted and without.text == "what"  # the noise hides "up"
