"""A third-party skill, installed by pip as a real wheel, is found by name through the entry point."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from botstage.skills.registry import ENTRY_POINT_GROUP, Registry
from tests.tools import install_wheel

MODULE = """
from botstage.skills.base import In, Outcome, Skill


class Wave(Skill):
    name = "wave"
    inputs = {"times": In(int, default=2)}

    def run(self, ctx, times):
        for _ in range(times):
            yield
        return Outcome.success()


class NotASkill:
    pass
"""


@pytest.fixture
def installed(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    def install(entry_points: str) -> None:
        files = {"botstage_wave_skill.py": MODULE}
        target = install_wheel(tmp_path, "botstage-wave-skill", files, f"[{ENTRY_POINT_GROUP}]\n{entry_points}\n")
        monkeypatch.syspath_prepend(str(target))

    yield install
    sys.modules.pop("botstage_wave_skill", None)


def test_plugin_skill_is_found_by_name(installed) -> None:
    installed("wave = botstage_wave_skill:Wave")
    registry = Registry.default()
    assert "wave" in registry
    assert registry.get("wave").describe()["inputs"]["times"]["default"] == 2
    assert registry.origin("wave") == "plugin botstage-wave-skill"
    assert registry.problems == []


def test_broken_plugins_are_reported_not_fatal(installed) -> None:
    installed(
        "wave = botstage_wave_skill:Wave\nghost = botstage_wave_skill:Missing\n"
        "thing = botstage_wave_skill:NotASkill\nmisnamed = botstage_wave_skill:Wave"
    )
    registry = Registry.default()
    assert "wave" in registry
    reasons = {p.entry_point.split(" =")[0]: p.reason for p in registry.problems}
    assert set(reasons) == {"ghost", "thing", "misnamed"}
    assert "import failed" in reasons["ghost"]
    assert "does not point to a Skill" in reasons["thing"]
    assert "differs from the skill's name 'wave'" in reasons["misnamed"]


def test_unknown_skill_suggests_a_close_name() -> None:
    registry = Registry.default()
    with pytest.raises(LookupError, match="unknown skill 'wiat' \\(did you mean 'wait'\\?\\)"):
        registry.get("wiat")
