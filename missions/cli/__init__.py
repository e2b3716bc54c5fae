"""The `botstage` command line: the verb groups' modules assembled into one Typer app.

Each module holds one group of verbs, each verb a thin layer over library calls; this module only
says which verbs there are and in what order `botstage --help` lists them.
"""

from __future__ import annotations

import contextlib
import os
import signal
from pathlib import Path

import typer
from botstage.missions.cli import (
    backends,
    btcpp,
    certs,
    chat,
    distributed,
    gallery,
    maps,
    monitor,
    pictures,
    robots,
    run,
)
from botstage.missions.cli.bench import bench_app
from botstage.missions.cli.run import scenario_app
from botstage.missions.cli.serve import serve_app
from botstage.missions.cli.speech import speech_app
from botstage.robots import limits

app = typer.Typer(
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_show_locals=False,  # a traceback must never print a secret held in a variable
    help="Orchestrate robots with behaviour trees and hierarchical state machines.",
)


@app.callback()
def _options(
    include_dir: list[Path] = typer.Option(
        [],
        "--include-dir",
        metavar="DIR",
        help="a folder missions may include files from besides their own folder tree and the "
        "built-in library (repeatable; the same as adding it to BOTSTAGE_INCLUDE_PATH)",
    ),
) -> None:
    """Orchestrate robots with behaviour trees and hierarchical state machines."""
    _interruptible()
    for folder in include_dir:
        if not folder.is_dir():
            raise typer.BadParameter(f"{folder} is not a folder", param_hint="'--include-dir'")
    if include_dir:  # through the environment, so scenario runs in child processes see it too
        extra = [str(folder.resolve()) for folder in include_dir]
        current = os.environ.get(limits.INCLUDE_PATH_ENV, "")
        os.environ[limits.INCLUDE_PATH_ENV] = os.pathsep.join([*extra, *([current] if current else [])])


app.add_typer(bench_app, name="bench")
app.add_typer(scenario_app, name="scenario")
app.add_typer(speech_app, name="speech")
app.add_typer(serve_app, name="serve")
serve_app.command("process")(distributed.process)

app.command()(run.validate)
app.command()(run.schema)
app.command()(run.run)
app.command("import")(btcpp.import_)
app.command("export")(btcpp.export)
app.command()(monitor.monitor)
app.command()(gallery.order)
app.command()(pictures.tree)
app.command()(pictures.machine)
app.command("test")(run.test_scenarios)
app.command()(robots.skills)
app.command()(robots.nodes)
app.command()(chat.chat)
app.command()(gallery.gallery)
app.command()(robots.emulate)
app.command()(robots.teleop)
app.command()(backends.backends)
app.command()(maps.places)
app.command()(distributed.up)
app.command()(certs.certs)


def main() -> None:  # pragma: no cover - console script entry
    app()


def _interruptible() -> None:
    """Let Ctrl-C and SIGINT stop botstage even if it was started with SIGINT ignored.

    A shell without job control (a script, a CI step) starts background commands with SIGINT
    ignored, and Python then keeps it ignored: `botstage serve ... &` could not be stopped by
    `kill -INT`, and `botstage up`'s children, which it stops with SIGINT, would run on. Every
    long-running command here documents Ctrl-C as its stop, so the default comes back.
    """
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        with contextlib.suppress(ValueError):  # not the main thread (an in-process test runner)
            signal.signal(signal.SIGINT, signal.default_int_handler)
