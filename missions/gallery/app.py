"""The gallery's HTTP interface (FastAPI): upload, list, photos, thumbnails and the page.

``POST /photos`` takes a multipart form: ``file`` (the photo), optional ``hash`` and header
``Idempotency-Key`` (its SHA-256, checked against the bytes received), ``metadata`` (a JSON
object, at most 64 KB and 32 levels deep) and ``name``. Answers: 201 stored, 200 already there
(``"duplicate": true``), 400 bad form, bad metadata or a hash that does not match, 401 missing or
wrong token, 413 too large (bytes, pixels or metadata), 415 not a whole JPEG or PNG, 422 no
file. Bytes after the image's end are kept as sent (the hash names what was sent). Reading is
open: ``GET /`` (the page), ``/api/photos`` (JSON), ``/photos/{hash}``, ``/thumbs/{hash}``, ``/healthz``.

A wrong token or an oversized body is refused by ``UploadGuard`` before the form is parsed.
The guard reads the rest of the body (up to a cap) before it answers, because a server that
answers and hangs up while the client is still sending makes the client see a broken
connection instead of the 401 or 413, and an outbox would take that for a network fault and
retry forever.
"""

from __future__ import annotations

import hashlib
import hmac
import json
import re
from collections.abc import Awaitable, Callable, MutableMapping
from pathlib import Path, PurePosixPath, PureWindowsPath
from typing import Annotated, Any

from fastapi import FastAPI, File, Form, Header, HTTPException, UploadFile
from fastapi.responses import FileResponse, HTMLResponse, JSONResponse

from botstage.missions.gallery.images import DEFAULT_MAX_PIXELS, BadImage, ImageTooLarge, check_image
from botstage.missions.gallery.metadata import BadMetadata, parse_metadata
from botstage.missions.gallery.page import render_page
from botstage.missions.gallery.store import GalleryStore
from botstage.skills.outbox.images import MEDIA_TYPES

DEFAULT_MAX_BYTES = 20 * 2**20
FORM_SLACK = 256 * 1024  # multipart boundaries, part headers and the metadata field
DRAIN_FACTOR = 4  # read at most this many times the limit of a refused body before hanging up
_HASH = re.compile(r"[0-9a-f]{64}")
_NOSNIFF = {"X-Content-Type-Options": "nosniff"}  # a photo is shown as an image, whatever follows its end


def _size(n: int) -> str:
    return f"{n / 2**20:g} MB" if n >= 2**20 else f"{n:,} bytes"


Scope = MutableMapping[str, Any]
Message = MutableMapping[str, Any]
Receive = Callable[[], Awaitable[Message]]
Send = Callable[[Message], Awaitable[None]]


async def _drain(receive: Receive, cap: int) -> None:
    """Read and drop the rest of a request body, up to ``cap`` bytes."""
    read = 0
    while read <= cap:
        message = await receive()
        if message["type"] != "http.request":
            return
        read += len(message.get("body", b""))
        if not message.get("more_body", False):
            return


async def _refuse(send: Send, status: int, detail: str, headers: list[tuple[bytes, bytes]] | None = None) -> None:
    body = json.dumps({"detail": detail}).encode()
    await send(
        {
            "type": "http.response.start",
            "status": status,
            "headers": [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode())]
            + (headers or []),
        }
    )
    await send({"type": "http.response.body", "body": body})


class UploadGuard:
    """ASGI middleware: a POST needs the token (when the gallery has one) and must fit the limit."""

    def __init__(self, app: Any, token: str | None, max_bytes: int) -> None:
        self.app = app
        self._expected = f"Bearer {token}".encode() if token else None
        self.max_bytes = max_bytes
        self.limit = max_bytes + FORM_SLACK

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["method"] != "POST":
            await self.app(scope, receive, send)
            return
        headers = {key.lower(): value for key, value in scope["headers"]}
        cap = self.limit * DRAIN_FACTOR
        if self._expected is not None and not hmac.compare_digest(headers.get(b"authorization", b""), self._expected):
            await _drain(receive, cap)
            await _refuse(send, 401, "missing or wrong token", [(b"www-authenticate", b"Bearer")])
            return
        length = headers.get(b"content-length")
        if length is not None and (not length.isdigit() or int(length) > self.limit):
            if not length.isdigit():
                await _refuse(send, 400, "bad Content-Length")
                return
            await _drain(receive, cap)
            await _refuse(send, 413, f"the upload is over the gallery's limit of {_size(self.max_bytes)}")
            return
        received = 0

        async def counted() -> Message:
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > self.limit:
                    if message.get("more_body", False):
                        await _drain(receive, cap)
                    raise HTTPException(413, f"the upload is over the gallery's limit of {_size(self.max_bytes)}")
            return message

        await self.app(scope, counted, send)


