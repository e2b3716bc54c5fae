"""The outbox against a real gallery on 127.0.0.1: crash and restart, the gallery down and back,
refusals, the token, damaged files, idempotency. Time is a hand-driven clock: nothing sleeps."""

from __future__ import annotations

import json
import logging
import os
import random
import socket
import sqlite3
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import cv2
import httpx
import numpy as np
import pytest

from botstage.missions.gallery.server import RunningGallery, start_gallery
from botstage.skills.outbox.outbox import Outbox
from botstage.skills.outbox.settings import TOKEN_ENV, OutboxSettings
from botstage.skills.outbox.store import DAMAGED, PENDING, REJECTED, UPLOADED, OutboxError, OutboxStore
from botstage.skills.outbox.worker import Backoff

TOKEN = "tok-3f9c1d2e-never-log-me"


class ManualClock:
    """The clock the backoff counts in, moved by hand."""

    def __init__(self) -> None:
        self.t = 0.0

    def now(self) -> float:
        return self.t


def make_photo(path: Path, seed: int = 0, size: tuple[int, int] = (120, 160), ext: str = ".jpg") -> Path:
    """A random-ish image (noise over gradients) as JPEG or PNG."""
    rng = np.random.default_rng(seed)
    h, w = size
    gradient = np.linspace(0, 255, w, dtype=np.float32)[None, :, None] * np.ones((h, 1, 3), np.float32)
    image = np.clip(gradient * rng.random(3) + rng.normal(0, 40, (h, w, 3)), 0, 255).astype(np.uint8)
    path = path.with_suffix(ext)
    path.parent.mkdir(parents=True, exist_ok=True)
    assert cv2.imwrite(str(path), image)
    return path


def photos_in(gallery: RunningGallery) -> list[dict]:
    return httpx.get(f"{gallery.url}/api/photos").json()["photos"]


def wait_for(condition: Callable[[], bool], timeout: float = 20.0) -> None:
    """A bounded poll for background work (never a timing assertion)."""
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, "gave up waiting"
        time.sleep(0.01)


@pytest.fixture
def clock() -> ManualClock:
    return ManualClock()


@pytest.fixture
def open_outbox(tmp_path: Path, clock: ManualClock) -> Iterator[Callable[..., Outbox]]:
    opened: list[Outbox] = []

    def make(endpoint: str, folder: Path | None = None, **kwargs) -> Outbox:
        settings = OutboxSettings(**kwargs.pop("settings", {}))
        outbox = Outbox(folder or tmp_path / "outbox", endpoint, settings, now=clock.now, **kwargs)
        opened.append(outbox)
        return outbox

    yield make
    for outbox in opened:
        outbox.close()  # closing twice is harmless


@pytest.fixture(autouse=True)
def no_token_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(TOKEN_ENV, raising=False)


# -- the happy path ---------------------------------------------------------------------------


def test_a_recorded_photo_is_uploaded_with_its_hash_and_metadata(tmp_path, gallery, open_outbox) -> None:
    photo = make_photo(tmp_path / "in" / "smile")
    outbox = open_outbox(gallery.upload_url)
    item = outbox.record(photo, {"visitor": "ada", "n": 3})
    assert item.state == PENDING
    assert (outbox.folder / "files" / f"{item.hash}.jpg").read_bytes() == photo.read_bytes()
    outbox.step()
    assert outbox.status(item.hash).state == UPLOADED
    [shown] = photos_in(gallery)
    assert shown["hash"] == item.hash
    assert shown["name"] == "smile.jpg"
    assert shown["metadata"] == {"visitor": "ada", "n": 3}
    assert outbox.summary()["photos_uploaded"] == 1


def test_recording_the_same_photo_twice_keeps_one_and_uploads_once(tmp_path, gallery, open_outbox) -> None:
    photo = make_photo(tmp_path / "a")
    copy = tmp_path / "elsewhere" / "b.jpg"
    copy.parent.mkdir()
    copy.write_bytes(photo.read_bytes())
    outbox = open_outbox(gallery.upload_url)
    first = outbox.record(photo)
    again = outbox.record(copy)
    assert again.hash == first.hash
    assert outbox.recorded == 1
    for _ in range(3):
        outbox.step()
    assert outbox.worker.stats["attempts"] == 1
    assert len(photos_in(gallery)) == 1
    assert outbox.record(photo).state == UPLOADED  # recorded after the upload: nothing to do


