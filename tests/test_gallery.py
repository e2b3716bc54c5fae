"""The gallery server over real HTTP on 127.0.0.1: storing, deduplicating, refusing bad uploads
with a clear 4xx, the page and the JSON list, restarts, and `botstage gallery` itself."""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import cv2
import httpx
import numpy as np
import pytest

from botstage.missions.gallery.server import RunningGallery, start_gallery
from botstage.missions.serving import bind, is_loopback
from tests.test_outbox import TOKEN, make_photo, photos_in, wait_for

ROOT = Path(__file__).resolve().parent.parent


NOISE = bytes([0x42]) + np.random.default_rng(7).bytes(3000)  # not a marker at byte 3: seeded, never flaky


def zeroed_idat(png: bytes) -> bytes:
    """A PNG whole in its chunks whose compressed pixels are zeros: only decoding finds out."""
    start = png.index(b"IDAT") + 4
    return png[:start] + bytes(200) + png[start + 200 :]


@pytest.fixture
def jpeg(tmp_path: Path) -> bytes:
    return make_photo(tmp_path / "photo", size=(240, 320)).read_bytes()


def post(
    gallery: RunningGallery, data: bytes, name: str = "p.jpg", headers: dict | None = None, **form: str
) -> httpx.Response:
    return httpx.post(gallery.upload_url, files={"file": (name, data, "image/jpeg")}, data=form, headers=headers)


def test_an_upload_is_stored_listed_shown_and_served(gallery, jpeg) -> None:
    digest = hashlib.sha256(jpeg).hexdigest()
    meta = {"visitor": "Ada <script>alert(1)</script>", "people": 3}
    key = {"Idempotency-Key": digest}
    response = post(gallery, jpeg, "../../etc/smile.jpg", key, hash=digest, metadata=json.dumps(meta))
    assert response.status_code == 201, response.text
    body = response.json()
    assert body["duplicate"] is False and body["hash"] == digest
    assert response.headers["location"] == f"/photos/{digest}"
    [listed] = photos_in(gallery)
    assert listed["name"] == "smile.jpg"  # only the file name of what the client said
    assert listed["metadata"] == meta and listed["size"] == len(jpeg)
    page = httpx.get(gallery.url + "/")
    assert page.status_code == 200 and page.headers["content-type"].startswith("text/html")
    assert "smile.jpg" in page.text and "1 photo" in page.text
    assert "<script>alert" not in page.text and "&lt;script&gt;alert(1)&lt;/script&gt;" in page.text
    photo = httpx.get(f"{gallery.url}/photos/{digest}")
    assert photo.content == jpeg and photo.headers["content-type"] == "image/jpeg"
    thumb = httpx.get(f"{gallery.url}/thumbs/{digest}")
    assert thumb.headers["content-type"] == "image/jpeg"
    assert cv2.imdecode(np.frombuffer(thumb.content, np.uint8), cv2.IMREAD_COLOR) is not None
    assert httpx.get(gallery.url + "/healthz").json() == {"ok": True, "photos": 1}


def test_the_same_bytes_twice_are_one_photo(gallery, jpeg) -> None:
    assert post(gallery, jpeg, "a.jpg").status_code == 201
    again = post(gallery, jpeg, "b.jpg", metadata='{"other": true}')
    assert again.status_code == 200 and again.json()["duplicate"] is True
    [listed] = photos_in(gallery)
    assert listed["name"] == "a.jpg" and listed["metadata"] == {}  # the first one stays as it was


