"""`botstage speech recognize` and `python -m tests.bench speech`, as a user and a developer run them."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import wave
from pathlib import Path

import numpy as np
import pytest

from botstage.skills.speech.wav import write_wav

DATA = Path(__file__).parent / "data" / "speech"
CHECKOUT = Path(__file__).resolve().parent.parent


def botstage(*args: str) -> subprocess.CompletedProcess[str]:
    """This checkout's command line (an installed `botstage` may belong to another checkout)."""
    command = [sys.executable, "-c", "from botstage.missions.cli import app; app()", *args]
    return subprocess.run(command, capture_output=True, text=True, cwd=CHECKOUT, timeout=600)


def test_recognize_prints_file_tab_command_per_file(tmp_path: Path) -> None:
    empty = tmp_path / "empty.wav"
    write_wav(empty, np.zeros(0, np.int16))
    files = [DATA / "photo.wav", DATA / "whatsup.wav", DATA / "good_morning.wav", empty, DATA / "ciao.wav"]
    result = botstage("speech", "recognize", *map(str, files))
    assert result.returncode == 0, result.stderr
    assert result.stdout.splitlines() == [
        f"{DATA / 'photo.wav'}\tPHOTO",
        f"{DATA / 'whatsup.wav'}\tWHATSUP",
        f"{DATA / 'good_morning.wav'}\t-",
        f"{empty}\t-",
        f"{DATA / 'ciao.wav'}\tCIAO",
    ]


def test_a_wrong_sample_rate_is_a_clear_error_and_the_other_files_still_run(tmp_path: Path) -> None:
    cd_quality = tmp_path / "cd.wav"
    with wave.open(str(cd_quality), "wb") as wav:
        wav.setnchannels(2)
        wav.setsampwidth(2)
        wav.setframerate(44100)
        wav.writeframes(b"\x00\x00" * 2 * 4410)
    result = botstage("speech", "recognize", str(cd_quality), str(DATA / "yes.wav"))
    assert result.returncode == 1
    assert f"error: {cd_quality}: 44100 Hz, 2 channels, 16-bit; expected 16 kHz mono 16-bit PCM" in result.stderr
    assert result.stdout == f"{DATA / 'yes.wav'}\tYES\n"


def test_a_missing_file_is_an_error(tmp_path: Path) -> None:
    result = botstage("speech", "recognize", str(tmp_path / "nope.wav"))
    assert result.returncode == 1 and "nope.wav" in result.stderr and result.stdout == ""


@pytest.mark.parametrize(("gain", "recognizer"), [(4, "embedding"), (8, "pocketsphinx")])
def test_clipped_audio_is_recognised_with_a_warning(tmp_path: Path, gain: int, recognizer: str) -> None:
    """Clipped audio is decoded, with a warning. x4 clips 2 % of the samples, x8 8 %; each
    recogniser hears CANCEL."""
    from botstage.skills.speech.wav import read_wav

    loud = np.clip(read_wav(DATA / "cancel.wav").astype(np.int32) * gain, -32768, 32767).astype(np.int16)
    path = tmp_path / "loud.wav"
    write_wav(path, loud)
    result = botstage("speech", "recognize", "--recognizer", recognizer, str(path))
    assert result.returncode == 0
    assert result.stdout == f"{path}\tCANCEL\n"
    assert "clipped" in result.stderr


def test_free_mode_prints_the_words() -> None:
    result = botstage("speech", "recognize", "--mode", "free", str(DATA / "nice_weather.wav"))
    assert result.returncode == 0, result.stderr
    path, text = result.stdout.rstrip("\n").split("\t")
    assert path == str(DATA / "nice_weather.wav") and len(text.split()) >= 3


def test_a_bad_mode_is_refused() -> None:
    result = botstage("speech", "recognize", "--mode", "chat", str(DATA / "yes.wav"))
    assert result.returncode == 2 and "--mode must be one of command, free" in result.stderr


def test_bench_speech_quick_prints_its_figures() -> None:
    if shutil.which("espeak-ng") is None:
        if os.environ.get("CI") == "true":
            pytest.fail("espeak-ng is missing: .ci/run installs it (SYSTEM_PACKAGES)")
        pytest.skip("espeak-ng is not installed (apt-get install espeak-ng)")
    result = subprocess.run(
        [sys.executable, "-m", "tests.bench", "speech", "--quick"],
        capture_output=True,
        text=True,
        cwd=CHECKOUT,
        timeout=600,
    )
    assert result.returncode == 0, result.stderr
    row = json.loads(result.stdout.splitlines()[0])
    assert row["bench"] == "speech_commands" and row["voices"] == 3 and row["default"] == "embedding"
    assert set(row["recognizers"]) == {"embedding", "pocketsphinx"}
    for measured in row["recognizers"].values():
        assert set(measured["conditions"]) == {"clean", "white_10db", "pink_10db"}
        for condition in measured["conditions"].values():
            assert set(condition["words"]) == {"PHOTO", "YES", "WHATSUP", "CANCEL", "CIAO"}
            assert 0 <= condition["overall"] <= 100 and 0 <= condition["false_accepts"] <= 100
        assert measured["rtf"] > 0
    assert "paper" in result.stdout and "47.0%" in result.stdout
    assert "embedding / pocketsphinx" in result.stdout


def test_recognize_with_pocketsphinx_on_request() -> None:
    result = botstage("speech", "recognize", "--recognizer", "pocketsphinx", str(DATA / "cancel.wav"))
    assert result.returncode == 0, result.stderr
    assert result.stdout == f"{DATA / 'cancel.wav'}\tCANCEL\n"
    bad = botstage("speech", "recognize", "--recognizer", "whisper", str(DATA / "cancel.wav"))
    assert bad.returncode == 2 and "--recognizer must be one of embedding, pocketsphinx" in bad.stderr
