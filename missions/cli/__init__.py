"""The `botstage` command line: one module per verb, assembled here into one Typer app.

This module only says which verbs the core has and in what order `botstage --help` lists them;
``verbs.LazyGroup`` imports a verb's module when that verb runs or shows its help, so listing the
verbs or running `validate` imports nothing a verb it does not run needs.

Verbs of a plug-in set are registered by that set in the ``botstage.commands`` entry-point group
(name = ``module:attr [extra]``) and loaded exactly as a third party's are; without the set's
extra installed, the verb says what to `pip install` instead of failing with a traceback. Which
verb is whose, decided by what it imports:

- core: validate, schema, run, test, scenario, tree, machine, skills, nodes, backends, places,
  order (a file written into a run folder's inbox), teleop (the keyboard on the simulator needs
  no set; its gesture glove and ``--connect`` paths import the hardware and ros2 sets when used).
  ``run --monitor`` and ``run --groot2`` are options of the core verb that start a set's server
  when given.
- web: monitor, gallery (FastAPI, uvicorn).
- ros2: serve (robot, process), up, certs (Zenoh, rosbags, cryptography).
- hardware: emulate (pyserial, the boards' emulators on a pty).
- speech: speech (pocketsphinx, onnxruntime). chat: chat (python-aiml).
- btcpp: import, export (BehaviorTree.CPP XML and Groot2's btlog).

Benchmarks and the speech-model trainer are not verbs: they live in the repository's
``tests/bench`` (``python -m tests.bench NAME`` from a checkout) and are not in the wheel.
"""

from __future__ import annotations

import contextlib
import os
import signal
from pathlib import Path

import typer

from botstage.missions.cli.verbs import LazyGroup

CLI = "botstage.missions.cli"


class Verbs(LazyGroup):
    """The core's verbs, as `botstage --help` lists them (plug-in sets' verbs follow, by name)."""

    core = {
        "validate": f"{CLI}.validate:validate",
        "schema": f"{CLI}.schema:schema",
        "run": f"{CLI}.run:run",
        "test": f"{CLI}.test:test_scenarios",
        "scenario": f"{CLI}.scenario:scenario_app",
        "tree": f"{CLI}.tree:tree",
        "machine": f"{CLI}.machine:machine",
        "skills": f"{CLI}.skills:skills",
        "nodes": f"{CLI}.nodes:nodes",
        "backends": f"{CLI}.backends:backends",
        "places": f"{CLI}.places:places",
        "order": f"{CLI}.order:order",
        "teleop": f"{CLI}.teleop:teleop",
    }


app = typer.Typer(
    cls=Verbs,
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
        from botstage.robots import limits

        extra = [str(folder.resolve()) for folder in include_dir]
        current = os.environ.get(limits.INCLUDE_PATH_ENV, "")
        os.environ[limits.INCLUDE_PATH_ENV] = os.pathsep.join([*extra, *([current] if current else [])])


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