def test_concurrent_uploads_of_one_photo_store_it_once(gallery, jpeg) -> None:
    statuses: list[int] = []
    threads = [threading.Thread(target=lambda: statuses.append(post(gallery, jpeg).status_code)) for _ in range(6)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert sorted(statuses) == [200] * 5 + [201]
    assert len(photos_in(gallery)) == 1
    assert len(list((gallery.folder / "photos").iterdir())) == 1


def test_a_png_is_accepted_too(gallery, tmp_path) -> None:
    png = make_photo(tmp_path / "p", ext=".png").read_bytes()
    assert post(gallery, png, "p.png").status_code == 201
    assert httpx.get(f"{gallery.url}/photos/{hashlib.sha256(png).hexdigest()}").headers["content-type"] == "image/png"


@pytest.mark.parametrize(
    ("mangle", "message"),
    [
        (lambda jpg, png: b"just some text", "not a JPEG or PNG image"),
        (lambda jpg, png: jpg[:-300], "the JPEG is truncated"),
        (lambda jpg, png: png[:-30], "the PNG is truncated"),
        (lambda jpg, png: b"\xff\xd8\xff" + NOISE + b"\xff\xd9", "the JPEG is damaged"),
        (lambda jpg, png: jpg[:20] + bytes(2000) + jpg[2020:], "the JPEG is damaged (no marker at byte 20)"),
        (lambda jpg, png: jpg[:2] + b"\xff\xd9", "the JPG does not decode (no frame header)"),
        (lambda jpg, png: zeroed_idat(png), "the PNG does not decode"),
        (lambda jpg, png: png[:16] + bytes(8) + png[24:], "the PNG has no pixels (0x0)"),
    ],
    ids=["text", "truncated-jpeg", "truncated-png", "random-bytes", "zeroed-header", "no-frame", "zeroed-png", "empty"],
)
def test_what_is_not_a_whole_image_is_refused_with_415(gallery, jpeg, tmp_path, mangle, message) -> None:
    png = make_photo(tmp_path / "p", ext=".png").read_bytes()
    response = post(gallery, mangle(jpeg, png))
    assert response.status_code == 415
    assert message in response.json()["detail"]
    assert photos_in(gallery) == []


def test_bytes_that_do_not_match_their_hash_are_refused_with_400(gallery, jpeg) -> None:
    wrong = "0" * 64
    response = post(gallery, jpeg, hash=wrong)
    assert response.status_code == 400 and "do not match its hash" in response.json()["detail"]
    response = post(gallery, jpeg, headers={"Idempotency-Key": wrong})
    assert response.status_code == 400 and "Idempotency-Key" in response.json()["detail"]
    assert photos_in(gallery) == []


@pytest.mark.parametrize(
    ("metadata", "message"), [("{not json", "metadata is not JSON"), ("[1, 2]", "must be a JSON object")]
)
def test_bad_metadata_is_refused_with_400(gallery, jpeg, metadata, message) -> None:
    response = post(gallery, jpeg, metadata=metadata)
    assert response.status_code == 400 and message in response.json()["detail"]


def test_a_form_without_a_photo_is_422(gallery) -> None:
    response = httpx.post(gallery.upload_url, data={"hash": "x"})
    assert response.status_code == 422


def test_too_large_is_refused_with_413_however_it_is_sent(tmp_path, jpeg) -> None:
    with start_gallery(tmp_path / "g", max_bytes=len(jpeg) - 1) as small:
        response = post(small, jpeg)  # fits the form's slack: the photo itself is measured
        assert response.status_code == 413 and "over the gallery's limit" in response.json()["detail"]
        big = jpeg * 40  # over the limit with its Content-Length: refused before parsing
        response = post(small, big)
        assert response.status_code == 413
        boundary = "b0undary"
        form = (
            (
                f'--{boundary}\r\nContent-Disposition: form-data; name="file"; filename="p.jpg"\r\n'
                "Content-Type: image/jpeg\r\n\r\n"
            ).encode()
            + big
            + f"\r\n--{boundary}--\r\n".encode()
        )

        def chunks() -> Iterator[bytes]:  # no Content-Length: counted as it streams
            for start in range(0, len(form), 65536):
                yield form[start : start + 65536]

        response = httpx.post(
            small.upload_url, content=chunks(), headers={"Content-Type": f"multipart/form-data; boundary={boundary}"}
        )
        assert response.status_code == 413
        assert photos_in(small) == []


def test_a_gallery_with_a_token_refuses_uploads_without_it_with_401(tmp_path, jpeg) -> None:
    with start_gallery(tmp_path / "g", token=TOKEN) as locked:
        for headers in ({}, {"Authorization": "Bearer nope"}, {"Authorization": TOKEN}):
            response = post(locked, jpeg, headers=headers)
            assert response.status_code == 401
            assert response.json() == {"detail": "missing or wrong token"}
            assert response.headers["www-authenticate"] == "Bearer"
        assert post(locked, jpeg, headers={"Authorization": f"Bearer {TOKEN}"}).status_code == 201
        assert httpx.get(locked.url + "/").status_code == 200  # looking needs no token
        assert len(photos_in(locked)) == 1


def test_unknown_or_malformed_photo_addresses_are_404(gallery) -> None:
    for path in ("/photos/" + "a" * 64, "/photos/..%2f..%2fgallery.sqlite", "/thumbs/nothing"):
        assert httpx.get(gallery.url + path).status_code == 404


def test_photos_survive_a_restart_on_the_same_port(tmp_path, jpeg) -> None:
    first = start_gallery(tmp_path / "g")
    assert post(first, jpeg).status_code == 201
    port = first.port
    first.stop()
    with pytest.raises(httpx.ConnectError):
        httpx.get(first.url + "/healthz")
    with start_gallery(tmp_path / "g", port=port) as second:
        assert second.url == first.url
        assert post(second, jpeg).json()["duplicate"] is True
        assert len(photos_in(second)) == 1


def test_an_empty_gallery_says_so(gallery) -> None:
    assert "No photos yet." in httpx.get(gallery.url + "/").text
    assert httpx.get(gallery.url + "/api/photos").json() == {"count": 0, "photos": []}


def test_loopback_addresses() -> None:
    assert is_loopback("127.0.0.1") and is_loopback("::1") and is_loopback("localhost")
    assert not is_loopback("0.0.0.0") and not is_loopback("192.0.2.1") and not is_loopback("example.org")


def test_botstage_gallery_serves_on_loopback_until_stopped(tmp_path, jpeg) -> None:
    probe = bind("127.0.0.1", 0)
    port = probe.getsockname()[1]
    probe.close()
    env = {**os.environ, "BOTSTAGE_GALLERY_TOKEN": TOKEN}
    command = [
        sys.executable,
        "-m",
        "botstage.missions.cli",
        "gallery",
        "--port",
        str(port),
        "--dir",
        str(tmp_path / "g"),
    ]
    process = subprocess.Popen(command, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    url = f"http://127.0.0.1:{port}"
    try:

        def up() -> bool:
            assert process.poll() is None, process.communicate()
            try:
                return httpx.get(url + "/healthz").status_code == 200
            except httpx.TransportError:
                return False

        wait_for(up)
        files = {"file": ("p.jpg", jpeg, "image/jpeg")}
        assert httpx.post(url + "/photos", files=files).status_code == 401
        assert httpx.post(url + "/photos", files=files, headers={"Authorization": f"Bearer {TOKEN}"}).status_code == 201
    finally:
        process.terminate()
        _, stderr = process.communicate(timeout=20)
    assert f"at http://127.0.0.1:{port}/" in stderr and "token required" in stderr
    assert TOKEN not in stderr
    assert len(list((tmp_path / "g" / "photos").iterdir())) == 1


def test_botstage_gallery_says_when_the_port_is_taken(tmp_path) -> None:
    taken = bind("127.0.0.1", 0)
    try:
        port = taken.getsockname()[1]
        result = subprocess.run(
            [
                sys.executable,
                "-m",
                "botstage.missions.cli",
                "gallery",
                "--port",
                str(port),
                "--dir",
                str(tmp_path / "g"),
            ],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=60,
        )
    finally:
        taken.close()
    assert result.returncode == 2
    assert f"error: cannot serve on 127.0.0.1:{port}" in result.stderr


def test_after_refusing_a_non_image_an_oversized_file_and_a_wrong_token_it_still_takes_photos(tmp_path, jpeg) -> None:
    auth = {"Authorization": f"Bearer {TOKEN}"}
    with start_gallery(tmp_path / "g", token=TOKEN, max_bytes=len(jpeg) + 10) as strict:
        refused = [
            post(strict, b"just some text", headers=auth),
            post(strict, jpeg * 3, headers=auth),
            post(strict, jpeg, headers={"Authorization": "Bearer nope"}),
        ]
        assert [r.status_code for r in refused] == [415, 413, 401]
        assert all(r.json()["detail"] for r in refused)  # each says why
        assert post(strict, jpeg, headers=auth).status_code == 201
        assert httpx.get(strict.url + "/").status_code == 200
        assert len(photos_in(strict)) == 1


def png_of(width: int, height: int, rows_per_block: int = 250) -> bytes:
    """A grey PNG of any size, built as a stream: a big one is a small file (a decompression bomb)."""
    import struct
    import zlib

    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    packer, block, parts = zlib.compressobj(1), bytes(1 + width) * rows_per_block, []
    for _ in range(height // rows_per_block):
        parts.append(packer.compress(block))
    parts.append(packer.compress(bytes(1 + width) * (height % rows_per_block)) + packer.flush())
    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", b"".join(parts)) + chunk(b"IEND", b"")


def test_an_image_of_too_many_pixels_is_refused_from_its_header_before_decoding(gallery, monkeypatch) -> None:
    from botstage.missions.gallery import images

    bomb = png_of(8000, 8000)  # 64 MP in a small file
    assert len(bomb) < 1_000_000
    decoded: list[int] = []
    real = images.cv2.imdecode
    monkeypatch.setattr(images.cv2, "imdecode", lambda *a: decoded.append(1) or real(*a))
    response = post(gallery, bomb, "bomb.png")
    assert response.status_code == 413
    assert response.json()["detail"] == "the image is 8000x8000 pixels (64.0 MP), over the gallery's limit of 40 MP"
    assert decoded == [] and photos_in(gallery) == []
    small = png_of(400, 300)
    assert post(gallery, small, "small.png").status_code == 201 and decoded  # the same path decodes a sane one


def test_the_pixel_limit_is_configurable(tmp_path, jpeg) -> None:
    with start_gallery(tmp_path / "g", max_pixels=320 * 240 - 1) as strict:
        response = post(strict, jpeg)
        assert response.status_code == 413 and "320x240 pixels" in response.json()["detail"]
    with start_gallery(tmp_path / "g", max_pixels=320 * 240) as exact:
        assert post(exact, jpeg).status_code == 201


@pytest.mark.parametrize("ext", [".jpg", ".png"])
def test_bytes_after_the_image_are_kept_as_sent_and_not_taken_for_damage(gallery, tmp_path, ext) -> None:
    photo = make_photo(tmp_path / "p", size=(240, 320), ext=ext).read_bytes()
    sent = photo + b"\x00\x00trailer: a camera's maker notes or a motion photo's video" * 50
    response = post(gallery, sent, f"p{ext}")
    assert response.status_code == 201, response.text
    digest = hashlib.sha256(sent).hexdigest()
    served = httpx.get(f"{gallery.url}/photos/{digest}")
    assert served.content == sent  # the hash names what was sent
    assert served.headers["x-content-type-options"] == "nosniff"
    thumb = httpx.get(f"{gallery.url}/thumbs/{digest}").content
    assert cv2.imdecode(np.frombuffer(thumb, np.uint8), cv2.IMREAD_COLOR).shape[1] >= 160


def test_an_exif_thumbnail_inside_a_truncated_jpeg_does_not_pass_for_its_end(gallery, jpeg) -> None:
    """An APP1 segment holding a whole little JPEG (its own end marker) is skipped by its length."""
    import struct

    inner = b"\xff\xd8\xff\xd9"
    app1 = b"\xff\xe1" + struct.pack(">H", 2 + 6 + len(inner)) + b"Exif\x00\x00" + inner
    with_exif = jpeg[:2] + app1 + jpeg[2:]
    assert post(gallery, with_exif).status_code == 201
    response = post(gallery, with_exif[:-400])
    assert response.status_code == 415 and "truncated" in response.json()["detail"]


@pytest.mark.parametrize(
    ("metadata", "status", "message"),
    [
        ('{"a": ' + "[" * 100_000 + "]" * 100_000 + "}", 413, "over the gallery's limit of 65,536"),
        ('{"a": ' + "[" * 30_000 + "]" * 30_000 + "}", 400, "metadata nests deeper than 32 levels"),
        ('{"a": ' + "[" * 33 + "]" * 33 + "}", 400, "metadata nests deeper than 32 levels"),
        ('{"a": "' + "x" * 70_000 + '"}', 413, "over the gallery's limit of 65,536"),
        ('{"a": NaN}', 400, "metadata is not JSON: NaN is not a number JSON allows"),
        ('{"a": 1e400}', 400, "metadata is not JSON: 1e400 is out of range"),
        ('{"a": ' + "1" * 5000 + "}", 400, "metadata is not JSON"),
    ],
    ids=["100000-deep", "30000-deep", "33-deep", "70-KB", "nan", "overflow", "5000-digits"],
)
def test_metadata_is_bounded_and_refused_with_a_reason(gallery, jpeg, metadata, status, message, caplog) -> None:
    response = post(gallery, jpeg, metadata=metadata)
    assert response.status_code == status and message in response.json()["detail"]
    assert "Traceback" not in caplog.text and not [r for r in caplog.records if r.levelname == "ERROR"]
    fine = '{"a": ' + "[" * 31 + '"[{ in a string"' + "]" * 31 + "}"  # brackets in strings do not count
    assert post(gallery, jpeg, metadata=fine).status_code == 201
    assert httpx.get(gallery.url + "/api/photos").status_code == 200


def test_botstage_gallery_on_port_0_serves_on_a_free_port_it_prints(tmp_path) -> None:
    command = [sys.executable, "-m", "botstage.missions.cli", "gallery", "--port", "0", "--dir", str(tmp_path / "g")]
    process = subprocess.Popen(command, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert process.stderr is not None
        line = process.stderr.readline()  # printed once the socket is bound
        url = line.split(" at ", 1)[1].split("/ ", 1)[0]
        port = int(url.rsplit(":", 1)[1])
        assert 0 < port < 65536
        wait_for(lambda: httpx.get(url + "/healthz").status_code == 200)
    finally:
        process.terminate()
        process.communicate(timeout=20)


def test_botstage_gallery_refuses_a_folder_it_cannot_keep_photos_in(tmp_path) -> None:
    index_is_a_folder = tmp_path / "g"
    (index_is_a_folder / "gallery.sqlite").mkdir(parents=True)
    result = subprocess.run(
        [sys.executable, "-m", "botstage.missions.cli", "gallery", "--port", "0", "--dir", str(index_is_a_folder)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 1, result.stderr
    assert f"error: cannot open the gallery in {index_is_a_folder}" in result.stderr
    assert "Traceback" not in result.stderr
