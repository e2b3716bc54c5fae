"""report.html opens in headless Chromium without console errors, with its timeline and pictures."""

from __future__ import annotations

import re
import subprocess
import tempfile
from pathlib import Path

import pytest

from missions.runner import run
from tests.tools import require


def open_in_chromium(page: Path) -> tuple[str, list[str]]:
    """The DOM after scripts ran, and every console message the page produced."""
    chromium = require("chromium", "chromium")
    with tempfile.TemporaryDirectory() as profile:
        result = subprocess.run(
            [
                chromium,
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--disable-quic",
                "--no-first-run",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                f"--user-data-dir={profile}",
                "--enable-logging=stderr",
                "--v=0",
                "--dump-dom",
                page.as_uri(),
            ],
            capture_output=True,
            text=True,
            timeout=120,
        )
    assert result.returncode == 0, result.stderr[-2000:]
    console = [line for line in result.stderr.splitlines() if ":CONSOLE" in line]
    return result.stdout, console


def test_the_console_check_catches_errors(tmp_path: Path) -> None:
    page = tmp_path / "broken.html"
    page.write_text("<html><body><script>notDefined();</script></body></html>")
    _, console = open_in_chromium(page)
    assert any("Uncaught ReferenceError" in line for line in console)


@pytest.mark.parametrize("mission", ["missions/hello.yaml", "missions/tree_demo.yaml", "missions/drive_demo.yaml"])
def test_report_opens_cleanly_with_timeline_and_pictures(tmp_path: Path, mission: str) -> None:
    run(mission, out=tmp_path)
    page = tmp_path / "report.html"
    dom, console = open_in_chromium(page)
    assert console == []
    assert re.search(r'<svg[^>]*class="timeline"', dom)
    assert dom.count("<rect") >= 5  # bars of states and skills
    pictures = dom[dom.index('id="pictures"') :]
    assert "<svg" in pictures and "<g" in pictures  # Graphviz's picture, inline
    assert "<table" in dom and "skill outcomes" in dom.lower()
    text = page.read_text()
    assert not re.search(r'\s(src|href)="(?!#|data:)', text), "the report must not load anything from outside"
    if mission.endswith("drive_demo.yaml"):
        assert '<img class="map" alt="map with the trajectory" src="data:image/png;base64,' in dom
    if mission.endswith("hello.yaml"):
        assert "working/patrol" in dom and "check ×41" in dom
