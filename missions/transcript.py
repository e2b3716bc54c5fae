"""transcript.jsonl: who said what, and when, in a run, read from its trace.

Skills say what was spoken through their outputs, so it is in the trace like every other
result and survives mocking: an output named ``said`` is the robot speaking (``speak``), one
named ``heard`` is a visitor (what ``listen`` recognised, what ``converse`` answered or routed).
The robot's lines are at the mission time its skill run started (when it began to talk), the
visitors' at the time the skill ended (when their words were recognised or answered), in the
order of the trace. Words taken up by two skills in a row (listen hears "whatsup", converse
answers it) are one line.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

ROLES = {"said": "robot", "heard": "visitor"}  # output port -> who spoke
FILE = "transcript.jsonl"


@dataclass(frozen=True)
class Utterance:
    t: float  # mission seconds
    who: str  # robot or visitor
    text: str
    node: str  # the tree node or state that ran the skill
    skill: str


class Transcriber:
    """Who said what, from trace events as they come (a run's observer feeds it; a file can too)."""

    def __init__(self) -> None:
        self.started: dict[str, float] = {}
        self.said: list[Utterance] = []

    def add(self, event: Mapping[str, Any]) -> None:
        kind = event["ev"]
        if kind == "skill_start":
            self.started[event["node"]] = event["t"]
        elif kind == "skill_outcome":
            outputs = event["outputs"] or {}
            began = self.started.pop(event["node"], event["t"])
            for port, who in ROLES.items():
                text = outputs.get(port)
                if isinstance(text, str) and text.strip():
                    t = began if who == "robot" else event["t"]
                    self.said.append(Utterance(t, who, text, event["node"], event["skill"]))

    def lines(self) -> list[Utterance]:
        lines = sorted(self.said, key=lambda u: u.t)  # stable: same-time lines keep the trace's order
        return [u for i, u in enumerate(lines) if not (i and _taken_up_again(lines[i - 1], u))]


def transcript(trace_path: Path) -> list[Utterance]:
    transcriber = Transcriber()
    with trace_path.open(encoding="utf-8") as trace:
        for raw in trace:
            transcriber.add(json.loads(raw))
    return transcriber.lines()


def _taken_up_again(previous: Utterance, line: Utterance) -> bool:
    return line.who == previous.who == "visitor" and line.text.lower() == previous.text.lower()


def write_transcript(folder: Path, lines: list[Utterance] | None = None) -> Path | None:
    """Write the run's transcript.jsonl (from its trace unless ``lines`` are given); None (and no
    file) when nobody said anything."""
    if lines is None:
        lines = transcript(folder / "trace.jsonl")
    if not lines:
        return None
    path = folder / FILE
    path.write_text("".join(json.dumps(asdict(u), ensure_ascii=False) + "\n" for u in lines), encoding="utf-8")
    return path


def read_transcript(folder: Path) -> list[Utterance]:
    path = folder / FILE
    if not path.exists():
        return []
    with path.open(encoding="utf-8") as f:
        return [Utterance(**json.loads(line)) for line in f if line.strip()]