def test_many_photos_in_parallel_each_arrive_once(tmp_path, gallery, open_outbox) -> None:
    photos = [make_photo(tmp_path / f"p{i}", seed=i) for i in range(7)]
    outbox = open_outbox(gallery.upload_url, settings={"concurrency": 3})
    items = [outbox.record(p, {"i": i}) for i, p in enumerate(photos)]
    for _ in range(3):
        outbox.step()
    assert outbox.counts()[UPLOADED] == 7
    listed = photos_in(gallery)
    assert sorted(p["hash"] for p in listed) == sorted(i.hash for i in items)


def test_background_mode_uploads_without_being_pumped(tmp_path, gallery) -> None:
    """Real time: the outbox pumps on its own thread (bounded poll for the result)."""
    with Outbox(tmp_path / "outbox", gallery.upload_url, background=True) as outbox:
        items = [outbox.record(make_photo(tmp_path / f"p{i}", seed=i)) for i in range(3)]
        wait_for(lambda: all(outbox.status(i.hash).state == UPLOADED for i in items))
    assert len(photos_in(gallery)) == 3


# -- crashes and restarts ---------------------------------------------------------------------


def test_a_worker_killed_mid_way_loses_nothing_and_sends_nothing_twice(tmp_path, gallery, open_outbox) -> None:
    photos = [make_photo(tmp_path / f"p{i}", seed=i) for i in range(5)]
    first = open_outbox(gallery.upload_url, settings={"concurrency": 2})
    hashes = [first.record(p).hash for p in photos]
    first.pump()  # two uploads in flight...
    assert first.worker.in_flight == 2
    first.abandon()  # ...and the process dies: their answers are never applied
    second = open_outbox(gallery.upload_url)
    assert second.resumed == 5  # nothing was marked done
    for _ in range(5):
        second.step()
    assert second.counts() == {PENDING: 0, UPLOADED: 5, REJECTED: 0, DAMAGED: 0}
    listed = [p["hash"] for p in photos_in(gallery)]
    assert sorted(listed) == sorted(hashes)  # each exactly once


CRASHING_ROBOT = """
import sys
from botstage.skills.outbox.outbox import Outbox
outbox = Outbox(sys.argv[1], sys.argv[2], background=True)
for photo in sys.argv[3:]:
    outbox.record(photo)
print("recorded", flush=True)
sys.stdin.readline()  # killed while waiting here, uploads in flight or done
"""


