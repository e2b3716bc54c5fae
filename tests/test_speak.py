"""speak: espeak-ng speech to the speaker (or the text alone), waiting or not, cancelled; the run's
transcript of who said what."""

from __future__ import annotations

import json
import math
import struct
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from botstage.missions.runner import run as run_mission
from botstage.missions.transcript import read_transcript
from botstage.robots.clock import SimClock
from botstage.robots.interfaces import AudioSpeaker, Speaker
from botstage.robots.sim.devices import SimSpeaker
from botstage.skills.speak import Speak
from botstage.skills.tts import SpeechError, read_wav, synthesise
from tests.test_converse import Harness, brain_cache, isolated_cache  # noqa: F401 (fixtures: the test cache)
from tests.tools import require


def wav(samples: np.ndarray, rate: int = 22050, channels: int = 1, bits: int = 16, streamed: bool = True) -> bytes:
    """A WAV as espeak-ng --stdout writes it: RIFF and data sizes are placeholders when streamed."""
    data = samples.astype("<i2").tobytes()
    riff, size = (0x7FFFF024, 0x7FFFF000) if streamed else (36 + len(data), len(data))
    fmt = struct.pack("<HHIIHH", 1, channels, rate, rate * channels * bits // 8, channels * bits // 8, bits)
    return (
        b"RIFF"
        + struct.pack("<I", riff)
        + b"WAVE"
        + b"fmt "
        + struct.pack("<I", 16)
        + fmt
        + b"data"
        + (struct.pack("<I", size) + data)
    )


@pytest.fixture
def speaker() -> Iterator[tuple[Harness, SimSpeaker]]:
    harness = Harness()
    sim_speaker = SimSpeaker(harness.clock)
    harness.interfaces["speaker"] = sim_speaker
    yield harness, sim_speaker
    harness.close()


@pytest.fixture
def no_espeak(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("botstage.skills.speak.espeak_ng", lambda: None)


# -- WAV --------------------------------------------------------------------------------------


@pytest.mark.parametrize("streamed", [True, False])
def test_wav_with_placeholder_sizes_is_read_whole(streamed: bool) -> None:
    samples = (np.sin(np.arange(2205) / 5) * 12000).astype(np.int16)
    speech = read_wav(wav(samples, streamed=streamed))
    assert speech.rate_hz == 22050
    assert np.array_equal(speech.samples, samples)
    assert speech.seconds == pytest.approx(0.1)


@pytest.mark.parametrize(
    ("data", "message"),
    [
        (b"not a wav at all", "not a WAV"),
        (wav(np.zeros(10, np.int16), channels=2), "expected mono 16-bit PCM"),
        (wav(np.zeros(10, np.int16), bits=8), "expected mono 16-bit PCM"),
        (wav(np.zeros(10, np.int16))[:36], "no data chunk"),
    ],
)
def test_a_bad_wav_is_a_speech_error(data: bytes, message: str) -> None:
    with pytest.raises(SpeechError, match=message):
        read_wav(data)


# -- speaking without espeak-ng ---------------------------------------------------------------


def test_without_espeak_ng_the_speaker_gets_the_text(speaker: tuple[Harness, SimSpeaker], no_espeak: None) -> None:
    harness, sim_speaker = speaker
    outcome, ticks = harness.run(Speak(), text="Hello, I am  Maya!")
    assert outcome.name == "success" and outcome.outputs == {"said": "Hello, I am Maya!"}
    assert sim_speaker.said == [(0.0, "Hello, I am Maya!")] and sim_speaker.played == []
    assert ticks == 16  # the sim speaker's 0.4 s a word, waited for on the mission clock
    assert not sim_speaker.busy()
    assert harness.logs == ["info: says: Hello, I am Maya!"]


def test_engine_espeak_ng_without_it_fails_with_the_reason(
    speaker: tuple[Harness, SimSpeaker], no_espeak: None
) -> None:
    harness, sim_speaker = speaker
    outcome, _ = harness.run(Speak({"engine": "espeak-ng"}), text="hello")
    assert outcome.name == "failure" and "espeak-ng is not installed" in outcome.reason
    assert sim_speaker.said == []


def test_without_wait_it_returns_while_the_speaker_talks(speaker: tuple[Harness, SimSpeaker], no_espeak: None) -> None:
    harness, sim_speaker = speaker
    outcome, ticks = harness.run(Speak(), text="one two three", wait=False)
    assert (outcome.name, ticks, outcome.outputs["said"]) == ("success", 0, "one two three")
    assert sim_speaker.busy()


def test_nothing_to_say_says_nothing(speaker: tuple[Harness, SimSpeaker]) -> None:
    harness, sim_speaker = speaker
    outcome, ticks = harness.run(Speak(), text="  ")
    assert (outcome.name, outcome.reason, outcome.outputs, ticks) == ("success", "nothing to say", {"said": ""}, 0)
    assert sim_speaker.said == []


class PlainSpeaker:
    """A speaker that takes text only (its own voice): no play, no stop."""

    def __init__(self) -> None:
        self.said: list[str] = []

    def say(self, text: str) -> None:
        self.said.append(text)

    def busy(self) -> bool:
        return False


def test_a_speaker_without_audio_gets_the_text_and_no_synthesis_runs() -> None:
    plain = PlainSpeaker()
    assert isinstance(plain, Speaker) and not isinstance(plain, AudioSpeaker)
    harness = Harness({"speaker": plain})
    try:
        outcome, ticks = harness.run(Speak(), text="hello there")
        assert (outcome.name, ticks, plain.said) == ("success", 0, ["hello there"])
        assert harness.run(Speak({"engine": "espeak-ng"}), text="hi")[0].reason.startswith("the speaker (PlainSpeaker)")
    finally:
        harness.close()


class StuckSpeaker(SimSpeaker):
    def busy(self) -> bool:
        return True


def test_a_speaker_that_never_finishes_is_given_up_on(no_espeak: None) -> None:
    harness = Harness()
    stuck = StuckSpeaker(harness.clock)
    harness.interfaces["speaker"] = stuck
    try:
        outcome, ticks = harness.run(Speak({"max_wait": 2.0}), text="hello")
    finally:
        harness.close()
    assert (outcome.name, ticks) == ("failure", 20)
    assert "still busy after 2 s" in outcome.reason


def test_cancelling_stops_the_speech(speaker: tuple[Harness, SimSpeaker], no_espeak: None) -> None:
    harness, sim_speaker = speaker
    run = harness.execution(Speak())
    assert run.start({"text": "a long sentence that takes a while to say"}) is None
    harness.tick()
    assert run.step() is None and sim_speaker.busy()
    assert run.cancel() is None
    assert not sim_speaker.busy()


def test_the_sim_speaker_checks_what_it_plays() -> None:
    sim_speaker = SimSpeaker(SimClock(10))
    with pytest.raises(ValueError, match="int16"):
        sim_speaker.play(np.zeros(100, np.float32), 16000)
    with pytest.raises(ValueError, match="positive"):
        sim_speaker.play(np.zeros(100, np.int16), 0)
    sim_speaker.play(np.zeros(8000, np.int16), 16000, "half a second")
    assert sim_speaker.busy() and sim_speaker.said == [(0.0, "half a second")]


# -- speaking with espeak-ng ------------------------------------------------------------------


@pytest.fixture
def espeak() -> str:
    return require("espeak-ng", "espeak-ng")


def test_espeak_ng_speech_is_played_and_waited_for(speaker: tuple[Harness, SimSpeaker], espeak: str) -> None:
    harness, sim_speaker = speaker
    outcome, ticks = harness.run(Speak(), text="Hello! I am Maya, the robot of the museum.")
    assert outcome.name == "success" and outcome.outputs["said"] == "Hello! I am Maya, the robot of the museum."
    [(t, text, samples, rate)] = sim_speaker.played
    assert (t, text, rate) == (0.1, "Hello! I am Maya, the robot of the museum.", 22050)  # after a tick of synthesis
    assert samples.dtype == np.int16 and samples.ndim == 1
    seconds = samples.size / rate
    assert 1.0 < seconds < 6.0  # nine words at 160 words a minute
    assert np.sqrt(np.mean(samples.astype(float) ** 2)) > 500  # speech, not silence
    assert ticks == 1 + math.ceil(round(seconds / 0.1, 6))  # synthesis, then until the speaker is done


def test_the_speed_parameter_reaches_espeak_ng(espeak: str) -> None:
    slow = synthesise("photos for everybody in the museum", words_per_minute=100)
    fast = synthesise("photos for everybody in the museum", words_per_minute=300)
    assert slow.seconds > 1.8 * fast.seconds


def test_an_unknown_voice(speaker: tuple[Harness, SimSpeaker], espeak: str) -> None:
    harness, sim_speaker = speaker
    outcome, _ = harness.run(Speak({"engine": "espeak-ng", "voice": "xx-nonexistent"}), text="hello")
    assert outcome.name == "failure" and "voice does not exist" in outcome.reason
    assert sim_speaker.said == []
    outcome, _ = harness.run(Speak({"voice": "xx-nonexistent"}), text="hello")  # auto: the text alone
    assert outcome.name == "success" and [text for _, text in sim_speaker.said] == ["hello"]
    assert sim_speaker.played == []
    assert any("speaking as text: espeak-ng failed" in line for line in harness.logs)


# -- the run's transcript -----------------------------------------------------------------------

CHAT_MISSION = """
name: chat_demo
robot: peoplebot
world: museum
start: hall_centre
until: 60
keys:
  reply: str
  command: "str | None"
trees:
  main:
    sequence:
      - converse: {cue: greeting, visitor: ada}
        outputs: {reply: reply}
      - speak: {text: "{reply}"}
      - converse: {text: "My name is Ada", visitor: ada}
        outputs: {reply: reply}
      - speak: {text: "{reply}"}
      - converse: {text: "take a picture of us please", visitor: ada}
        outputs: {command: command}
        success_on: [command]
      - converse: {cue: compliment, visitor: ada}
        outputs: {reply: reply}
      - speak: {text: "{reply}"}
"""


@pytest.fixture
def chat_mission(tmp_path: Path) -> Path:
    path = tmp_path / "chat.yaml"
    path.write_text(CHAT_MISSION)
    return path


def test_the_transcript_says_who_said_what_when(chat_mission: Path, tmp_path: Path) -> None:
    result = run_mission(chat_mission, out=tmp_path / "run")
    assert result.outcome == "success", result.reason
    lines = read_transcript(result.folder)
    assert [(u.who, u.node) for u in lines] == [
        ("robot", "main/speak"),
        ("visitor", "main/converse#2"),
        ("robot", "main/speak#2"),
        ("visitor", "main/converse#3"),
        ("robot", "main/speak#3"),
    ]
    assert [u.text for u in lines][1:4] == [
        "My name is Ada",
        "Nice to meet you, Ada! I am Maya.",
        ("take a picture of us please"),
    ]
    assert lines[0].text.startswith(("Hello!", "Hi there!", "Welcome to the museum!"))
    assert [u.t for u in lines] == sorted(u.t for u in lines) and lines[0].t == 0.2  # Maya loaded, then replied
    trace = [json.loads(line) for line in (result.folder / "trace.jsonl").read_text().splitlines()]
    says = [e["message"] for e in trace if e["ev"] == "log" and e["message"].startswith("says: ")]
    assert says == [f"says: {u.text}" for u in lines if u.who == "robot"]  # what was said is in the trace
    assert "transcript.jsonl" in result.summary["artefacts"]
    report = (result.folder / "report.html").read_text()
    assert '<h2 id="transcript">Transcript</h2>' in report and "Nice to meet you, Ada! I am Maya." in report


def test_a_chatting_mission_is_deterministic(chat_mission: Path, tmp_path: Path) -> None:
    first = run_mission(chat_mission, out=tmp_path / "a")
    second = run_mission(chat_mission, out=tmp_path / "b")
    for name in ("trace.jsonl", "transcript.jsonl"):
        assert (first.folder / name).read_bytes() == (second.folder / name).read_bytes()


def test_a_run_where_nobody_speaks_has_no_transcript(tmp_path: Path) -> None:
    result = run_mission("missions/examples/hello.yaml", out=tmp_path / "run")
    assert not (result.folder / "transcript.jsonl").exists()
    assert 'id="transcript"' not in (result.folder / "report.html").read_text()


def test_mocked_speech_is_in_the_transcript_too(tmp_path: Path) -> None:
    from botstage.missions.scenario import load_scenario, run_scenario

    mission = tmp_path / "m.yaml"
    mission.write_text(CHAT_MISSION)
    scenario = tmp_path / "s.yaml"
    scenario.write_text(
        "mission: m.yaml\nmocks:\n  speak: {always: {outputs: {said: mocked words}, duration: 1}}\n"
        "  converse: {always: {outcome: replied, outputs: {reply: hi, heard: hello}}}\n"
    )
    result = run_scenario(load_scenario(scenario), tmp_path / "run")
    assert result.passed, result.report()
    assert result.folder is not None
    lines = read_transcript(result.folder)
    assert [(u.who, u.text) for u in lines][:2] == [("visitor", "hello"), ("robot", "mocked words")]


def test_words_heard_then_answered_are_one_line_at_the_time_they_were_heard(tmp_path: Path) -> None:
    from botstage.missions.transcript import transcript

    def event(t: float, ev: str, node: str, skill: str, **outputs: str) -> str:
        fields = {"t": t, "ev": ev, "node": node, "skill": skill}
        if ev == "skill_outcome":
            fields["outputs"] = outputs
        return json.dumps(fields)

    trace = tmp_path / "trace.jsonl"
    trace.write_text(
        "\n".join(
            [
                event(10.0, "skill_start", "listening", "listen"),
                event(14.5, "skill_outcome", "listening", "listen", heard="whatsup", command="WHATSUP"),
                event(14.6, "skill_start", "answer", "converse"),
                event(14.7, "skill_outcome", "answer", "converse", heard="whatsup", reply="Welcome!"),
                event(14.8, "skill_start", "say", "speak"),
                event(17.0, "skill_outcome", "say", "speak", said="Welcome!"),
                event(20.0, "skill_start", "listening", "listen"),
                event(22.0, "skill_outcome", "listening", "listen", heard="whatsup"),
            ]
        )
        + "\n"
    )
    assert [(u.t, u.who, u.text, u.skill) for u in transcript(trace)] == [
        (14.5, "visitor", "whatsup", "listen"),  # when it was recognised, not when listening began
        (14.8, "robot", "Welcome!", "speak"),  # when the robot began to talk
        (22.0, "visitor", "whatsup", "listen"),  # said again after the answer: a line of its own
    ]
