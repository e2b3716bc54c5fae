"""Run a mission file on the engine and leave a run folder with its trace and summary."""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

import yaml
from py_trees.common import Status

from behaviors.builder import SpecError, SpecProblem
from behaviors.engine import Engine
from robots.clock import SimClock, WallClock

MISSION_KEYS = {"name", "description", "seed", "rate_hz", "until", "blackboard", "trees", "machine", "root"}


class MissionError(Exception):
    """A mission that cannot run; ``problems`` say where and why."""

    def __init__(self, path: Path, problems: list[SpecProblem]) -> None:
        self.path = path
        self.problems = problems
        super().__init__("\n".join(f"{path}: error: {p}" for p in problems))


@dataclass
class RunResult:
    outcome: str
    reason: str
    folder: Path
    summary: dict[str, Any]


def load(path: Path) -> dict[str, Any]:
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise MissionError(path, [SpecProblem((), f"cannot read the mission: {exc.strerror}")]) from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        raise MissionError(path, [SpecProblem((), f"{where}YAML syntax: {getattr(exc, 'problem', exc)}")]) from None
    if not isinstance(data, dict):
        raise MissionError(path, [SpecProblem((), "a mission is a mapping with trees and/or a machine")])
    unknown = [k for k in data if k not in MISSION_KEYS]
    if unknown:
        raise MissionError(path, [SpecProblem((k,), f"unknown mission key {k!r}") for k in unknown])
    if "machine" not in data and "root" not in data and not data.get("trees"):
        raise MissionError(path, [SpecProblem((), "a mission needs a `machine`, a `root` tree name, or `trees`")])
    return data


def build(engine: Engine, data: dict[str, Any], path: Path) -> None:
    trees = data.get("trees") or {}
    builder = engine.builder(trees=trees)
    for key, value in (data.get("blackboard") or {}).items():
        engine.blackboard.set(key, value, writer="init")
    try:
        if "machine" in data:
            root = builder.machine(data["machine"], name=data.get("name", "mission"), spec_path=("machine",))
        else:
            name = data.get("root") or next(iter(trees))
            root = builder.named_tree(name)
    except SpecError as exc:
        raise MissionError(path, exc.problems) from None
    engine.set_root(root)


def run(
    path: Path, *, seed: int | None = None, until: float | None = None, realtime: bool = False, out: Path | None = None
) -> RunResult:
    data = load(path)
    name = str(data.get("name", path.stem))
    seed = int(data.get("seed", 0) if seed is None else seed)
    rate = float(data.get("rate_hz", 10))
    until = float(data.get("until", 600) if until is None else until)
    folder = out or Path("runs") / f"{name}-{datetime.now().strftime('%Y%m%d-%H%M%S')}"
    folder.mkdir(parents=True, exist_ok=True)
    clock = WallClock(rate) if realtime else SimClock(rate)
    started = time.perf_counter()
    with (folder / "trace.jsonl").open("w", encoding="utf-8") as sink:
        from behaviors.trace import Trace

        engine = Engine(clock=clock, seed=seed, trace=Trace(clock, sink, keep=False))
        try:
            build(engine, data, path)
            try:
                status = engine.run(until=until)
            except KeyboardInterrupt:
                engine.halt("interrupted (Ctrl-C)")
                status = Status.FAILURE
            root = engine.root
            outcome = getattr(root, "outcome", None)
            if outcome is not None:
                result, reason = outcome.name, outcome.reason
            elif status in (Status.SUCCESS, Status.FAILURE):
                result, reason = status.value.lower(), getattr(root, "feedback_message", "")
            else:
                result, reason = "stopped", f"time limit of {until:g} s reached"
            summary = {
                "mission": name,
                "backend": "sim",
                "seed": seed,
                "outcome": result,
                "reason": reason,
                "sim_time_s": round(clock.now(), 6),
                "wall_time_s": round(time.perf_counter() - started, 3),
                "ticks": clock.ticks,
                "trace_events": engine.trace.count,
            }
            if isinstance(clock, WallClock):
                summary["overruns"] = {"count": clock.overruns.count, "worst_s": round(clock.overruns.worst_s, 4)}
        finally:
            engine.close()
    (folder / "summary.json").write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    return RunResult(result, reason, folder, summary)