def test_a_process_killed_with_sigkill_leaves_an_outbox_the_next_one_finishes(tmp_path, gallery, open_outbox) -> None:
    photos = [str(make_photo(tmp_path / f"p{i}", seed=i, size=(480, 640))) for i in range(6)]
    folder = tmp_path / "outbox"
    robot = subprocess.Popen(
        [sys.executable, "-c", CRASHING_ROBOT, str(folder), gallery.upload_url, *photos],
        cwd=Path(__file__).resolve().parent.parent,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert robot.stdout is not None and robot.stdout.readline() == "recorded\n"
    finally:
        robot.kill()  # SIGKILL: no finally, no close, the WAL as it was
        robot.wait(30)
    after = open_outbox(gallery.upload_url, folder)
    assert after.counts()[PENDING] + after.counts()[UPLOADED] == 6
    for _ in range(6):
        after.step()
    assert after.counts()[UPLOADED] == 6
    assert sorted(p["name"] for p in photos_in(gallery)) == [f"p{i}.jpg" for i in range(6)]


def test_a_crash_after_the_gallery_stored_it_but_before_marking_done_makes_no_duplicate(
    tmp_path, gallery, open_outbox
) -> None:
    first = open_outbox(gallery.upload_url)
    item = first.record(make_photo(tmp_path / "p"))
    data = first.store.read_verified(item)
    assert first.client.upload(item, data).verdict == "uploaded"  # the gallery has it...
    first.close()  # ...and the answer is lost with the process
    second = open_outbox(gallery.upload_url)
    assert second.status(item.hash).state == PENDING
    second.step()
    assert second.status(item.hash).state == UPLOADED
    assert second.worker.stats["duplicates"] == 1  # the gallery recognised the hash
    assert len(photos_in(gallery)) == 1


def test_what_a_crash_leaves_half_written_is_cleaned_or_adopted(tmp_path, gallery, open_outbox) -> None:
    folder = tmp_path / "outbox"
    first = open_outbox(gallery.upload_url, folder)
    item = first.record(make_photo(tmp_path / "p"))
    first.close()
    (folder / "tmp" / "0123.part").write_bytes(b"\xff\xd8\xff half a copy")  # cut short while copying
    with sqlite3.connect(folder / "outbox.sqlite") as db:  # cut short after the files, before the row
        db.execute("DELETE FROM photos")
    second = open_outbox(gallery.upload_url, folder)
    assert list((folder / "tmp").iterdir()) == []
    assert second.status(item.hash).state == PENDING
    assert any("without a record were queued" in note for note in second.store.notes)
    second.step()
    assert [p["hash"] for p in photos_in(gallery)] == [item.hash]


def test_a_damaged_database_is_set_aside_and_rebuilt_from_the_files(tmp_path, gallery, open_outbox) -> None:
    folder = tmp_path / "outbox"
    first = open_outbox(gallery.upload_url, folder)
    done = first.record(make_photo(tmp_path / "a", seed=1))
    first.step()
    waiting = first.record(make_photo(tmp_path / "b", seed=2))
    first.close()
    for name in ("outbox.sqlite-wal", "outbox.sqlite-shm"):
        (folder / name).unlink(missing_ok=True)
    (folder / "outbox.sqlite").write_bytes(b"this is not an SQLite database" * 100)
    second = open_outbox(gallery.upload_url, folder)
    assert any("database was damaged" in note for note in second.store.notes)
    assert list(folder.glob("outbox.sqlite.damaged-1"))
    assert {second.status(done.hash).state, second.status(waiting.hash).state} == {PENDING}
    second.step()
    assert second.counts()[UPLOADED] == 2
    assert second.worker.stats["duplicates"] == 1  # the one the gallery already had
    assert sorted(p["hash"] for p in photos_in(gallery)) == sorted([done.hash, waiting.hash])


def test_a_damaged_copy_is_repaired_from_the_original(tmp_path, gallery, open_outbox) -> None:
    photo = make_photo(tmp_path / "p")
    outbox = open_outbox(gallery.upload_url)
    item = outbox.record(photo)
    item.file.write_bytes(item.file.read_bytes()[:100])  # the disk lost the end of the copy
    outbox.step()
    assert outbox.status(item.hash).state == UPLOADED
    assert item.file.read_bytes() == photo.read_bytes()
    assert photos_in(gallery)[0]["hash"] == item.hash


def test_a_damaged_copy_without_its_original_is_never_sent(tmp_path, gallery, open_outbox) -> None:
    photo = make_photo(tmp_path / "p")
    outbox = open_outbox(gallery.upload_url)
    item = outbox.record(photo)
    photo.unlink()
    item.file.write_bytes(b"\xff\xd8\xff" + os.urandom(500))
    outbox.step()
    status = outbox.status(item.hash)
    assert status.state == DAMAGED
    assert "does not match its hash, and the original is gone" in status.last_error
    assert photos_in(gallery) == []
    outbox.step()
    assert outbox.worker.stats["attempts"] == 1  # final: not retried


def test_a_sidecar_that_is_not_json_is_left_out_with_a_note(tmp_path, gallery, open_outbox) -> None:
    folder = tmp_path / "outbox"
    (folder / "files").mkdir(parents=True)
    (folder / "files" / f"{'a' * 64}.json").write_text("{not json")
    outbox = open_outbox(gallery.upload_url, folder)
    assert outbox.counts()[PENDING] == 0
    assert any(note.startswith(f"left out {'a' * 64}.json") for note in outbox.store.notes)


# -- the gallery down, then back --------------------------------------------------------------


def test_gallery_down_for_a_while_then_back_loses_nothing_and_sends_nothing_twice(tmp_path, open_outbox, clock) -> None:
    gallery = start_gallery(tmp_path / "gallery")
    port = gallery.port
    gallery.stop()  # down before the first photo
    outbox = open_outbox(gallery.upload_url, settings={"backoff_initial": 2.0, "backoff_max": 16.0})
    hashes = [outbox.record(make_photo(tmp_path / f"p{i}", seed=i)).hash for i in range(3)]
    attempts = 0
    while clock.t < 60:  # a minute of mission time with the gallery down
        outbox.step()
        clock.t += 0.1
        attempts = outbox.worker.stats["attempts"]
    for h in hashes:
        status = outbox.status(h)
        assert status.state == PENDING
        assert "unreachable" in status.last_error
    # waits of 1-2, 2-4, 4-8, 8-16, 8-16... s: 6 to 10 tries each in 60 s, not one a tick
    assert 3 * 6 <= attempts <= 3 * 10
    gallery = start_gallery(tmp_path / "gallery", port=port)  # back, on the same address
    try:
        while outbox.counts()[PENDING] and clock.t < 200:
            outbox.step()
            clock.t += 0.1
        assert outbox.counts()[UPLOADED] == 3
        assert clock.t - 60 <= 16.0 + 0.2  # each was retried within the longest backoff
        assert sorted(p["hash"] for p in photos_in(gallery)) == sorted(hashes)
    finally:
        gallery.stop()


def test_backoff_is_exponential_capped_and_jittered_by_the_seed() -> None:
    backoff = Backoff(1.0, 30.0)
    rng = random.Random(4)
    delays = [backoff.delay(n, rng) for n in range(1, 9)]
    for n, delay in enumerate(delays, start=1):
        full = min(30.0, 2.0 ** (n - 1))
        assert full / 2 <= delay <= full
    again = random.Random(4)
    assert [backoff.delay(n, again) for n in range(1, 9)] == delays
    assert backoff.delay(200, rng) <= 30.0  # no overflow on a long outage


def test_the_retry_schedule_is_the_same_for_the_same_seed(tmp_path, clock) -> None:
    down = start_gallery(tmp_path / "g")
    down.stop()

    def schedule(folder: str, seed: int) -> list[float]:
        clock.t = 0.0
        outbox = Outbox(tmp_path / folder, down.upload_url, now=clock.now, seed=seed)
        outbox.record(make_photo(tmp_path / "p"))
        due = []
        while clock.t < 30:
            outbox.step()
            if outbox.worker.next_due() not in (None, *due):
                due.append(outbox.worker.next_due())
            clock.t += 0.1
        outbox.close()
        return due

    assert schedule("a", 1) == schedule("b", 1)
    assert schedule("c", 1) != schedule("d", 2)


# -- refusals ---------------------------------------------------------------------------------


def test_what_is_not_a_photo_is_refused_before_it_enters_the_outbox(tmp_path, gallery, open_outbox) -> None:
    outbox = open_outbox(gallery.upload_url)
    text = tmp_path / "notes.jpg"
    text.write_text("a text file named like a photo")
    with pytest.raises(OutboxError, match="is not a JPEG or PNG"):
        outbox.record(text)
    with pytest.raises(OutboxError, match="no such photo"):
        outbox.record(tmp_path / "missing.jpg")
    with pytest.raises(OutboxError, match="metadata must be plain JSON"):
        outbox.record(make_photo(tmp_path / "p"), {"when": object()})
    assert outbox.counts()[PENDING] == 0
    assert list((outbox.folder / "tmp").iterdir()) == []


def test_a_photo_the_gallery_refuses_is_rejected_once_not_retried(tmp_path, gallery, open_outbox) -> None:
    truncated = tmp_path / "cut.jpg"
    truncated.write_bytes(make_photo(tmp_path / "p").read_bytes()[:-200])
    outbox = open_outbox(gallery.upload_url)
    item = outbox.record(truncated)
    for _ in range(3):
        outbox.step()
    status = outbox.status(item.hash)
    assert status.state == REJECTED
    assert "HTTP 415" in status.last_error and "truncated" in status.last_error
    assert outbox.worker.stats["attempts"] == 1
    assert photos_in(gallery) == []


def test_a_photo_over_the_gallerys_limit_is_rejected_with_413(tmp_path, open_outbox) -> None:
    with start_gallery(tmp_path / "g", max_bytes=20_000) as small:
        outbox = open_outbox(small.upload_url)
        item = outbox.record(make_photo(tmp_path / "big", size=(480, 640)))
        assert item.size > 20_000
        outbox.step()
        status = outbox.status(item.hash)
        assert status.state == REJECTED
        assert "HTTP 413" in status.last_error


def test_a_wrong_token_keeps_the_photo_waiting_until_the_right_one_comes(tmp_path, open_outbox, clock) -> None:
    with start_gallery(tmp_path / "g", token=TOKEN) as locked:
        folder = tmp_path / "outbox"
        without = open_outbox(locked.upload_url, folder)
        item = without.record(make_photo(tmp_path / "p"))
        without.step()
        status = without.status(item.hash)
        assert status.state == PENDING
        assert f"refused the token (HTTP 401): check {TOKEN_ENV}" in status.last_error
        without.close()
        wrong = open_outbox(locked.upload_url, folder, token="guess")
        clock.t += 100
        wrong.step()
        assert "HTTP 401" in wrong.status(item.hash).last_error
        wrong.close()
        right = open_outbox(locked.upload_url, folder, token=TOKEN)
        right.step()
        assert right.status(item.hash).state == UPLOADED
        assert len(photos_in(locked)) == 1


def test_the_token_comes_from_the_environment_and_is_never_logged(tmp_path, open_outbox, monkeypatch, caplog) -> None:
    caplog.set_level(logging.DEBUG)  # everything: httpx, httpcore, the outbox, the gallery
    monkeypatch.setenv(TOKEN_ENV, TOKEN)
    with start_gallery(tmp_path / "g", token=TOKEN) as locked:
        refused = open_outbox(locked.upload_url, tmp_path / "refused", token="wrong-token")
        refused.record(make_photo(tmp_path / "p0"))
        refused.step()
        outbox = open_outbox(locked.upload_url)  # the token from the environment
        outbox.record(make_photo(tmp_path / "p1", seed=1))
        outbox.step()
        assert outbox.counts()[UPLOADED] == 1
        shown = [repr(outbox.client), json.dumps(outbox.summary()), json.dumps(refused.summary()), caplog.text]
        outbox.close()
    assert "HTTP Request: POST" in caplog.text  # httpx did log the requests
    for text in shown:
        assert TOKEN not in text
    for path in tmp_path.rglob("*"):  # nor stored by the outbox or the gallery
        if path.is_file():
            assert TOKEN.encode() not in path.read_bytes(), path


def test_two_outboxes_sending_the_same_photo_leave_one_in_the_gallery(tmp_path, gallery, open_outbox) -> None:
    photo = make_photo(tmp_path / "p")
    a = open_outbox(gallery.upload_url, tmp_path / "a")
    b = open_outbox(gallery.upload_url, tmp_path / "b")
    a.record(photo)
    b.record(photo)
    a.step()
    b.step()
    assert a.counts()[UPLOADED] == b.counts()[UPLOADED] == 1
    assert b.worker.stats["duplicates"] == 1
    assert len(photos_in(gallery)) == 1


def test_the_store_is_safe_to_record_into_from_several_threads(tmp_path) -> None:
    store = OutboxStore(tmp_path / "outbox")
    photos = [make_photo(tmp_path / f"p{i % 4}", seed=i % 4) for i in range(12)]  # each photo three times
    results = []
    threads = [threading.Thread(target=lambda p=p: results.append(store.record(p))) for p in photos]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert sum(created for _, created in results) == 4
    assert len(store.items()) == 4
    assert len(list((tmp_path / "outbox" / "files").glob("*.jpg"))) == 4
    store.close()
    reopened = OutboxStore(tmp_path / "outbox")
    assert len(reopened.items()) == 4
    reopened.close()


# -- how each answer is classified: a scripted server on 127.0.0.1 ----------------------------

SERVER_DATE = "Sun, 06 Nov 1994 08:49:37 GMT"  # far from today: the client must read it, not its own clock


class Scripted:
    """An HTTP server on a free loopback port answering every POST as told."""

    def __init__(self) -> None:
        self.status = 200
        self.headers: dict[str, str] = {}
        self.body = b"{}"
        self.requests = 0
        scripted = self

        class Handler(BaseHTTPRequestHandler):
            def do_POST(self) -> None:
                self.rfile.read(int(self.headers.get("Content-Length", 0)))
                scripted.requests += 1
                self.send_response_only(scripted.status)
                headers = {"Date": SERVER_DATE, "Content-Type": "application/json", **scripted.headers}
                for name, value in headers.items():
                    if value is not None:
                        self.send_header(name, value)
                self.send_header("Content-Length", str(len(scripted.body)))
                self.end_headers()
                self.wfile.write(scripted.body)

            def log_message(self, *args: object) -> None:
                pass

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.server.daemon_threads = True
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)
        self.thread.start()
        self.url = f"http://127.0.0.1:{self.server.server_address[1]}/photos"

    def answer(self, status: int, headers: dict[str, str | None] | None = None, detail: str | None = None) -> None:
        self.status, self.headers = status, dict(headers or {})
        self.body = json.dumps({"detail": detail} if detail else {}).encode()

    def stop(self) -> None:
        self.server.shutdown()
        self.server.server_close()


