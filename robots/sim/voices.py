"""Simulated voices: the simulator's people speak to the robot through its microphone.

Utterances are WAV clips made with espeak-ng (commands and chat phrases, in several voices;
``voices/clips.yaml`` lists them), played into the microphone:

- at **scripted** moments (``say``), whoever is around, for tests and demos;
- at **random** moments when someone stands within ``near`` metres of the robot: after each
  utterance (or after a quiet check) the next is due ``pause`` plus an exponential wait of mean ``every``
  seconds later, and the clip is drawn at random, commands ``command_share`` of the time (each
  command as often as ``command_weights`` says);
- as **answers**: guests seated at the map's tables (its places named ``table_*``) answer YES
  when the robot, within ``near`` metres of their table, asks a question (its speaker says
  something ending in ``?``), ``answer_delay`` seconds after it stopped speaking. This is how
  a delivery is confirmed in simulation without a person at the keyboard.

The randomness comes from the world's ``voices`` generator, so the same seed gives the same
utterances at the same moments, and adding voices changes nothing else in the world.
What was said, when and by whom is kept in ``spoken`` (the run's summary counts it).
"""

from __future__ import annotations

import math
import wave
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from botstage.robots.sim.devices import SimMicrophone
from botstage.robots.sim.people import Crowd
from botstage.robots.sim.world import World

VOICES_DIR = Path(__file__).resolve().parent / "voices"


@dataclass(frozen=True, slots=True)
class Clip:
    name: str
    text: str
    command: str | None  # the command it says (PHOTO, YES, ...), None for chat
    samples: np.ndarray  # 16 kHz mono int16

    @property
    def duration(self) -> float:
        return self.samples.size / SimMicrophone.RATE


def read_clip(path: Path) -> np.ndarray:
    """A clip's samples: the files are 16 kHz mono 16-bit PCM, like the microphone's audio."""
    with wave.open(str(path), "rb") as wav:
        if (wav.getframerate(), wav.getnchannels(), wav.getsampwidth()) != (SimMicrophone.RATE, 1, 2):
            raise ValueError(f"{path}: a voice clip must be 16 kHz mono 16-bit PCM")
        return np.frombuffer(wav.readframes(wav.getnframes()), dtype="<i2").astype(np.int16)


@cache
def clips() -> tuple[Clip, ...]:
    """The shipped clips (read once a process)."""
    listed = yaml.safe_load((VOICES_DIR / "clips.yaml").read_text(encoding="utf-8"))
    made = []
    for entry in listed["clips"]:
        samples = read_clip(VOICES_DIR / entry["file"])
        samples.setflags(write=False)
        made.append(Clip(Path(entry["file"]).stem, entry["text"], entry.get("command"), samples))
    return tuple(made)


@dataclass
class Spoken:
    t: float
    clip: str
    text: str
    command: str | None
    person: int | None  # None for a scripted line