def _clean_name(name: str | None, fallback: str) -> str:
    """A display name: the last path component of what the client said, at most 255 characters."""
    if not name:
        return fallback
    base = PureWindowsPath(PurePosixPath(name).name).name.strip()
    return base[:255] or fallback


def create_app(
    folder: str | Path,
    *,
    token: str | None = None,
    max_bytes: int = DEFAULT_MAX_BYTES,
    max_pixels: int = DEFAULT_MAX_PIXELS,
    title: str = "botstage gallery",
) -> FastAPI:
    """The gallery over ``folder`` (created if needed); ``token`` protects uploads; an image of more
    than ``max_pixels`` is refused from its header, before it is decoded."""
    store = GalleryStore(folder)
    app = FastAPI(title=title, docs_url=None, redoc_url=None, openapi_url=None)
    app.state.store = store
    app.add_middleware(UploadGuard, token=token, max_bytes=max_bytes)

    @app.post("/photos")
    def upload(
        file: Annotated[UploadFile, File(description="the photo: JPEG or PNG")],
        hash: Annotated[str | None, Form(description="SHA-256 of the photo, hex")] = None,
        metadata: Annotated[str, Form(description="a JSON object")] = "{}",
        name: Annotated[str | None, Form()] = None,
        idempotency_key: Annotated[str | None, Header()] = None,
    ) -> JSONResponse:
        data = file.file.read(max_bytes + 1)
        if len(data) > max_bytes:
            raise HTTPException(413, f"the photo is over the gallery's limit of {_size(max_bytes)}")
        digest = hashlib.sha256(data).hexdigest()
        for field, claimed in (("hash", hash), ("Idempotency-Key", idempotency_key)):
            if claimed is not None and claimed.strip().lower() != digest:
                raise HTTPException(
                    400, f"the photo's bytes do not match its {field} (damaged on the way?): got sha256 {digest}"
                )
        try:
            meta = parse_metadata(metadata)
        except BadMetadata as error:
            raise HTTPException(error.status, str(error)) from None
        try:
            ext, thumb = check_image(data, max_pixels)
        except ImageTooLarge as error:
            raise HTTPException(413, str(error)) from None
        except BadImage as error:
            raise HTTPException(415, str(error)) from None
        photo, created = store.add(digest, data, ext, thumb, _clean_name(name or file.filename, digest[:12]), meta)
        body = {"duplicate": not created, **photo.public()}
        return JSONResponse(body, status_code=201 if created else 200, headers={"Location": f"/photos/{digest}"})

    def _photo(photo_hash: str) -> Any:
        photo = store.get(photo_hash) if _HASH.fullmatch(photo_hash) else None
        if photo is None:
            raise HTTPException(404, "no such photo")
        return photo

    @app.get("/photos/{photo_hash}")
    def photo_file(photo_hash: str) -> FileResponse:
        photo = _photo(photo_hash)
        return FileResponse(
            store.photos / photo.file, media_type=MEDIA_TYPES[Path(photo.file).suffix], headers=_NOSNIFF
        )

    @app.get("/thumbs/{photo_hash}")
    def thumbnail(photo_hash: str) -> FileResponse:
        _photo(photo_hash)
        return FileResponse(store.thumbs / f"{photo_hash}.jpg", media_type="image/jpeg", headers=_NOSNIFF)

    @app.get("/api/photos")
    def photos() -> dict[str, Any]:
        listed = store.list()
        return {"count": len(listed), "photos": [p.public() for p in listed]}

    @app.get("/", response_class=HTMLResponse)
    def page() -> str:
        return render_page(store.list(), title)

    @app.get("/healthz")
    def health() -> dict[str, Any]:
        return {"ok": True, "photos": store.count()}

    return app
