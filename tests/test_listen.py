"""The listen skill on the sim clock: the simulator's microphone plays WAVs at mission times.

The engine's rule is kept: after each tick the worker pool is drained, so the recogniser's
result is seen at the next tick whatever the wall time of decoding. Nothing here sleeps or
looks at the wall clock.
"""

from __future__ import annotations

import random
from pathlib import Path
from typing import Any

import pytest

from botstage.robots.clock import SimClock
from botstage.robots.gridmap import load
from botstage.robots.interfaces import Pose2D
from botstage.robots.profile import load_profile
from botstage.robots.sim.backend import SimBackend
from botstage.skills.base import Outcome, SkillContext, SkillLogger
from botstage.skills.execution import SkillExecution
from botstage.skills.listen import Listen
from botstage.skills.registry import Registry
from botstage.skills.speech.wav import read_wav
from botstage.skills.testing import DictBoard
from botstage.skills.workers import Workers

DATA = Path(__file__).parent / "data" / "speech"
MUSEUM = load("robots/maps/museum.yaml")


class Rig:
    """A PeopleBot in the museum (nobody else there) and the listen skill on its microphone."""

    def __init__(self, seed: int = 3, rate_hz: float = 10) -> None:
        profile, problems, _ = load_profile("robots/profiles/peoplebot.yaml")
        assert profile is not None, problems
        self.clock = SimClock(rate_hz)
        self.sim = SimBackend(profile, MUSEUM, Pose2D(11.0, 10.0, 0.0), seed, self.clock)
        self.microphone = self.sim.devices["microphone"]
        self.workers = Workers()
        self.logs: list[str] = []

    def advance(self, seconds: float) -> None:
        for _ in range(round(seconds / self.clock.period)):
            self.sim.step()
            self.clock.next_tick()

    def play(self, name: str, at: float) -> float:
        """Play tests/data/speech/<name>.wav from mission time ``at``; returns when it ends."""
        samples = read_wav(DATA / f"{name}.wav")
        self.microphone.play(samples, at)
        return at + samples.size / 16000

    def listen(
        self,
        limit: float = 60.0,
        interfaces: dict[str, Any] | None = None,
        params: dict[str, Any] | None = None,
        **inputs: Any,
    ) -> Outcome:
        skill = Listen(params or {})
        ctx = SkillContext(
            clock=self.clock,
            params=skill.params,
            logger=SkillLogger("listen", sink=lambda node, level, message: self.logs.append(message)),
            blackboard=DictBoard(),
            workers=self.workers,
            interfaces=self.sim.devices if interfaces is None else interfaces,
            rng=random.Random(0),
        )
        execution = SkillExecution(skill, ctx)
        outcome = execution.start(inputs)
        deadline = self.clock.now() + limit
        while outcome is None:
            assert self.clock.now() < deadline, "listen still running"
            self.workers.drain()  # as the engine does on the sim clock
            self.sim.step()
            self.clock.next_tick()
            outcome = execution.step()
        self.ended = self.clock.now()
        return outcome


@pytest.mark.parametrize("command", ["PHOTO", "YES", "WHATSUP", "CANCEL", "CIAO"])
def test_a_command_played_into_the_microphone_is_heard(command: str) -> None:
    rig = Rig()
    end = rig.play(command.lower(), at=1.0)
    outcome = rig.listen(timeout=10.0)
    assert outcome.name == "heard", outcome.reason
    assert outcome.outputs["command"] == command
    assert outcome.outputs["text"] == outcome.outputs["heard"] == command.lower()
    assert 0.0 < outcome.outputs["confidence"] <= 1.0
    # heard once the quiet after it ended the utterance: after the word, within a second of it
    assert end < rig.ended < end + 1.0


@pytest.mark.parametrize("recognizer", ["embedding", "pocketsphinx"])
def test_either_recogniser_hears_a_command_and_the_embedding_is_the_default(recognizer: str) -> None:
    assert Listen().params.recognizer == "embedding"  # type: ignore[attr-defined]
    rig = Rig()
    rig.play("cancel", at=1.0)
    outcome = rig.listen(timeout=10.0, params={"recognizer": recognizer})
    assert outcome.name == "heard" and outcome.outputs["command"] == "CANCEL", outcome.reason


