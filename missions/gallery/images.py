"""Is an upload really a JPEG or PNG? Decoded with OpenCV, and a thumbnail made on the way.

A renamed text file, a truncated photo or random bytes are refused here with the reason, before
anything is stored. Decoding at 1/8 scale (libjpeg's DCT scaling) still reads the whole
compressed stream, so a damaged file fails, and costs a fraction of a full decode.
"""

from __future__ import annotations

import cv2
import numpy as np

from skills.outbox.images import sniff

THUMB_WIDTH = 320
_JPEG_END = b"\xff\xd9"
_PNG_END = b"IEND\xaeB`\x82"
_SCALES = ((8, cv2.IMREAD_REDUCED_COLOR_8), (4, cv2.IMREAD_REDUCED_COLOR_4), (2, cv2.IMREAD_REDUCED_COLOR_2))


class BadImage(ValueError):
    """Not a whole JPEG or PNG image; the message says why."""


def check_image(data: bytes) -> tuple[str, bytes]:
    """The image's extension and a JPEG thumbnail; raises ``BadImage``."""
    ext = sniff(data[:8])
    if ext is None:
        raise BadImage("not a JPEG or PNG image (its first bytes are neither)")
    if ext == ".jpg" and not data.rstrip(b"\x00").endswith(_JPEG_END):
        raise BadImage("the JPEG is truncated (no end-of-image marker)")
    if ext == ".png" and not data.endswith(_PNG_END):
        raise BadImage("the PNG is truncated (no IEND chunk)")
    buffer = np.frombuffer(data, np.uint8)
    image = None
    for _scale, flag in _SCALES:  # the smallest decode that still makes a useful thumbnail
        image = cv2.imdecode(buffer, flag)
        if image is None or image.shape[1] >= THUMB_WIDTH // 2:
            break
    else:
        image = cv2.imdecode(buffer, cv2.IMREAD_COLOR)
    if image is None or image.size == 0:
        raise BadImage(f"the {ext[1:].upper()} does not decode")
    if image.shape[1] > THUMB_WIDTH:
        height = max(1, round(image.shape[0] * THUMB_WIDTH / image.shape[1]))
        image = cv2.resize(image, (THUMB_WIDTH, height), interpolation=cv2.INTER_AREA)
    ok, thumb = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, 80])
    if not ok:
        raise BadImage("the image decodes but cannot be re-encoded")
    return ext, thumb.tobytes()
