"""`botstage monitor SOURCE...`: finished runs and other processes' live monitors in one page (the web set)."""

from __future__ import annotations

from pathlib import Path

import typer

from botstage.missions.cli.common import _fail, console
from botstage.missions.cli.live import HOST_HELP


def monitor(
    sources: list[str] = typer.Argument(
        ...,
        help="run folders (runs/<mission>-<time>/) and live monitors' addresses (http://HOST:PORT)",
        metavar="SOURCE...",
    ),
    host: str = typer.Option("127.0.0.1", help=HOST_HELP),
    port: int = typer.Option(8470, help="port to listen on (0: a free one)", min=0, max=65535),
) -> None:
    """Open finished runs and live monitors: one run folder shows its run with a scrubber through its
    ticks (the tree at tick N is what `botstage tree --trace … --at N` prints); several sources
    (folders, and other processes' live monitors by their address) share one page, an overview
    of them all with each one's full monitor a click away. Ctrl-C stops it."""
    from botstage.missions.monitor.replay import RunFolderError, load_run
    from botstage.missions.monitor.server import MonitorError, create_app, start_monitor, start_overview, token_for
    from botstage.missions.monitor.sources import Source, remote_source, source_name

    try:
        token = token_for(host)
        if len(sources) == 1 and not _is_address(sources[0]):
            run = load_run(Path(sources[0]))
            running = start_monitor(run.hub, host=host, port=port, run=run, token=token)
            shown = f"{run.last + 1} ticks"
        else:
            found: list[Source] = []
            for text in sources:
                taken = [source.name for source in found]
                if _is_address(text):
                    found.append(remote_source(text, taken, token))
                else:
                    run = load_run(Path(text))
                    app = create_app(run.hub, token=token, run=run)
                    found.append(Source(source_name(Path(text).resolve().name, taken), "finished", app, text))
            running = start_overview(found, host=host, port=port, token=token)
            shown = f"{len(found)} runs"
    except (RunFolderError, MonitorError, ValueError) as exc:
        raise _fail(f"error: {exc}", 1) from None
    console.print(f"monitor: {running.url}/  ({shown}; Ctrl-C stops)", highlight=False, soft_wrap=True)
    try:
        while running.thread.is_alive():
            running.thread.join(0.5)
    except KeyboardInterrupt:
        pass
    finally:
        running.stop()


def _is_address(text: str) -> bool:
    return text.startswith(("http://", "https://"))