@dataclass
class Voices:
    """Plays clips into ``microphone``; ``step`` once a tick (after the people moved)."""

    microphone: SimMicrophone
    crowd: Crowd
    robot: Callable[[], tuple[float, float]]
    rng: np.random.Generator
    near: float = 2.5
    every: float = 12.0
    command_share: float = 0.6
    pause: float = 1.0  # s of quiet at least between two utterances: people take turns
    command_weights: dict[str, float] = field(default_factory=dict)  # command -> weight (default 1 each)
    library: tuple[Clip, ...] = field(default_factory=clips)
    spoken: list[Spoken] = field(default_factory=list)
    speaker: Any = None  # the robot's SimSpeaker: what it said, for the seated guests to answer
    seats: tuple[tuple[float, float], ...] = ()
    answer_delay: float = 0.8
    _next: float = 0.0
    _busy_until: float = 0.0
    _heard: int = 0  # how many of the speaker's lines the guests have listened to
    _asked: bool = False

    def __post_init__(self) -> None:
        if self.near <= 0 or self.every <= 0 or self.pause < 0 or not 0 <= self.command_share <= 1:
            raise ValueError("voices need near > 0, every > 0, pause >= 0 and 0 <= command_share <= 1")
        commands = {c.command for c in self.library if c.command}
        unknown = sorted(set(self.command_weights) - commands)
        if unknown or any(w < 0 for w in self.command_weights.values()):
            raise ValueError(
                f"command weights are non-negative numbers for {', '.join(sorted(commands))}; "
                f"got {self.command_weights}"
            )
        self._commands = [c for c in self.library if c.command]
        self._chat = [c for c in self.library if not c.command]
        self._command_p: np.ndarray | None = None  # None: every command clip alike
        if self.command_weights:
            per_command = Counter(c.command for c in self._commands)
            weights = np.array(
                [self.command_weights.get(c.command or "", 0.0) / per_command[c.command] for c in self._commands]
            )
            if weights.sum() > 0:
                self._command_p = weights / weights.sum()
        self._next = float(self.rng.exponential(self.every))

    @classmethod
    def for_world(
        cls, world: World, crowd: Crowd, microphone: SimMicrophone, speaker: Any = None, **options: Any
    ) -> Voices:
        pose = world.body

        def robot() -> tuple[float, float]:
            return pose.pose.x, pose.pose.y

        seats = tuple((x, y) for name, (x, y, _) in sorted(world.grid.places.items()) if name.startswith("table"))
        return cls(
            microphone,
            crowd,
            robot,
            world.noise("voices"),
            speaker=speaker,
            seats=seats if speaker is not None else (),
            **options,  # type: ignore[arg-type]
        )

    def clip(self, name: str) -> Clip:
        for clip in self.library:
            if clip.name == name:
                return clip
        raise KeyError(f"no voice clip {name!r} (have: {', '.join(c.name for c in self.library)})")

    def say(self, clip: str | Clip, at: float, person: int | None = None) -> None:
        """A scripted line: ``clip`` (a name or a Clip) heard from mission time ``at``."""
        chosen = self.clip(clip) if isinstance(clip, str) else clip
        self.microphone.play(np.asarray(chosen.samples), at)
        self.spoken.append(Spoken(at, chosen.name, chosen.text, chosen.command, person))
        self._busy_until = max(self._busy_until, at + chosen.duration)

    def step(self, now: float) -> None:
        self._answer(now)
        if now < self._next or now < self._busy_until or not self.library:
            return
        speaker = self._nearest(now)
        if speaker is None:
            self._next = now + 1.0  # nobody near: look again in a second
            return
        commands, chat = self._commands, self._chat
        if commands and (not chat or self.rng.random() < self.command_share):
            chosen = self._weighted(commands)
        else:
            chosen = chat[int(self.rng.integers(len(chat)))]
        self.say(chosen, now, speaker)
        self._next = now + chosen.duration + self.pause + float(self.rng.exponential(self.every))

    def _weighted(self, commands: list[Clip]) -> Clip:
        """A command clip: each command as likely as its weight says, its clips equally likely."""
        if self._command_p is None:
            return commands[int(self.rng.integers(len(commands)))]
        return commands[int(self.rng.choice(len(commands), p=self._command_p))]

    def _answer(self, now: float) -> None:
        """A seated guest answers YES to a question the robot asked at their table."""
        if self.speaker is None or not self.seats:
            return
        said = self.speaker.said
        if len(said) > self._heard:
            rx, ry = self.robot()
            at_table = any(math.hypot(x - rx, y - ry) <= self.near for x, y in self.seats)
            self._asked |= at_table and any(text.rstrip().endswith("?") for _, text in said[self._heard :])
            self._heard = len(said)
        if self._asked and not self.speaker.busy():
            yes = [c for c in self.library if c.command == "YES"]
            if yes:
                self.say(yes[int(self.rng.integers(len(yes)))], now + self.answer_delay, person=-1)
            self._asked = False

    def _nearest(self, now: float) -> int | None:
        rx, ry = self.robot()
        best, best_distance = None, math.inf
        for person in self.crowd.people:
            distance = math.hypot(person.x - rx, person.y - ry)
            if distance <= self.near and distance < best_distance:
                best, best_distance = person.id, distance
        return best
