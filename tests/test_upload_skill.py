"""The upload skill: queued in a tick, waiting in mission time, refusals as outcomes with reasons;
and missions run by the runner (a gallery of the run's own, a configured one, resuming after a
restart, the token kept out of the run folder, the same trace twice)."""

from __future__ import annotations

import json
import logging
import random
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml

from botstage.missions.gallery.server import start_gallery
from botstage.missions.runner import run as run_mission
from botstage.robots.clock import SimClock
from botstage.skills.base import Outcome, SkillContext, SkillLogger
from botstage.skills.execution import SkillExecution
from botstage.skills.outbox.service import Uploads
from botstage.skills.outbox.settings import TOKEN_ENV, OutboxSettings
from botstage.skills.testing import DictBoard as Board
from botstage.skills.upload import Upload
from botstage.skills.workers import Workers
from tests.test_outbox import TOKEN, make_photo, photos_in


class Harness:
    """The skill run as the engine runs it on the sim clock, with the run's uploads after each tick."""

    def __init__(self, folder: Path, interfaces: dict[str, Any] | None = None) -> None:
        self.clock = SimClock(10)
        self.workers = Workers()
        self.uploads = Uploads(folder, self.clock, seed=3)
        self.interfaces = {"uploads": self.uploads} if interfaces is None else interfaces
        self.logs: list[str] = []

    def run(self, skill: Upload, max_ticks: int = 10_000, **inputs: Any) -> tuple[Outcome, int]:
        ctx = SkillContext(
            clock=self.clock,
            params=skill.params,
            logger=SkillLogger("node", sink=lambda node, level, message: self.logs.append(f"{level}: {message}")),
            blackboard=Board(),
            workers=self.workers,
            interfaces=self.interfaces,
            rng=random.Random(0),
        )
        execution = SkillExecution(skill, ctx)
        outcome, ticks = execution.start(inputs), 0
        while outcome is None:
            self.workers.drain()
            self.clock.next_tick()
            self.uploads.after_tick()
            ticks += 1
            assert ticks < max_ticks, "the skill never ended"
            outcome = execution.step()
        return outcome, ticks

    def close(self) -> None:
        self.workers.shutdown()
        self.uploads.close()


@pytest.fixture
def harness(tmp_path: Path) -> Iterator[Harness]:
    h = Harness(tmp_path / "run")
    yield h
    h.close()


@pytest.fixture(autouse=True)
def no_token_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(TOKEN_ENV, raising=False)


def test_upload_queues_in_a_tick_and_the_photo_arrives_in_the_background(tmp_path, gallery, harness) -> None:
    skill = Upload({"endpoint": gallery.upload_url})
    photo = make_photo(tmp_path / "smile")
    outcome, ticks = harness.run(skill, photo=str(photo), metadata={"visitor": "ada"})
    assert outcome.name == "queued" and ticks == 1  # the copy into the outbox, in the worker pool
    assert outcome.outputs["status"] == "queued"
    [listed] = photos_in(gallery)  # uploaded after that tick, by the outbox
    assert listed["hash"] == outcome.outputs["photo_id"]
    assert listed["metadata"] == {"visitor": "ada"}
    assert harness.uploads.summary()["photos_uploaded"] == 1
    assert (tmp_path / "run" / "outbox" / "outbox.sqlite").exists()  # default: in the run folder


def test_the_uploads_rest_only_while_no_photo_waits(tmp_path, gallery, harness) -> None:
    """What lets a distributed run skip an upload process's steps: resting means a step does nothing."""
    uploads = harness.uploads
    assert uploads.resting()  # no outbox yet
    outbox = uploads.outbox(OutboxSettings(endpoint=gallery.upload_url))
    assert uploads.resting()
    outbox.record(make_photo(tmp_path / "p"))
    assert not uploads.resting()  # recorded, not yet sent
    harness.clock.next_tick()
    uploads.after_tick()
    assert len(photos_in(gallery)) == 1 and uploads.resting()


def test_wait_runs_until_the_gallery_has_it(tmp_path, gallery, harness) -> None:
    skill = Upload({"endpoint": gallery.upload_url})
    photo = str(make_photo(tmp_path / "p"))
    outcome, _ = harness.run(skill, photo=photo, wait=True)
    assert outcome == Outcome("uploaded", "", {"photo_id": outcome.outputs["photo_id"], "status": "uploaded"})
    again, ticks = harness.run(skill, photo=photo)  # the same photo again: nothing to do
    assert again.name == "uploaded" and ticks == 1
    assert len(photos_in(gallery)) == 1