@pytest.fixture
def scripted() -> Iterator[Scripted]:
    server = Scripted()
    yield server
    server.stop()


BACKOFF = {"backoff_initial": 1.0, "backoff_max": 60.0}


@pytest.mark.parametrize(
    ("status", "headers", "said", "wait"),
    [
        (500, {}, "HTTP 500 from", (0.5, 1.0)),
        (502, {}, "HTTP 502 from", (0.5, 1.0)),
        (503, {}, "HTTP 503 from", (0.5, 1.0)),
        (504, {}, "HTTP 504 from", (0.5, 1.0)),
        (503, {"Retry-After": "7"}, "HTTP 503 from", (7.0, 7.0)),
        (429, {"Retry-After": "12"}, "HTTP 429 from", (12.0, 12.0)),
        (429, {}, "HTTP 429 from", (0.5, 1.0)),
        (429, {"Retry-After": "Sun, 06 Nov 1994 08:50:07 GMT"}, "asked to retry after 30 s", (30.0, 30.0)),
        # an HTTP-date without the server's Date: counted from now; a day away is cut to the longest backoff
        (429, {"Date": None, "Retry-After": "Fri, 01 Jan 2100 00:00:00 GMT"}, "HTTP 429 from", (60.0, 60.0)),
        (503, {"Retry-After": "86400"}, "asked to retry after 86400 s", (60.0, 60.0)),
        (503, {"Retry-After": "Sun, 06 Nov 1994 08:00:00 GMT"}, "HTTP 503 from", (0.5, 1.0)),  # in the past
        (503, {"Retry-After": "soon"}, "HTTP 503 from", (0.5, 1.0)),  # not a valid value: plain backoff
        (408, {}, "HTTP 408 from", (0.5, 1.0)),
        (404, {}, "no upload address at", (0.5, 1.0)),  # a wrong endpoint waits for the operator
        (405, {}, "HTTP 405", (0.5, 1.0)),
        (403, {}, "refused the token (HTTP 403)", (0.5, 1.0)),
    ],
)
def test_a_transient_answer_is_retried_after_the_wait_it_asks_for(
    tmp_path, scripted, open_outbox, clock, status, headers, said, wait
) -> None:
    scripted.answer(status, headers, detail="busy, come back later")
    outbox = open_outbox(scripted.url, settings=BACKOFF)
    item = outbox.record(make_photo(tmp_path / "p"))
    outbox.step()
    after = outbox.status(item.hash)
    assert after.state == PENDING
    assert after.attempts == 1
    assert said in after.last_error
    assert str(status) in after.last_error
    assert outbox.worker.stats["retries"] == 1
    due = outbox.worker.next_due()
    assert due is not None and wait[0] <= due - clock.t <= wait[1]
    clock.t = due - 0.01
    outbox.step()  # not yet
    assert scripted.requests == 1
    scripted.answer(201, detail=None)
    clock.t = due
    outbox.step()
    assert outbox.status(item.hash).state == UPLOADED
    assert scripted.requests == 2


