"""A run does each thing once: it reads the robot's profile and the world's map once (when the
mission is checked; the run, its robot and its report use what checking loaded) and builds what
runs once (on the engine the run ticks, when checking)."""

from __future__ import annotations

import sys
from collections import Counter
from pathlib import Path

import pytest

from botstage.behaviors import skill_behaviour
from botstage.missions.runner import run

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "missions" / "examples"
OPENED: Counter[str] = Counter()
COUNTING = [False]


def _audit(event: str, args: tuple) -> None:
    if COUNTING[0] and event == "open" and isinstance(args[0], str | Path):
        OPENED[str(Path(args[0]).resolve())] += 1


sys.addaudithook(_audit)  # audit hooks cannot be removed: it counts only inside `counting`


@pytest.fixture
def counting(monkeypatch: pytest.MonkeyPatch) -> Counter[str]:
    built: Counter[str] = Counter()
    original = skill_behaviour.SkillBehaviour.__init__

    def init(self, name, path, *args, **kwargs):  # type: ignore[no-untyped-def]
        built[path] += 1
        original(self, name, path, *args, **kwargs)

    monkeypatch.setattr(skill_behaviour.SkillBehaviour, "__init__", init)
    OPENED.clear()
    COUNTING[0] = True
    yield built
    COUNTING[0] = False


@pytest.mark.parametrize("mission", ["drive_demo", "face_tracker"])
def test_the_profile_and_map_are_read_once_and_the_tree_built_once(
    mission: str, counting: Counter[str], tmp_path: Path
) -> None:
    result = run(EXAMPLES / f"{mission}.yaml", out=tmp_path / "run")
    assert result.outcome
    profile = ROOT / "robots" / "profiles" / f"{result.summary['robot']}.yaml"
    world = (EXAMPLES / f"{mission}.yaml").read_text(encoding="utf-8").split("\nworld:")[1].split()[0]
    maps = ROOT / "robots" / "maps"
    read = {path: OPENED[str(path)] for path in (profile, maps / f"{world}.yaml", maps / f"{world}.pgm")}
    assert read == dict.fromkeys(read, 1)
    assert counting, "no skill node was built: the count is not counting"
    twice = {path: n for path, n in counting.items() if n != 1}
    assert twice == {}