def test_waiting_on_a_gallery_that_is_down_times_out_in_mission_time(tmp_path, harness) -> None:
    down = start_gallery(tmp_path / "g")
    down.stop()
    skill = Upload({"endpoint": down.upload_url, "backoff_initial": 0.5})
    outcome, ticks = harness.run(skill, photo=str(make_photo(tmp_path / "p")), wait=True, timeout=3.0)
    assert outcome.name == "timeout"
    assert outcome.reason.startswith("not uploaded within 3 s (last attempt: the gallery at http://127.0.0.1:")
    assert "is unreachable" in outcome.reason
    assert ticks == 31  # 3 s at 10 Hz after the tick that queued it: wall time plays no part
    assert outcome.outputs["status"] == "queued"  # still in the outbox: it will go when the gallery is back
    assert harness.uploads.summary()["photos_pending"] == 1


def test_a_photo_the_gallery_refuses_ends_rejected_with_its_reason(tmp_path, gallery, harness) -> None:
    cut = tmp_path / "cut.jpg"
    cut.write_bytes(make_photo(tmp_path / "p").read_bytes()[:-100])
    outcome, _ = harness.run(Upload({"endpoint": gallery.upload_url}), photo=str(cut), wait=True)
    assert outcome.name == "rejected"
    assert "HTTP 415" in outcome.reason and "truncated" in outcome.reason
    assert outcome.outputs["status"] == "rejected"


@pytest.mark.parametrize(
    ("photo", "metadata", "reason"),
    [
        ("missing.jpg", {}, "no such photo"),
        ("notes.txt", {}, "is not a JPEG or PNG image"),
        ("p.jpg", {"x": float("nan")}, "metadata must be plain JSON"),
    ],
)
def test_what_cannot_be_queued_fails_with_a_reason(tmp_path, gallery, harness, photo, metadata, reason) -> None:
    make_photo(tmp_path / "p")
    (tmp_path / "notes.txt").write_text("hello")
    skill = Upload({"endpoint": gallery.upload_url})
    outcome, _ = harness.run(skill, photo=str(tmp_path / photo), metadata=metadata)
    assert outcome.name == "failure"
    assert outcome.reason.startswith(f"cannot queue {tmp_path / photo}: ") and reason in outcome.reason


def test_without_an_endpoint_or_a_run_gallery_it_fails_with_a_reason(tmp_path, harness) -> None:
    outcome, _ = harness.run(Upload(), photo=str(make_photo(tmp_path / "p")))
    assert outcome.name == "failure" and "no gallery endpoint is configured" in outcome.reason


def test_without_the_uploads_interface_it_fails_with_a_reason(tmp_path) -> None:
    bare = Harness(tmp_path / "run", interfaces={})
    try:
        outcome, _ = bare.run(Upload(), photo=str(make_photo(tmp_path / "p")))
    finally:
        bare.close()
    assert outcome.name == "failure" and "no 'uploads' interface" in outcome.reason


def test_bad_settings_are_refused_when_the_skill_is_made() -> None:
    with pytest.raises(ValueError, match="http:// or https:// URL"):
        Upload({"endpoint": "ftp://gallery"})
    with pytest.raises(ValueError, match="backoff_max must not be below backoff_initial"):
        Upload({"backoff_initial": 10, "backoff_max": 1})


# -- missions ---------------------------------------------------------------------------------


def write_mission(folder: Path, photos: list[Path], **extra: Any) -> Path:
    steps: list[Any] = [{"upload": {"photo": str(p), "metadata": {"n": i}}} for i, p in enumerate(photos)]
    steps.append({"upload": {"photo": str(photos[0]), "wait": True, "timeout": 5}})
    mission = {
        "name": "photos",
        "until": 10,
        "trees": {"main": {"sequence": [*steps, {"wait": {"duration": 1}}]}},
        "counters": ["photos_uploaded", "photos_pending"],
        **extra,
    }
    path = folder / "photos.yaml"
    path.write_text(yaml.safe_dump(mission))
    return path


