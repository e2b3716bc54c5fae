"""The PeopleBot entertainer end to end: the default run as a newcomer starts it, and the gallery
outage scenario looked at from the gallery's side."""

from __future__ import annotations

import json
import re
import sqlite3
from pathlib import Path

import pytest

from botstage.missions import DEFAULT_MISSION
from botstage.missions.runner import run
from botstage.missions.scenario import load_scenario, run_scenario
from tests.test_cli import botstage


def test_the_default_run_visits_crowds_takes_photos_and_uploads_them_all_the_same_every_time(
    tmp_path: Path,
) -> None:
    """`botstage run` with no arguments: the simulated PeopleBot in the museum for 10 minutes,
    the real recogniser hearing the simulated visitors, photos to the run's own gallery."""
    assert DEFAULT_MISSION.name == "peoplebot_entertainer.yaml"
    runs = []
    for name in ("a", "b"):
        result = botstage("run", "-q", "--out", str(tmp_path / name))
        assert result.returncode == 0, result.stderr
        runs.append(json.loads((tmp_path / name / "summary.json").read_text()))
    first, second = runs
    counters = first["counters"]
    assert first["outcome"] == "time_limit" and first["sim_time_s"] == 600.0
    assert counters["crowds_visited"] >= 2
    assert counters["photos_taken"] >= 2
    assert counters["photos_uploaded"] == counters["photos_taken"] and counters["photos_pending"] == 0
    assert second["counters"] == counters  # the same seed, the same result
    sim = first["sim"]
    assert (sim["bumps"], sim["bumps_walls"], sim["bumps_people"], sim["bump_ticks"]) == (0, 0, 0, 0)
    traces = [(tmp_path / n / "trace.jsonl").read_text() for n in ("a", "b")]
    assert traces[0] == traces[1]
    folder = tmp_path / "a"
    photos = sorted((folder / "photos").glob("*.jpg"))
    assert len(photos) == counters["photos_taken"]
    assert all(p.with_suffix(".json").is_file() for p in photos)
    assert len(list((folder / "gallery" / "photos").glob("*.jpg"))) == counters["photos_taken"]
    heard = [json.loads(line) for line in (folder / "transcript.jsonl").read_text().splitlines()]
    assert any(u["who"] == "visitor" for u in heard) and any(u["who"] == "robot" for u in heard)
    report = (folder / "report.html").read_text()
    for section in ("photos", "layouts", "transcript", "map"):
        assert f'<h2 id="{section}">' in report
    assert f"<p>{len(photos)} taken, {len(photos)} uploaded to the gallery.</p>" in report
    shown = set(re.findall(r"<td>(Layout_\d)</td>", report))
    assert {"Layout_0", "Layout_1", "Layout_2", "Layout_5", "Layout_6"} <= shown


SHORT_OF_PHOTOS = pytest.mark.xfail(
    strict=True,
    reason="one photo: since the speech-embedding recogniser (issue 20) the run takes another course, "
    "and late on the approach gives up on crowds of 8 and of 4 people (30 s, 0.56 m short; blocked by "
    "a visitor for 20 s); the recogniser heard every command it was given (README, entertainer)",
)


@pytest.mark.parametrize("seed", [*range(2, 6), pytest.param(6, marks=SHORT_OF_PHOTOS), *range(7, 11)])
def test_every_seed_to_10_keeps_clear_of_walls_and_people_and_takes_photos(tmp_path: Path, seed: int) -> None:
    """Seeds 2-10 of the default mission (seed 1, the default, is the run above): no bump into a
    wall or a person (the skills that reverse or turn blind check their way on the map and stop
    at the first contact), and the README's claim: 2 crowds and 2 photos at least, all uploaded
    (seed 6 falls one photo short, strictly expected to until approaching a dense crowd is fixed)."""
    summary = run(DEFAULT_MISSION, seed=seed, out=tmp_path).summary
    sim, counters = summary["sim"], summary["counters"]
    bumps = (tmp_path / "bumps.csv").read_text()
    assert (sim["bumps"], sim["bumps_walls"], sim["bumps_people"], sim["bump_ticks"]) == (0, 0, 0, 0), bumps
    assert counters["crowds_visited"] >= 2 and counters["photos_taken"] >= 2, counters
    assert counters["photos_uploaded"] == counters["photos_taken"], counters


def test_a_gallery_down_for_two_minutes_gets_every_photo_once(tmp_path: Path) -> None:
    result = run_scenario(load_scenario(Path("missions/scenarios/peoplebot_entertainer/gallery_down.yaml")), tmp_path)
    assert result.passed, result.report()
    upload = json.loads((tmp_path / "summary.json").read_text())["upload"]["outboxes"][0]
    assert upload["retries"] >= 2  # both photos were tried while it was down, and waited
    assert upload["already_in_gallery"] == 0  # none was sent again after it arrived
    with sqlite3.connect(tmp_path / "gallery" / "gallery.sqlite") as db:
        assert db.execute("SELECT COUNT(*) FROM photos").fetchone()[0] == 2
    assert len(list((tmp_path / "gallery" / "photos").glob("*.jpg"))) == 2
