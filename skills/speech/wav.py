"""16 kHz mono 16-bit PCM WAV files: the one format the recogniser takes.

A file in another format is an error that names the expected one rather than being resampled
behind the caller's back: the acoustic model was trained on 16 kHz audio, and a silent
conversion (from 8 kHz telephone audio, say) would hide why recognition got worse. The message
gives the sox command that converts it.
"""

from __future__ import annotations

import wave
from pathlib import Path

import numpy as np

RATE = 16_000  # samples a second
EXPECTED = "16 kHz mono 16-bit PCM"


class WavFormatError(ValueError):
    """A file that is not a 16 kHz mono 16-bit PCM WAV."""


def read_wav(path: str | Path) -> np.ndarray:
    """The samples of a 16 kHz mono 16-bit PCM WAV file, as int16 (possibly empty)."""
    path = Path(path)
    try:
        with wave.open(str(path), "rb") as wav:
            rate, channels, width, frames = (
                wav.getframerate(),
                wav.getnchannels(),
                wav.getsampwidth(),
                wav.getnframes(),
            )
            if (rate, channels, width) != (RATE, 1, 2):
                found = f"{rate} Hz, {channels} channel{'s' if channels != 1 else ''}, {8 * width}-bit"
                raise WavFormatError(
                    f"{path}: {found}; expected {EXPECTED} "
                    f"(convert it: sox {path} -r 16000 -c 1 -b 16 -e signed-integer out.wav)"
                )
            data = wav.readframes(frames)
    except (wave.Error, EOFError) as exc:
        raise WavFormatError(f"{path}: not a PCM WAV file ({exc}); expected {EXPECTED}") from None
    if len(data) % 2:
        data = data[:-1]  # a truncated last sample
    return np.frombuffer(data, dtype="<i2").astype(np.int16)


def write_wav(path: str | Path, samples: np.ndarray) -> None:
    """Write int16 samples as a 16 kHz mono 16-bit PCM WAV file."""
    samples = np.asarray(samples)
    if samples.ndim != 1 or samples.dtype != np.int16:
        raise ValueError(f"samples must be one-dimensional int16, got {samples.dtype} {samples.shape}")
    with wave.open(str(path), "wb") as wav:
        wav.setnchannels(1)
        wav.setsampwidth(2)
        wav.setframerate(RATE)
        wav.writeframes(samples.astype("<i2").tobytes())
