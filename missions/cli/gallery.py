"""`botstage gallery`: the photo gallery the upload skill sends to, served over HTTP (the web set)."""

from __future__ import annotations

from pathlib import Path

import typer

from botstage.missions.cli.common import POSITIVE, TCP_PORT, _fail, _stderr, output_dir


def gallery(
    host: str = typer.Option("127.0.0.1", help="address to listen on (loopback by default)"),
    port: int = typer.Option(8765, help="TCP port, 1-65535 (0: a free one, printed)", callback=TCP_PORT),
    folder: Path = typer.Option(
        Path("gallery"), "--dir", help="where photos and the index are kept", callback=output_dir
    ),
    max_mb: float = typer.Option(20.0, help="largest photo accepted, MB (bigger: 413)", callback=POSITIVE),
    max_mp: float = typer.Option(
        40.0, help="most pixels a photo may have, megapixels (more: 413, refused before decoding)", callback=POSITIVE
    ),
) -> None:
    """Serve the photo gallery the upload skill sends to: POST /photos, the page at /, JSON at /api/photos.

    With $BOTSTAGE_GALLERY_TOKEN set, uploads need `Authorization: Bearer <token>` (else 401).
    """
    import os

    from botstage.missions.gallery.server import GalleryError, serve
    from botstage.missions.serving import is_loopback
    from botstage.skills.outbox.settings import TOKEN_ENV

    token = os.environ.get(TOKEN_ENV) or None
    if not is_loopback(host) and token is None:
        _stderr([f"warning: serving on {host} without a token: anyone who can reach it can upload (set {TOKEN_ENV})"])
    shown = f"[{host}]" if ":" in host else host

    def bound(actual: int) -> None:
        _stderr(
            [
                f"gallery of {folder.resolve()} at http://{shown}:{actual}/ (uploads: POST /photos"
                + (", token required)" if token else ")")
            ]
        )

    limits = {"max_bytes": max(1, int(max_mb * 2**20)), "max_pixels": max(1, int(max_mp * 1e6))}
    try:
        serve(folder, host, port, token=token, bound=bound, **limits)
    except GalleryError as exc:
        raise _fail(f"error: {exc}") from None
    except OSError as exc:
        raise _fail(f"error: cannot serve on {host}:{port}: {exc.strerror or exc}", 2) from None
