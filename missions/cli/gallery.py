"""Verbs of the photo gallery and the delivery robot's orders: serve the gallery, give an order."""

from __future__ import annotations

from pathlib import Path

import typer

from missions.cli.common import _fail, _stderr, console


def gallery(
    host: str = typer.Option("127.0.0.1", help="address to listen on (loopback by default)"),
    port: int = typer.Option(8765, help="TCP port"),
    folder: Path = typer.Option(Path("gallery"), "--dir", help="where photos and the index are kept"),
    max_mb: float = typer.Option(20.0, help="largest photo accepted, MB (bigger: 413)"),
) -> None:
    """Serve the photo gallery the upload skill sends to: POST /photos, the page at /, JSON at /api/photos.

    With $BOTSTAGE_GALLERY_TOKEN set, uploads need `Authorization: Bearer <token>` (else 401).
    """
    import os

    from missions.gallery.server import is_loopback, serve
    from skills.outbox.settings import TOKEN_ENV

    token = os.environ.get(TOKEN_ENV) or None
    if not is_loopback(host) and token is None:
        _stderr([f"warning: serving on {host} without a token: anyone who can reach it can upload (set {TOKEN_ENV})"])
    if max_mb <= 0:
        raise _fail("error: --max-mb must be positive", 2)
    shown = f"[{host}]" if ":" in host else host
    _stderr(
        [
            f"gallery of {folder.resolve()} at http://{shown}:{port}/ (uploads: POST /photos"
            + (", token required)" if token else ")")
        ]
    )
    try:
        serve(folder, host, port, token=token, max_bytes=int(max_mb * 2**20))
    except OSError as exc:
        raise _fail(f"error: cannot serve on {host}:{port}: {exc.strerror or exc}", 2) from None


def order(
    table: str = typer.Argument(..., help="the table to serve, e.g. table_3"),
    item: str = typer.Argument(..., help="what to bring, e.g. 'tomato soup'"),
    run_folder: Path | None = typer.Option(None, "--run", help="the run folder (default: the newest running mission)"),
    runs: Path = typer.Option(Path("runs"), help="where to look for running missions"),
) -> None:
    """Give a running delivery mission an order (through its run folder's inbox; see the README)."""
    from missions.orders import find_inbox, post_order
    from skills.delivery.inbox import OrderError

    try:
        inbox = find_inbox(run_folder, runs)
        path = post_order(inbox, table, item)
    except OrderError as exc:
        raise _fail(f"error: {exc}", 2) from None
    except OSError as exc:
        raise _fail(f"error: cannot write the order: {exc}", 2) from None
    console.print(f"order for {table}: {' '.join(item.split())} -> {path}", highlight=False, soft_wrap=True)
