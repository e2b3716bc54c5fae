"""A third-party skill, installed by pip as a real wheel, is found by name through the entry point."""

from __future__ import annotations

import base64
import hashlib
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from skills.registry import ENTRY_POINT_GROUP, Registry

MODULE = """
from skills.base import In, Outcome, Skill


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


def build_wheel(directory: Path, entry_points: str) -> Path:
    dist = "botstage_wave_skill-0.1.0"
    files = {
        "botstage_wave_skill.py": MODULE,
        f"{dist}.dist-info/METADATA": "Metadata-Version: 2.1\nName: botstage-wave-skill\nVersion: 0.1.0\n",
        f"{dist}.dist-info/WHEEL": "Wheel-Version: 1.0\nGenerator: test\nRoot-Is-Purelib: true\nTag: py3-none-any\n",
        f"{dist}.dist-info/entry_points.txt": f"[{ENTRY_POINT_GROUP}]\n{entry_points}\n",
    }
    record = []
    for name, text in files.items():
        digest = base64.urlsafe_b64encode(hashlib.sha256(text.encode()).digest()).rstrip(b"=").decode()
        record.append(f"{name},sha256={digest},{len(text.encode())}")
    record.append(f"{dist}.dist-info/RECORD,,")
    files[f"{dist}.dist-info/RECORD"] = "\n".join(record) + "\n"
    wheel = directory / f"{dist.replace('-', '-')}-py3-none-any.whl"
    with zipfile.ZipFile(wheel, "w") as zf:
        for name, text in files.items():
            zf.writestr(name, text)
    return wheel


@pytest.fixture
def installed(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    def install(entry_points: str) -> None:
        wheel = build_wheel(tmp_path, entry_points)
        target = tmp_path / "site"
        subprocess.run(
            [
                sys.executable,
                "-m",
                "pip",
                "install",
                "--quiet",
                "--no-deps",
                "--no-index",
                "--target",
                str(target),
                str(wheel),
            ],
            check=True,
        )
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
