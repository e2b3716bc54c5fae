"""Upload benchmarks. Run with `python -m tests.bench upload`.

Photos go to the gallery (`botstage gallery`, in a process of its own on 127.0.0.1, as on a
robot's upload computer) two ways, in the same run, against the same server:

- **plain**: an httpx client POSTing each file in turn (the same multipart form, hash and
  ``Idempotency-Key`` as the outbox sends): what a script without durability would do.
- **outbox**: ``Outbox.record`` for each photo (copy in, fsync the file, its sidecar and the
  folder, commit the row with ``synchronous=FULL``), uploaded by the outbox's background worker
  (default settings: 2 in flight), until the last one is marked done.

**batch** times a set of random-ish JPEGs of camera sizes (0.3-4 MB, one of 3.26 MB), from
the first POST (or record) to the last answer (or photo marked uploaded): throughput, and the
latency of each photo (POST to answer; record to marked uploaded). The ratio is outbox /
plain throughput; target >= 0.8. The outbox is also timed with 1 upload in flight, like the
plain client. **paper_photo** is the PeopleBot paper's case: one 3.26 MB photo uploaded alone
(their modified RestFB took 15.9 s to Facebook; here the network is loopback, so the figure
is the software's cost). Each pass and repeat sends fresh bytes (a JPEG comment segment holds
the pass number), so the gallery never answers from its dedup; passes are interleaved and the
median pass is reported.
"""

from __future__ import annotations

import hashlib
import json
import os
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import cv2
import httpx
import numpy as np

from botstage.skills.outbox.outbox import Outbox
from botstage.skills.outbox.settings import OutboxSettings
from botstage.skills.outbox.store import UPLOADED

TARGET_RATIO = 0.8
PAPER_BYTES = 3_260_000  # the paper's 3.26 MB photo
PAPER_SECONDS = 15.856  # modified RestFB, Table V
SOURCE = Path(__file__).resolve().parents[2]  # the checkout: the gallery runs this very code
SIZES_MB = (0.3, 0.6, 1.0, 1.5, 2.0, 2.5, 3.26, 3.5, 4.0, 1.2, 0.8, 2.8)


# -- photos -----------------------------------------------------------------------------------


def _scene(rng: np.random.Generator, height: int, width: int, noise: float) -> np.ndarray:
    """Smooth colour fields with some texture: compresses like a photo, not like flat colour."""
    coarse = rng.random((height // 64 + 2, width // 64 + 2, 3)).astype(np.float32) * 255
    image = cv2.resize(coarse, (width, height), interpolation=cv2.INTER_CUBIC)
    image += rng.normal(0.0, noise, (height, width, 3)).astype(np.float32)
    return np.clip(image, 0, 255).astype(np.uint8)


def _comment(data: bytes, text: bytes) -> bytes:
    """The JPEG with a COM segment right after SOI (different bytes, same picture)."""
    assert len(text) < 65000
    return data[:2] + b"\xff\xfe" + (len(text) + 2).to_bytes(2, "big") + text + data[2:]


def make_jpeg(target: int, seed: int) -> bytes:
    """A JPEG of exactly ``target`` bytes: the highest quality under it, padded with comments."""
    rng = np.random.default_rng(seed)
    pixels = max(640 * 480, int(target * 1.6))  # about 0.6 bytes per pixel at these qualities
    width = int((pixels * 4 / 3) ** 0.5) // 16 * 16
    height = width * 3 // 4
    image = _scene(rng, height, width, noise=14.0)
    low, high, best = 30, 100, b""
    while low <= high:
        quality = (low + high) // 2
        data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, quality])[1].tobytes()
        if len(data) <= target - 16:
            best, low = data, quality + 1
        else:
            high = quality - 1
    if not best:
        raise ValueError(f"cannot make a JPEG of {target} bytes from a {width}x{height} scene")
    while len(best) < target:  # pad with comment segments (4 bytes of header each)
        room = min(65000, target - len(best) - 4)
        best = _comment(best, bytes(max(room, 0)))
    assert len(best) == target, (len(best), target)
    return best


