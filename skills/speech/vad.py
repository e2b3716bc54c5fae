"""Voice activity detection and end of utterance, on frame energy against a tracked noise floor.

The microphone hears room noise all the time; speech is what rises clearly above it. The noise
floor follows the quietest frames (it drops at once, and rises by at most ``rise_db`` a second,
so a long utterance does not become the floor). An utterance starts after ``onset_frames``
frames in a row ``onset_db`` above the floor, and ends after ``end_silence`` seconds below
``offset_db`` above it; it keeps ``preroll`` seconds from before its start (the soft beginning
of a word is under the onset threshold) and ``tail`` seconds after its last loud frame.

Energy is enough here because the noise it must ignore is steady (the simulator's room, white
or pink noise, a fan): at 10 dB SNR voiced speech stands 10-20 dB above the floor. Thresholds
were checked on the benchmark's espeak-ng utterances (tests/bench/bench_speech.py): with a 6 dB
onset over 3 frames, none of 72 utterances at 10 dB SNR (white or pink) was missed and each was
found whole (4 of 72 missed at 5 dB white); a minute of white noise alone starts nothing, a
minute of pink noise (whose power swings more from frame to frame) starts about ten short
false utterances, which the recogniser then rejects. An 8 or 10 dB onset halves or removes
those but starts missing quiet words at 10 dB white noise, so the recogniser does that work.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from botstage.skills.speech.wav import RATE

FRAME = 320  # 20 ms


@dataclass(frozen=True, slots=True)
class Utterance:
    """Speech found in a stream: its samples (pre-roll and tail included) and where they lie."""

    samples: np.ndarray
    start: int  # index in the stream of the first sample
    cut: bool = False  # ended because it reached the longest utterance allowed

    @property
    def duration(self) -> float:
        return self.samples.size / RATE


class VoiceActivityDetector:
    """Feed it audio in chunks of any size; it returns each utterance once it has ended."""

    def __init__(
        self,
        onset_db: float = 6.0,
        offset_db: float = 3.0,
        onset_frames: int = 3,
        end_silence: float = 0.5,
        min_speech: float = 0.1,
        max_utterance: float = 5.0,
        preroll: float = 0.3,
        tail: float = 0.25,
        rise_db: float = 2.5,
    ) -> None:
        if not (0 < offset_db <= onset_db) or onset_frames < 1 or end_silence <= 0 or max_utterance <= 0:
            raise ValueError("need 0 < offset_db <= onset_db, onset_frames >= 1, end_silence > 0, max_utterance > 0")
        self.onset_db, self.offset_db, self.onset_frames = onset_db, offset_db, onset_frames
        self.end_frames = max(1, round(end_silence * RATE / FRAME))
        self.min_frames = max(1, round(min_speech * RATE / FRAME))
        self.max_samples = round(max_utterance * RATE)
        self.preroll = round(preroll * RATE)
        self.tail = round(tail * RATE)
        self.rise = rise_db * FRAME / RATE  # dB a frame
        self.floor_db: float | None = None
        self.heard = False  # any utterance started since the detector was made
        self._pending = np.zeros(0, np.int16)  # samples not yet making a whole frame
        self._position = 0  # stream index of the first pending sample
        self._history: list[np.ndarray] = []  # recent frames, for the pre-roll
        self._above = 0  # frames in a row above the onset threshold
        self._speech: list[np.ndarray] | None = None  # frames of the utterance in progress
        self._start = 0
        self._voiced = 0  # frames of it above the offset threshold
        self._last_voiced = 0  # frames of it up to its last voiced one
        self._quiet = 0  # frames in a row below the offset threshold

    @property
    def in_speech(self) -> bool:
        return self._speech is not None

    def feed(self, samples: np.ndarray) -> list[Utterance]:
        samples = np.asarray(samples, dtype=np.int16)
        data = np.concatenate([self._pending, samples]) if self._pending.size else samples
        whole = data.size - data.size % FRAME
        found: list[Utterance] = []
        if whole:
            frames = data[:whole].reshape(-1, FRAME)
            energies = 10 * np.log10(np.mean(frames.astype(np.float64) ** 2, axis=1) + 1.0)
            for frame, energy in zip(frames, energies, strict=True):
                utterance = self._frame(frame, float(energy))
                self._position += FRAME
                if utterance is not None:
                    found.append(utterance)
        self._pending = data[whole:].copy()
        return found

    def flush(self) -> Utterance | None:
        """End of the stream: the utterance in progress, if it has enough speech in it."""
        if self._speech is None:
            return None
        return self._end(cut=False, keep_all=True)

    # -- per frame --------------------------------------------------------------------------

    def _frame(self, frame: np.ndarray, energy: float) -> Utterance | None:
        floor = self.floor_db
        floor = energy if floor is None else min(energy, floor + self.rise)
        self.floor_db = floor
        if self._speech is None:
            self._history.append(frame)
            keep = self.preroll // FRAME + self.onset_frames
            if len(self._history) > keep:
                del self._history[: len(self._history) - keep]
            self._above = self._above + 1 if energy > floor + self.onset_db else 0
            if self._above >= self.onset_frames:
                self._begin()
            return None
        self._speech.append(frame)
        if energy > floor + self.offset_db:
            self._voiced += 1
            self._quiet = 0
            self._last_voiced = len(self._speech)
        else:
            self._quiet += 1
        if self._quiet >= self.end_frames:
            return self._end(cut=False)
        if len(self._speech) * FRAME >= self.max_samples:
            return self._end(cut=True, keep_all=True)
        return None

    def _begin(self) -> None:
        history = self._history
        self._speech = list(history)
        self._start = self._position + FRAME - len(history) * FRAME
        self._voiced = self._above
        self._last_voiced = len(history)
        self._quiet = 0
        self._history = []
        self._above = 0
        self.heard = True

    def _end(self, cut: bool, keep_all: bool = False) -> Utterance | None:
        speech, voiced = self._speech, self._voiced
        assert speech is not None
        self._speech = None
        frames = speech if keep_all else speech[: self._last_voiced + self.tail // FRAME]
        if self._pending.size and keep_all and not cut:
            frames = [*frames, self._pending]
        if voiced < self.min_frames:
            return None  # a click or a knock, not speech
        return Utterance(np.concatenate(frames), self._start, cut)


def find_utterances(samples: np.ndarray, **options: float) -> list[Utterance]:
    """Every utterance in a recording (one that runs to its end included)."""
    vad = VoiceActivityDetector(**options)  # type: ignore[arg-type]
    found = vad.feed(samples)
    last = vad.flush()
    return found + ([last] if last is not None else [])
