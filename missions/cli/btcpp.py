"""Verbs for BehaviorTree.CPP v4 XML: `botstage import` writes the mission a tree file describes,
`botstage export` writes a mission (or a run, for Groot2) as XML."""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from botstage.missions.cli.common import _fail, console, input_file, os_problem, output_file


def import_(
    tree: Path = typer.Argument(..., help="a BehaviorTree.CPP v4 XML file", callback=input_file),
    output: Path | None = typer.Option(
        None, "-o", "--output", help="the mission YAML to write (default: standard output)", callback=output_file
    ),
    robot: str | None = typer.Option(None, help="the robot profile the mission names (default: none, fill it in)"),
    world: str | None = typer.Option(None, help="the world (map) the mission names (default: none, fill it in)"),
) -> None:
    """Write the mission a BehaviorTree.CPP v4 XML file describes; errors as file:line:col, exit 1."""
    from botstage.behaviors.btcpp.xml_format import load_xml
    from botstage.missions.api.mission import dump_yaml

    loaded = load_xml(tree)
    if loaded.data is None:
        raise _fail([str(problem) for problem in loaded.problems])
    data = dict(loaded.data)
    placed = {field: value for field, value in (("robot", robot), ("world", world)) if value is not None}
    text = dump_yaml({"name": data.pop("name"), **placed, **data})
    if output is None:
        sys.stdout.write(text)
        return
    try:
        output.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise _fail(f"error: {os_problem(exc)}") from None
    console.print(f"wrote {output}", highlight=False, soft_wrap=True)


# -- export: `botstage export MISSION.yaml -f btcpp`, `botstage export RUN_FOLDER -f btlog` ----------

EXPORT_FORMATS = ("btcpp", "btlog")


def export(
    source: Path = typer.Argument(..., help="a mission (-f btcpp) or a run folder, runs/<mission>-<time>/ (-f btlog)"),
    fmt: str = typer.Option(
        ..., "-f", "--format", help="btcpp: BehaviorTree.CPP v4 XML for Groot2; btlog: Groot2's replay file of a run"
    ),
    output: Path | None = typer.Option(
        None, "-o", "--output", help="the file to write (btcpp default: standard output; btlog: RUN_FOLDER.btlog)"
    ),
) -> None:
    """Write a mission as BehaviorTree.CPP v4 XML (Groot2 opens it; `botstage run` and `import` read
    it back), or a finished run as Groot2's .btlog replay file; errors as file:line:col, exit 1."""
    if fmt not in EXPORT_FORMATS:
        raise _fail(f"error: --format {fmt!r}: expected one of {', '.join(EXPORT_FORMATS)}", 2)
    if fmt == "btlog":
        _export_btlog(source, output)
        return
    from botstage.behaviors.btcpp.export import ExportError, export_loaded
    from botstage.missions.check import check

    if source.is_dir():
        raise _fail(f"error: {source} is a folder: -f btcpp exports a mission file (-f btlog a run folder)", 2)
    checked = check(source)  # nothing half-valid is written: the mission is checked as `run` would
    if not checked.ok:
        raise _fail([str(problem) for problem in checked.problems])
    try:
        text = export_loaded(checked.loaded)
    except ExportError as exc:
        raise _fail([str(problem) for problem in exc.problems]) from None
    if output is None:
        sys.stdout.write(text)
        return
    try:
        output.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise _fail(f"error: {os_problem(exc)}") from None
    console.print(f"wrote {output}", highlight=False, soft_wrap=True)


def _export_btlog(folder: Path, output: Path | None) -> None:
    from botstage.missions.groot2.btlog import BtlogError, write_btlog

    if not folder.is_dir():
        raise _fail(f"error: {folder} is not a run folder: -f btlog exports a finished run (runs/<mission>-<time>/)", 2)
    target = output if output is not None else folder.with_name(folder.resolve().name + ".btlog")
    try:
        written = write_btlog(folder, target)
    except BtlogError as exc:
        raise _fail(f"error: {exc}") from None
    except OSError as exc:
        raise _fail(f"error: {os_problem(exc)}") from None
    console.print(f"wrote {written}", highlight=False, soft_wrap=True)
