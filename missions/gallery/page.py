"""The gallery page: every photo, newest first, with its metadata. Plain HTML, no scripts.

Names and metadata come from whoever uploaded: everything is escaped.
"""

from __future__ import annotations

import json
from html import escape

from botstage.missions.gallery.store import Photo

_STYLE = """
body{font-family:system-ui,sans-serif;margin:2rem;background:#fafafa;color:#222}
h1{font-weight:600}
.grid{display:grid;grid-template-columns:repeat(auto-fill,minmax(240px,1fr));gap:1rem}
figure{margin:0;background:#fff;border:1px solid #ddd;border-radius:6px;padding:.5rem}
figure img{width:100%;height:auto;display:block;border-radius:4px}
figcaption{font-size:.85rem;margin-top:.4rem;overflow-wrap:anywhere}
dl{margin:.3rem 0 0;display:grid;grid-template-columns:auto 1fr;gap:0 .5rem}
dt{color:#666}dd{margin:0}
"""


def _value(value: object) -> str:
    return value if isinstance(value, str) else json.dumps(value, ensure_ascii=False)


def _when(iso: str) -> str:
    """``2026-11-22T02:51:38.831+00:00`` as ``2026-11-22 02:51:38 UTC``."""
    return f"{iso[:19].replace('T', ' ')} UTC" if iso.endswith("+00:00") else iso


def render_page(photos: list[Photo], title: str = "botstage gallery") -> str:
    figures = []
    for photo in photos:
        rows = "".join(
            f"<dt>{escape(str(key))}</dt><dd>{escape(_value(value))}</dd>" for key, value in photo.metadata.items()
        )
        figures.append(
            f'<figure><a href="/photos/{photo.hash}"><img src="/thumbs/{photo.hash}" alt="{escape(photo.name)}" '
            f'loading="lazy"></a><figcaption><strong>{escape(photo.name)}</strong> '
            f"({photo.size / 2**20:.2f} MB, {escape(_when(photo.received_at))})"
            f"{f'<dl>{rows}</dl>' if rows else ''}</figcaption></figure>"
        )
    count = f"{len(photos)} photo{'' if len(photos) == 1 else 's'}"
    body = f'<div class="grid">{"".join(figures)}</div>' if figures else "<p>No photos yet.</p>"
    return (
        f'<!doctype html><html lang="en"><head><meta charset="utf-8"><title>{escape(title)}</title>'
        f'<meta name="viewport" content="width=device-width,initial-scale=1"><style>{_STYLE}</style></head>'
        f'<body><h1>{escape(title)}</h1><p>{count} · <a href="/api/photos">JSON</a></p>{body}</body></html>\n'
    )
