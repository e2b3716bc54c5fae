"""`botstage order TABLE ITEM`: an order given to a running delivery mission through its run folder."""

from __future__ import annotations

from pathlib import Path

import typer

from botstage.missions.cli.common import _fail, console


def order(
    table: str = typer.Argument(..., help="the table to serve, e.g. table_3"),
    item: str = typer.Argument(..., help="what to bring, e.g. 'tomato soup'"),
    run_folder: Path | None = typer.Option(None, "--run", help="the run folder (default: the newest running mission)"),
    runs: Path = typer.Option(Path("runs"), help="where to look for running missions"),
) -> None:
    """Give a running delivery mission an order (through its run folder's inbox; see docs/robots/chefbot.md)."""
    from botstage.missions.orders import find_inbox, post_order
    from botstage.skills.delivery.inbox import OrderError

    try:
        inbox = find_inbox(run_folder, runs)
        path = post_order(inbox, table, item)
    except OrderError as exc:
        raise _fail(f"error: {exc}", 2) from None
    except OSError as exc:
        raise _fail(f"error: cannot write the order: {exc}", 2) from None
    console.print(f"order for {table}: {' '.join(item.split())} -> {path}", highlight=False, soft_wrap=True)