def test_a_mission_without_an_endpoint_gets_a_gallery_of_its_own(tmp_path, monkeypatch, caplog) -> None:
    caplog.set_level(logging.DEBUG)
    monkeypatch.setenv(TOKEN_ENV, TOKEN)  # the run's gallery asks for it, the outbox sends it
    photos = [make_photo(tmp_path / f"p{i}", seed=i) for i in range(3)]
    mission = write_mission(tmp_path, photos)
    result = run_mission(mission, out=tmp_path / "run")
    assert result.outcome == "success", result.reason
    summary = result.summary
    assert summary["counters"] == {"photos_uploaded": 3, "photos_pending": 0}
    assert summary["upload"]["photos_queued"] == 3
    assert summary["upload"]["outboxes"][0]["endpoint"] == "the run's own gallery (gallery/)"
    assert summary["skill_outcomes"]["upload"] == {"queued": 3, "uploaded": 1}
    assert len(list((tmp_path / "run" / "gallery" / "photos").iterdir())) == 3
    for path in (tmp_path / "run").rglob("*"):  # trace, summary, report, outbox and gallery files
        if path.is_file():
            assert TOKEN.encode() not in path.read_bytes(), path
    assert TOKEN not in caplog.text


def test_the_same_mission_leaves_the_same_trace(tmp_path) -> None:
    mission = write_mission(tmp_path, [make_photo(tmp_path / f"p{i}", seed=i) for i in range(2)])
    first = run_mission(mission, out=tmp_path / "a")
    second = run_mission(mission, out=tmp_path / "b")
    assert (first.folder / "trace.jsonl").read_bytes() == (second.folder / "trace.jsonl").read_bytes()


def test_a_restarted_robot_resumes_what_it_had_queued(tmp_path) -> None:
    """First run: the gallery is down, photos stay in the outbox. Second run: they go, once each."""
    down = start_gallery(tmp_path / "gallery")
    port = down.port
    down.stop()
    photos = [make_photo(tmp_path / f"p{i}", seed=i) for i in range(2)]
    settings = {"endpoint": down.upload_url, "outbox": str(tmp_path / "outbox"), "backoff_initial": 0.5}
    mission = write_mission(tmp_path, photos, skill_params={"upload": settings})
    first = run_mission(mission, out=tmp_path / "run1")
    assert first.outcome == "failure"  # the waiting upload timed out
    assert first.summary["counters"] == {"photos_uploaded": 0, "photos_pending": 2}
    assert first.summary["upload"]["outboxes"][0]["retries"] > 0
    with start_gallery(tmp_path / "gallery", port=port) as back:
        only_waiting = write_mission(tmp_path, photos[:1], skill_params={"upload": settings})
        second = run_mission(only_waiting, out=tmp_path / "run2")
        assert second.outcome == "success", second.reason
        upload = second.summary["upload"]["outboxes"][0]
        assert upload["resumed_from_earlier_runs"] == 2
        assert upload["photos_uploaded"] == 2 and upload["photos_pending"] == 0
        assert sorted(p["name"] for p in photos_in(back)) == ["p0.jpg", "p1.jpg"]


def test_on_a_real_time_clock_uploads_run_on_a_thread_of_their_own(tmp_path) -> None:
    photo = make_photo(tmp_path / "p")
    mission = {
        "name": "realtime_photo",
        "until": 3,
        "trees": {"main": {"sequence": [{"upload": {"photo": str(photo), "wait": True, "timeout": 2.5}}]}},
    }
    path = tmp_path / "m.yaml"
    path.write_text(yaml.safe_dump(mission))
    result = run_mission(path, out=tmp_path / "run", realtime=True)
    assert result.outcome == "success", result.reason
    assert result.summary["upload"]["photos_uploaded"] == 1
    trace = [json.loads(line) for line in (result.folder / "trace.jsonl").read_text().splitlines()]
    assert [e["outcome"] for e in trace if e["ev"] == "skill_outcome"] == ["uploaded"]


def test_a_mission_that_does_not_upload_starts_nothing(tmp_path) -> None:
    path = tmp_path / "m.yaml"
    path.write_text(yaml.safe_dump({"name": "quiet", "until": 1, "trees": {"main": {"wait": {"duration": 0.5}}}}))
    result = run_mission(path, out=tmp_path / "run")
    assert "upload" not in result.summary
    assert not (tmp_path / "run" / "gallery").exists() and not (tmp_path / "run" / "outbox").exists()