def fresh(photos: list[bytes], tag: str) -> list[bytes]:
    return [_comment(p, f"botstage bench {tag} {i}".encode()) for i, p in enumerate(photos)]


# -- the gallery ------------------------------------------------------------------------------


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_gallery_process(folder: Path) -> tuple[subprocess.Popen[bytes], str]:
    port = _free_port()
    env = {**os.environ, "PYTHONPATH": str(SOURCE)}
    env.pop("BOTSTAGE_GALLERY_TOKEN", None)
    command = [sys.executable, "-m", "botstage.missions.cli", "gallery", "--port", str(port), "--dir", str(folder)]
    command += ["--max-mb", "50"]
    folder.mkdir(parents=True)
    log = (folder.parent / "gallery.log").open("wb")  # its access log, out of the figures' way
    process = subprocess.Popen(command, cwd=folder.parent, env=env, stdout=log, stderr=subprocess.STDOUT)
    log.close()
    url = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + 30
    while True:
        if process.poll() is not None:
            raise RuntimeError(f"the gallery exited: {(folder.parent / 'gallery.log').read_text()}")
        try:
            if httpx.get(url + "/healthz").status_code == 200:
                return process, url
        except httpx.TransportError:
            pass
        if time.monotonic() > deadline:
            process.kill()
            raise RuntimeError("the gallery did not start within 30 s")
        time.sleep(0.05)


# -- the two ways -----------------------------------------------------------------------------


def plain_pass(client: httpx.Client, url: str, photos: list[bytes]) -> dict[str, Any]:
    latencies = []
    started = time.perf_counter()
    for i, data in enumerate(photos):
        digest = hashlib.sha256(data).hexdigest()
        begun = time.perf_counter()
        response = client.post(
            url + "/photos",
            headers={"Idempotency-Key": digest},
            data={"hash": digest, "metadata": json.dumps({"n": i}), "name": f"p{i}.jpg"},
            files={"file": (f"p{i}.jpg", data, "image/jpeg")},
        )
        assert response.status_code == 201, response.text
        latencies.append(time.perf_counter() - begun)
    return {"seconds": time.perf_counter() - started, "latencies": latencies}


def outbox_pass(folder: Path, url: str, photos: list[bytes], concurrency: int) -> dict[str, Any]:
    sources = folder / "camera"
    sources.mkdir(parents=True)
    paths = []
    for i, data in enumerate(photos):  # the camera's files, written before the clock starts
        path = sources / f"p{i}.jpg"
        path.write_bytes(data)
        paths.append(path)
    done: dict[str, float] = {}
    all_done = threading.Event()

    def on_change(item: Any) -> None:  # the stopwatch: the worker's own event, as it marks a photo done
        if item.state == UPLOADED:
            done[item.hash] = time.perf_counter()
            if len(done) == len(photos):
                all_done.set()

    settings = OutboxSettings(concurrency=concurrency)
    outbox = Outbox(folder / "outbox", url + "/photos", settings, background=True, on_change=on_change)
    recorded: dict[str, float] = {}
    record_seconds = []
    try:
        started = time.perf_counter()
        for i, path in enumerate(paths):
            begun = time.perf_counter()
            item = outbox.record(path, {"n": i})
            record_seconds.append(time.perf_counter() - begun)
            recorded[item.hash] = begun
        assert all_done.wait(300), "the outbox did not finish within 300 s"
        seconds = max(done.values()) - started
    finally:
        outbox.close()
    assert outbox.worker.stats["duplicates"] == 0 and outbox.worker.stats["retries"] == 0
    return {
        "seconds": seconds,
        "latencies": [done[h] - recorded[h] for h in recorded],
        "record_seconds": record_seconds,
    }


def _ms(values: list[float]) -> float:
    return round(statistics.median(values) * 1e3, 1)


