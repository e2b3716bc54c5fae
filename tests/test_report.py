"""report.html opens in headless Chromium without console errors, with its timeline and pictures."""

from __future__ import annotations

import re
import subprocess
import tempfile
from pathlib import Path

import pytest

from botstage.missions.runner import run
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


@pytest.mark.parametrize(
    "mission", ["missions/examples/hello.yaml", "missions/examples/tree_demo.yaml", "missions/examples/drive_demo.yaml"]
)
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


def test_the_map_marks_each_bump_and_says_which_were_walls_and_which_people(tmp_path: Path) -> None:
    from botstage.missions.check import check
    from botstage.missions.report import trajectory_map

    checked = check("missions/examples/drive_demo.yaml")
    (tmp_path / "trajectory.csv").write_text("t,x,y,theta\n0,6,1,-1.57\n1,6,1.5,-1.57\n2,7,1.9,0\n")
    assert '<p class="bumps">No bumps.</p>' in trajectory_map(tmp_path, checked)
    (tmp_path / "bumps.csv").write_text("t,x,y,what\n1.5,6.1,1.6,wall\n2.25,7,1.9,person\n3,7.2,1.9,wall\n")
    section = trajectory_map(tmp_path, checked)
    assert "3 bump(s) marked ×: 2 into walls, 1 into people" in section
    assert "1.5 s at (6.10, 1.60), wall; 2.25 s at (7.00, 1.90), person" in section
    with_bumps = re.search(r'src="data:image/png;base64,([^"]+)"', section)
    (tmp_path / "bumps.csv").unlink()
    without = re.search(r'src="data:image/png;base64,([^"]+)"', trajectory_map(tmp_path, checked))
    assert with_bumps and without and with_bumps.group(1) != without.group(1)  # the crosses are drawn
