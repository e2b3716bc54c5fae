"""Text to speech with espeak-ng: text in, mono int16 samples and their rate out.

espeak-ng writes a WAV to stdout (``--stdout``) whose RIFF and data sizes are placeholders
(it streams, so it cannot know them): the reader here walks the chunks and takes whatever the
data chunk holds. The text goes in on stdin, so a text starting with "-" is never an option.
"""

from __future__ import annotations

import shutil
import struct
import subprocess
from dataclasses import dataclass
from functools import cache

import numpy as np

ESPEAK_NG = "espeak-ng"
MAYA_VOICE = "en-us+f3"  # an American English voice with a female variant: Maya's


class SpeechError(RuntimeError):
    """Speech could not be made (no espeak-ng, an unknown voice, a broken WAV)."""


@dataclass(frozen=True)
class Speech:
    samples: np.ndarray  # mono int16
    rate_hz: int

    @property
    def seconds(self) -> float:
        return self.samples.size / self.rate_hz


@cache
def espeak_ng() -> str | None:
    """Where espeak-ng is installed, or None (looked up once: a skill asks on the engine's thread)."""
    return shutil.which(ESPEAK_NG)


def synthesise(
    text: str,
    voice: str = MAYA_VOICE,
    words_per_minute: int = 160,
    executable: str | None = None,
    timeout_s: float = 60.0,
) -> Speech:
    """``text`` spoken by espeak-ng. Blocking (a subprocess): call it through ``ctx.submit``."""
    exe = executable or espeak_ng()
    if exe is None:
        raise SpeechError("espeak-ng is not installed (apt-get install espeak-ng)")
    command = [exe, "--stdout", "--stdin", "-v", voice, "-s", str(words_per_minute)]
    try:
        done = subprocess.run(command, input=text.encode(), capture_output=True, timeout=timeout_s, check=False)
    except (OSError, subprocess.TimeoutExpired) as error:
        raise SpeechError(f"espeak-ng did not run: {error}") from None
    if done.returncode != 0:
        message = done.stderr.decode(errors="replace").strip() or f"exit status {done.returncode}"
        raise SpeechError(f"espeak-ng failed: {message}")
    return read_wav(done.stdout)


def read_wav(data: bytes) -> Speech:
    """Mono 16-bit PCM from a WAV, including espeak-ng's streamed one with placeholder sizes."""
    if len(data) < 12 or data[:4] != b"RIFF" or data[8:12] != b"WAVE":
        raise SpeechError("not a WAV file")
    position, fmt = 12, None
    while position + 8 <= len(data):
        chunk, size = data[position : position + 4], int.from_bytes(data[position + 4 : position + 8], "little")
        body = position + 8
        if chunk == b"fmt ":
            if size < 16 or body + 16 > len(data):
                raise SpeechError("truncated fmt chunk")
            fmt = struct.unpack("<HHIIHH", data[body : body + 16])
        elif chunk == b"data":
            if fmt is None:
                raise SpeechError("data chunk before the fmt chunk")
            encoding, channels, rate, _, _, bits = fmt
            if encoding != 1 or bits != 16 or channels != 1:
                raise SpeechError(f"expected mono 16-bit PCM, got format {encoding}, {channels} channels, {bits} bits")
            end = min(body + size, len(data))
            end -= (end - body) % 2
            samples = np.frombuffer(data[body:end], dtype="<i2").astype(np.int16)
            return Speech(samples, rate)
        position = body + size + (size & 1)
    raise SpeechError("no data chunk")