def test_heard_is_the_success_outcome() -> None:
    assert Listen.success_outcomes == ("heard",)
    assert {"heard", "silence", "timeout", "failure"} == set(Listen.all_outcomes)
    assert "listen" in Registry.shipped()  # the speech set's, installed here


def test_nothing_said_is_silence_at_the_timeout() -> None:
    rig = Rig()
    outcome = rig.listen(timeout=3.0)
    assert outcome.name == "silence"
    assert outcome.outputs == {"command": "", "text": "", "confidence": 0.0, "heard": ""}
    assert rig.ended == pytest.approx(3.0, abs=0.15)


def test_speech_that_is_no_command_times_out() -> None:
    rig = Rig()
    rig.play("good_morning", at=0.5)
    outcome = rig.listen(timeout=4.0)
    assert outcome.name == "timeout", outcome.reason
    assert "none accepted" in outcome.reason
    assert outcome.outputs["command"] == ""
    assert any("not accepted" in line for line in rig.logs)


def test_a_rejected_utterance_does_not_end_listening() -> None:
    rig = Rig()
    rig.play("good_morning", at=0.5)
    rig.play("yes", at=3.0)
    outcome = rig.listen(timeout=8.0)
    assert outcome.name == "heard" and outcome.outputs["command"] == "YES"
    assert rig.ended > 3.0


def test_only_the_commands_asked_for_are_accepted() -> None:
    rig = Rig()
    rig.play("photo", at=0.5)
    outcome = rig.listen(timeout=3.0, commands=["yes", "cancel"])
    assert outcome.name == "timeout"
    assert "PHOTO is not wanted now" in outcome.reason


def test_speech_before_listening_started_is_not_heard() -> None:
    rig = Rig()
    rig.play("photo", at=0.5)
    rig.advance(3.0)  # the word was said and over before the skill started
    outcome = rig.listen(timeout=2.0)
    assert outcome.name == "silence"


def test_free_mode_gives_the_words() -> None:
    rig = Rig()
    rig.play("nice_weather", at=0.5)
    outcome = rig.listen(timeout=6.0, mode="free")
    assert outcome.name == "heard", outcome.reason
    assert outcome.outputs["command"] == ""
    words = outcome.outputs["text"].split()
    assert len(words) >= 2 and outcome.outputs["text"] == outcome.outputs["text"].lower()


def test_speech_cut_by_the_timeout_is_still_decoded() -> None:
    rig = Rig()
    rig.play("cancel", at=1.0)
    outcome = rig.listen(timeout=1.8)  # the word ends about 1.8 s: no quiet after it yet
    assert outcome.name in ("heard", "timeout")
    assert rig.ended == pytest.approx(1.9, abs=0.15)  # decoded in the tick after the deadline


def test_the_same_run_gives_the_same_outcome() -> None:
    results = []
    for _ in range(2):
        rig = Rig(seed=11)
        rig.play("whatsup", at=0.7)
        outcome = rig.listen(timeout=5.0)
        results.append((outcome.name, outcome.outputs, rig.ended))
    assert results[0] == results[1]


@pytest.mark.parametrize(
    ("inputs", "reason"),
    [
        ({"mode": "chat"}, "mode must be one of command, free"),
        ({"commands": ["PHOTO", "DANCE"]}, "unknown command(s) DANCE"),
        ({"timeout": 0.0}, "timeout must be positive"),
    ],
)
def test_bad_inputs_fail_with_a_reason(inputs: dict[str, Any], reason: str) -> None:
    outcome = Rig().listen(**inputs)
    assert outcome.name == "failure" and reason in outcome.reason


def test_a_robot_without_a_microphone_fails_with_a_reason() -> None:
    rig = Rig()
    outcome = rig.listen(interfaces={"drive": rig.sim.devices["drive"]}, timeout=2.0)
    assert outcome.name == "failure" and "no 'microphone' interface" in outcome.reason
