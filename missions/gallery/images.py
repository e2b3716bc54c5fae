"""Is an upload really a JPEG or PNG, and a sane size? Walked, measured, then decoded with OpenCV,
and a thumbnail made on the way.

A renamed text file, a truncated photo or random bytes are refused here with the reason, before
anything is stored. The image's structure is walked first (JPEG markers and segments up to the
end-of-image marker, PNG chunks up to IEND): that finds where the image ends, so bytes after
it (a camera's trailer, a motion photo's video) are left alone rather than taken for damage,
and it reads the width and height from the header, so a decompression bomb (a small file of
huge dimensions) is refused before a single pixel is decoded. Decoding at 1/8 scale (libjpeg's
DCT scaling) still reads the whole compressed stream, so a damaged file fails, and costs a
fraction of a full decode.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import cv2
import numpy as np

from botstage.skills.outbox.images import sniff

THUMB_WIDTH = 320
DEFAULT_MAX_PIXELS = 40_000_000  # 40 megapixels: a 3-byte decode of at most 120 MB
_SCALES = ((8, cv2.IMREAD_REDUCED_COLOR_8), (4, cv2.IMREAD_REDUCED_COLOR_4), (2, cv2.IMREAD_REDUCED_COLOR_2))
# start-of-frame markers: C0-CF but DHT (C4), JPG (C8) and DAC (CC)
_SOF = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}
_STANDALONE = frozenset({0x01, *range(0xD0, 0xD8)})  # TEM and RSTn: no length follows
_PNG_SIGNATURE = 8


class BadImage(ValueError):
    """Not a whole JPEG or PNG image; the message says why."""


class ImageTooLarge(BadImage):
    """A whole image, but of more pixels than the gallery decodes."""


@dataclass(frozen=True)
class Layout:
    """What the header says: the size, and where the image ends (bytes after it are not image)."""

    ext: str
    width: int
    height: int
    end: int


def _jpeg_scan_end(data: bytes, pos: int) -> int:
    """Where the entropy-coded data that starts at ``pos`` ends: at the next real marker."""
    while True:
        found = data.find(b"\xff", pos)
        if found < 0 or found + 1 >= len(data):
            raise BadImage("the JPEG is truncated (no end-of-image marker)")
        following = data[found + 1]
        if following == 0x00 or 0xD0 <= following <= 0xD7:  # a stuffed 0xFF, or a restart marker
            pos = found + 2
            continue
        return found


def jpeg_layout(data: bytes) -> Layout:
    """Walk a JPEG's markers from SOI to EOI; its frame size and its end; raises ``BadImage``."""
    size: tuple[int, int] | None = None
    pos = 2  # after SOI
    while True:
        if pos >= len(data):
            raise BadImage("the JPEG is truncated (no end-of-image marker)")
        if data[pos] != 0xFF:
            raise BadImage(f"the JPEG is damaged (no marker at byte {pos})")
        while pos < len(data) and data[pos] == 0xFF:  # fill bytes
            pos += 1
        if pos >= len(data):
            raise BadImage("the JPEG is truncated (no end-of-image marker)")
        marker = data[pos]
        pos += 1
        if marker == 0xD9:  # EOI
            break
        if marker in _STANDALONE:
            continue
        if pos + 2 > len(data):
            raise BadImage("the JPEG is truncated (no end-of-image marker)")
        (length,) = struct.unpack_from(">H", data, pos)
        if length < 2 or pos + length > len(data):
            raise BadImage(f"the JPEG is damaged or truncated (a segment at byte {pos - 2} runs past the end)")
        if marker in _SOF and size is None:
            if length < 7:
                raise BadImage("the JPEG is damaged (a frame header too short)")
            height, width = struct.unpack_from(">HH", data, pos + 3)
            size = (width, height)
        pos += length
        if marker == 0xDA:  # SOS: the compressed data follows
            pos = _jpeg_scan_end(data, pos)
    if size is None:
        raise BadImage("the JPG does not decode (no frame header)")
    return Layout(".jpg", size[0], size[1], pos)


def png_layout(data: bytes) -> Layout:
    """Walk a PNG's chunks from IHDR to IEND; its size and its end; raises ``BadImage``."""
    if len(data) < _PNG_SIGNATURE + 8 + 13 or data[_PNG_SIGNATURE + 4 : _PNG_SIGNATURE + 8] != b"IHDR":
        raise BadImage("the PNG is damaged (no IHDR chunk first)")
    width, height = struct.unpack_from(">II", data, _PNG_SIGNATURE + 8)
    pos = _PNG_SIGNATURE
    while True:
        if pos + 8 > len(data):
            raise BadImage("the PNG is truncated (no IEND chunk)")
        length, kind = struct.unpack_from(">I4s", data, pos)
        end = pos + 12 + length
        if end > len(data):
            raise BadImage("the PNG is truncated (no IEND chunk)")
        pos = end
        if kind == b"IEND":
            return Layout(".png", width, height, pos)


def layout(data: bytes) -> Layout:
    """The image's kind, size and end, from its bytes; raises ``BadImage``."""
    ext = sniff(data[:8])
    if ext is None:
        raise BadImage("not a JPEG or PNG image (its first bytes are neither)")
    found = jpeg_layout(data) if ext == ".jpg" else png_layout(data)
    if found.width == 0 or found.height == 0:
        raise BadImage(f"the {ext[1:].upper()} has no pixels ({found.width}x{found.height})")
    return found


def _decode(image: bytes, ext: str) -> np.ndarray:
    buffer = np.frombuffer(image, np.uint8)
    decoded = None
    for _scale, flag in _SCALES:  # the smallest decode that still makes a useful thumbnail
        decoded = cv2.imdecode(buffer, flag)
        if decoded is None or decoded.shape[1] >= THUMB_WIDTH // 2:
            break
    else:
        decoded = cv2.imdecode(buffer, cv2.IMREAD_COLOR)
    if decoded is None or decoded.size == 0:
        raise BadImage(f"the {ext[1:].upper()} does not decode")
    return decoded


def check_image(data: bytes, max_pixels: int = DEFAULT_MAX_PIXELS) -> tuple[str, bytes]:
    """The image's extension and a JPEG thumbnail; raises ``BadImage`` (``ImageTooLarge``).

    Bytes after the image's end are not decoded; the caller keeps the upload as sent (its hash
    is the photo's identity).
    """
    found = layout(data)
    pixels = found.width * found.height
    if pixels > max_pixels:
        raise ImageTooLarge(
            f"the image is {found.width}x{found.height} pixels ({pixels / 1e6:.1f} MP), over the gallery's "
            f"limit of {max_pixels / 1e6:g} MP"
        )
    try:
        image = _decode(data[: found.end], found.ext)
        if image.shape[1] > THUMB_WIDTH:
            height = max(1, round(image.shape[0] * THUMB_WIDTH / image.shape[1]))
            image = cv2.resize(image, (THUMB_WIDTH, height), interpolation=cv2.INTER_AREA)
        ok, thumb = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 80])
    except cv2.error as exc:  # OpenCV refuses what its codecs cannot take: a bad image, said so
        raise BadImage(f"the {found.ext[1:].upper()} does not decode ({str(exc).strip().splitlines()[-1]})") from None
    if not ok:
        raise BadImage("the image decodes but cannot be re-encoded")
    return found.ext, thumb.tobytes()
