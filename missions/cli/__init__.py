"""The `botstage` command line: the verb groups' modules assembled into one Typer app.

Each module holds one group of verbs, each verb a thin layer over library calls; this module only
says which verbs there are and in what order `botstage --help` lists them.
"""

from __future__ import annotations

import typer

from missions.cli import backends, chat, gallery, pictures, robots, run
from missions.cli.bench import bench_app
from missions.cli.run import scenario_app
from missions.cli.speech import speech_app

app = typer.Typer(
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_show_locals=False,  # a traceback must never print a secret held in a variable
    help="Orchestrate robots with behaviour trees and hierarchical state machines.",
)
app.add_typer(bench_app, name="bench")
app.add_typer(scenario_app, name="scenario")
app.add_typer(speech_app, name="speech")

app.command()(run.validate)
app.command()(run.schema)
app.command()(run.run)
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


def main() -> None:  # pragma: no cover - console script entry
    app()
