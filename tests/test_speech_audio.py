"""WAV files and voice activity detection (skills/speech/wav.py, vad.py): no recogniser needed."""

from __future__ import annotations

import wave
from pathlib import Path

import numpy as np
import pytest

from botstage.skills.speech.vad import FRAME, VoiceActivityDetector, find_utterances
from botstage.skills.speech.wav import RATE, WavFormatError, read_wav, write_wav

DATA = Path(__file__).parent / "data" / "speech"


def room(seconds: float, seed: int = 0, dbfs: float = -50.0) -> np.ndarray:
    """The simulator's room noise: white, -50 dBFS."""
    rng = np.random.default_rng(seed)
    return rng.normal(0.0, 32768 * 10 ** (dbfs / 20), round(seconds * RATE))


def burst(seconds: float, amplitude: float = 3000.0, hz: float = 300.0) -> np.ndarray:
    """A voiced-like sound: a tone with a few harmonics."""
    t = np.arange(round(seconds * RATE)) / RATE
    return amplitude * sum(np.sin(2 * np.pi * hz * k * t) / k for k in (1, 2, 3))


def int16(x: np.ndarray) -> np.ndarray:
    return np.clip(np.round(x), -32768, 32767).astype(np.int16)


# -- WAV ------------------------------------------------------------------------------------


def test_a_wav_round_trips(tmp_path: Path) -> None:
    samples = int16(burst(0.2))
    write_wav(tmp_path / "a.wav", samples)
    assert np.array_equal(read_wav(tmp_path / "a.wav"), samples)


def test_the_shipped_test_audio_is_16_khz_mono_and_small() -> None:
    files = sorted(DATA.glob("*.wav"))
    assert len(files) >= 7
    assert sum(f.stat().st_size for f in files) < 1_000_000
    for path in files:
        assert read_wav(path).size > RATE // 2


@pytest.mark.parametrize(
    ("rate", "channels", "width", "found"),
    [(44100, 1, 2, "44100 Hz, 1 channel, 16-bit"), (16000, 2, 2, "16000 Hz, 2 channels"), (16000, 1, 1, "8-bit")],
)
def test_another_format_is_an_error_naming_the_expected_one(
    tmp_path: Path, rate: int, channels: int, width: int, found: str
) -> None:
    path = tmp_path / "other.wav"
    with wave.open(str(path), "wb") as wav:
        wav.setnchannels(channels)
        wav.setsampwidth(width)
        wav.setframerate(rate)
        wav.writeframes(b"\x00" * width * channels * 1000)
    with pytest.raises(WavFormatError) as error:
        read_wav(path)
    assert found in str(error.value) and "expected 16 kHz mono 16-bit PCM" in str(error.value)
    assert "sox" in str(error.value)  # and how to convert it


def test_a_file_that_is_not_a_wav_is_an_error(tmp_path: Path) -> None:
    path = tmp_path / "notes.wav"
    path.write_text("not audio")
    with pytest.raises(WavFormatError, match="not a PCM WAV file"):
        read_wav(path)


def test_an_empty_wav_gives_no_samples(tmp_path: Path) -> None:
    write_wav(tmp_path / "empty.wav", np.zeros(0, np.int16))
    assert read_wav(tmp_path / "empty.wav").size == 0


def test_write_wav_takes_only_int16() -> None:
    with pytest.raises(ValueError, match="int16"):
        write_wav("never.wav", np.zeros(10))


# -- voice activity detection ----------------------------------------------------------------


def test_room_noise_alone_is_no_speech() -> None:
    assert find_utterances(int16(room(10.0))) == []


def test_digital_silence_and_empty_audio_are_no_speech() -> None:
    assert find_utterances(np.zeros(RATE * 3, np.int16)) == []
    assert find_utterances(np.zeros(0, np.int16)) == []


def test_two_utterances_are_found_where_they_are() -> None:
    audio = room(6.0)
    audio[RATE : RATE + 8000] += burst(0.5)  # 1.0-1.5 s
    audio[4 * RATE : 4 * RATE + 12000] += burst(0.75)  # 4.0-4.75 s
    found = find_utterances(int16(audio))
    assert len(found) == 2
    for utterance, (start, end) in zip(found, [(1.0, 1.5), (4.0, 4.75)], strict=True):
        first = utterance.start / RATE
        assert start - 0.35 <= first <= start - 0.25  # the pre-roll
        assert end + 0.2 <= first + utterance.duration <= end + 0.35  # the tail
        assert not utterance.cut


def test_an_utterance_ends_after_the_quiet_not_before() -> None:
    vad = VoiceActivityDetector(end_silence=0.5)
    audio = room(3.0)
    audio[RATE // 2 : RATE] += burst(0.5)
    samples = int16(audio)
    assert vad.feed(samples[: RATE + 6400]) == []  # 0.4 s after the burst: still open
    assert vad.in_speech
    assert len(vad.feed(samples[RATE + 6400 :])) == 1
    assert not vad.in_speech and vad.heard


def test_chunk_sizes_do_not_change_what_is_found() -> None:
    audio = room(4.0, seed=3)
    audio[RATE : RATE + 9000] += burst(0.5625)
    samples = int16(audio)
    whole = find_utterances(samples)
    vad = VoiceActivityDetector()
    pieces = []
    for start in range(0, samples.size, 1013):  # reads that do not fall on frames
        pieces += vad.feed(samples[start : start + 1013])
    assert [(u.start, u.samples.size) for u in pieces] == [(u.start, u.samples.size) for u in whole]
    assert all(np.array_equal(a.samples, b.samples) for a, b in zip(pieces, whole, strict=True))


def test_a_click_is_not_speech() -> None:
    audio = room(2.0)
    audio[RATE : RATE + FRAME * 3] += 20000.0  # 60 ms
    assert find_utterances(int16(audio)) == []


def test_a_long_utterance_is_cut_at_the_maximum() -> None:
    audio = room(9.0)
    audio[RATE : 8 * RATE] += burst(7.0)
    found = find_utterances(int16(audio), max_utterance=3.0)
    assert found[0].cut and found[0].duration == pytest.approx(3.0, abs=FRAME / RATE)
    assert sum(u.duration for u in found) > 6.5


def test_the_noise_floor_follows_the_room() -> None:
    vad = VoiceActivityDetector()
    vad.feed(int16(room(2.0, dbfs=-50)))
    quiet = vad.floor_db
    vad.feed(int16(room(10.0, dbfs=-30)))  # a fan starts: 20 dB louder, and steady (the floor rises 2.5 dB/s)
    assert quiet is not None and vad.floor_db is not None
    assert vad.floor_db == pytest.approx(quiet + 20, abs=2.0)
    assert not vad.in_speech  # a steady fan is not speech once the floor has caught up


def test_bad_thresholds_are_refused() -> None:
    with pytest.raises(ValueError):
        VoiceActivityDetector(onset_db=3, offset_db=6)