def bench_batch(url: str, folder: Path, photos: list[bytes], repeats: int) -> dict[str, Any]:
    total = sum(len(p) for p in photos)
    runs: dict[str, list[dict[str, Any]]] = {"plain": [], "outbox": [], "outbox_1": []}
    with httpx.Client(timeout=60) as client:
        for r in range(repeats):  # interleaved: drift in the machine's load hits all three alike
            runs["plain"].append(plain_pass(client, url, fresh(photos, f"plain {r}")))
            runs["outbox"].append(outbox_pass(folder / f"outbox-{r}", url, fresh(photos, f"outbox {r}"), 2))
            runs["outbox_1"].append(outbox_pass(folder / f"outbox1-{r}", url, fresh(photos, f"outbox1 {r}"), 1))

    def figures(passes: list[dict[str, Any]]) -> dict[str, Any]:
        median = sorted(passes, key=lambda p: p["seconds"])[len(passes) // 2]
        latencies = [x for p in passes for x in p["latencies"]]
        out = {
            "seconds": round(median["seconds"], 3),
            "mb_per_s": round(total / 1e6 / median["seconds"], 1),
            "photos_per_s": round(len(photos) / median["seconds"], 1),
            "latency_median_ms": _ms(latencies),
            "latency_max_ms": round(max(latencies) * 1e3, 1),
        }
        if "record_seconds" in median:
            out["record_median_ms"] = _ms([x for p in passes for x in p["record_seconds"]])
        return out

    plain, outbox, outbox_1 = (figures(runs[k]) for k in ("plain", "outbox", "outbox_1"))
    return {
        "bench": "batch_outbox_vs_plain_post",
        "photos": len(photos),
        "mb": round(total / 1e6, 2),
        "plain_post": plain,
        "outbox": outbox,
        "outbox_one_in_flight": outbox_1,
        "ratio": round(plain["seconds"] / outbox["seconds"], 2),
        "ratio_one_in_flight": round(plain["seconds"] / outbox_1["seconds"], 2),
        "target_ratio": TARGET_RATIO,
        "repeats": repeats,
    }


def bench_paper_photo(url: str, folder: Path, photo: bytes, repeats: int) -> dict[str, Any]:
    plain, outbox, record = [], [], []
    with httpx.Client(timeout=60) as client:
        for r in range(repeats):
            plain += plain_pass(client, url, fresh([photo], f"paper plain {r}"))["latencies"]
            one = outbox_pass(folder / f"paper-{r}", url, fresh([photo], f"paper outbox {r}"), 2)
            outbox += one["latencies"]
            record += one["record_seconds"]
    return {
        "bench": "paper_photo_3_26_mb",
        "bytes": len(photo),
        "plain_post_ms": _ms(plain),
        "outbox_record_to_uploaded_ms": _ms(outbox),
        "of_which_record_ms": _ms(record),
        "paper_restfb_ms": round(PAPER_SECONDS * 1e3, 1),
        "faster_than_paper": round(PAPER_SECONDS / statistics.median(outbox), 1),
        "repeats": repeats,
        "network": "loopback (the paper's was 1.7-4.0 Mbit/s to Facebook)",
    }


def missed(results: list[dict[str, Any]]) -> list[str]:
    """The benches whose outbox / plain throughput is under their target ratio."""
    return [r["bench"] for r in results if r.get("ratio", float("inf")) < r.get("target_ratio", 0)]


def main(quick: bool = False) -> list[dict[str, Any]]:
    sizes = SIZES_MB[5:9] if quick else SIZES_MB
    photos = [make_jpeg(int(mb * 1e6) if mb != 3.26 else PAPER_BYTES, seed) for seed, mb in enumerate(sizes)]
    paper = photos[sizes.index(3.26)]
    results = []
    with tempfile.TemporaryDirectory(prefix="botstage-bench-upload-") as tmp:
        folder = Path(tmp)
        process, url = start_gallery_process(folder / "gallery")
        try:
            for bench in (
                lambda: bench_batch(url, folder, photos, 1 if quick else 5),
                lambda: bench_paper_photo(url, folder, paper, 2 if quick else 9),
            ):
                results.append(bench())
                print(json.dumps(results[-1]), flush=True)
        finally:
            process.terminate()
            process.wait(30)
    return results


if __name__ == "__main__":
    main()
