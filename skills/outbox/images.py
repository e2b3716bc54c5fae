"""What kind of image a file is, from its first bytes: the outbox refuses anything else early.

Only the magic numbers are read here (cheap, on the skill's side); the gallery decodes the
whole image before it stores it.
"""

from __future__ import annotations

JPEG_MAGIC = b"\xff\xd8\xff"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
HEAD_BYTES = 8  # enough for both magic numbers
MEDIA_TYPES = {".jpg": "image/jpeg", ".png": "image/png"}


def sniff(head: bytes) -> str | None:
    """The file extension (``.jpg`` or ``.png``) the first bytes announce, or None."""
    if head.startswith(JPEG_MAGIC):
        return ".jpg"
    if head.startswith(PNG_MAGIC):
        return ".png"
    return None