@pytest.mark.parametrize("status", [400, 409, 412, 418, 422, 451])
def test_a_photo_refused_with_another_4xx_is_rejected_for_good_with_the_reason(
    tmp_path, scripted, open_outbox, clock, status
) -> None:
    scripted.answer(status, {"Retry-After": "1"}, detail="no faces allowed")
    outbox = open_outbox(scripted.url, settings=BACKOFF)
    item = outbox.record(make_photo(tmp_path / "p"))
    for _ in range(5):
        outbox.step()
        clock.t += 100
    after = outbox.status(item.hash)
    assert after.state == REJECTED
    assert after.last_error == f"the gallery refused the photo (HTTP {status}: no faces allowed)"
    assert scripted.requests == 1
    assert outbox.worker.next_due() is None
    assert outbox.summary()["photos_rejected"] == 1


def test_a_gallery_that_never_answers_times_out_and_is_retried(tmp_path, open_outbox, clock) -> None:
    """It accepts the connection (the kernel does, from the backlog) and never reads or answers."""
    with socket.socket() as silent:
        silent.bind(("127.0.0.1", 0))
        silent.listen(8)
        url = f"http://127.0.0.1:{silent.getsockname()[1]}/photos"
        outbox = open_outbox(url, settings={**BACKOFF, "request_timeout": 0.2})
        item = outbox.record(make_photo(tmp_path / "p"))
        outbox.step()  # waits for the attempt: the client's own 0.2 s timeout ends it
        after = outbox.status(item.hash)
        assert after.state == PENDING
        assert after.last_error == f"the gallery at {url} did not answer in time (ReadTimeout)"
        due = outbox.worker.next_due()
        assert due is not None and 0.5 <= due - clock.t <= 1.0
