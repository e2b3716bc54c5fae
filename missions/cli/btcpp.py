"""Verbs for BehaviorTree.CPP v4 XML: `botstage import` writes the mission a tree file describes;
`botstage run tree.xml --robot R --world W` runs one directly (see ``runner_for``)."""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import typer

from botstage.missions.cli.common import _fail, _stderr, console, input_file, os_problem, output_file


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


def blackboard_values(assignments: list[str]) -> dict[str, Any]:
    """``--set KEY=VALUE`` options as initial blackboard values, each VALUE read as YAML
    (``exhibit_a`` a string, ``[2.0, 3.5]`` a list, ``4`` a number); a bad one is a usage error."""
    import yaml

    values: dict[str, Any] = {}
    for text in assignments:
        key, sep, raw = text.partition("=")
        if not sep or not key.strip():
            raise _fail(f"error: --set {text!r}: expected KEY=VALUE, e.g. --set goal=exhibit_a", 2)
        try:
            values[key.strip()] = yaml.safe_load(raw) if raw.strip() else ""
        except yaml.YAMLError as exc:
            raise _fail(f"error: --set {text!r}: the value is not YAML: {exc}", 2) from None
    return values


def runner_for(robot: str | None, world: str | None, values: dict[str, Any] | None = None) -> Callable[..., Any]:
    """How `run` runs a mission file: as it is, or, with ``--robot``/``--world`` (a tree file
    names neither) or ``--set`` values, as a mission with them set: checked first (problems at
    the file's lines), then written to the run folder as mission.yaml and run from there."""
    from botstage.missions.runner import run

    if robot is None and world is None and not values:
        return run

    from botstage.missions.api.mission import Mission
    from botstage.robots.gridmap import known_maps, map_path
    from botstage.robots.profile import known_profiles, profile_path

    # found from the working directory, as paths on a command line are; a bad one is a usage error
    for option, value, find, shipped, noun in (
        ("--robot", robot, profile_path, known_profiles, "robot profile"),
        ("--world", world, map_path, known_maps, "world"),
    ):
        if value is not None and find(value, Path.cwd()) is None:
            raise _fail(f"error: {option}: unknown {noun} {value!r} (shipped: {', '.join(shipped())})", 2)

    def run_placed(path: Path, **options: Any) -> Any:
        mission = Mission.from_yaml(path)
        if robot is not None:
            mission.robot = str(profile_path(robot, Path.cwd()) if robot not in known_profiles() else robot)
        if world is not None:
            mission.world = str(map_path(world, Path.cwd()) if world not in known_maps() else world)
        if values:
            mission.blackboard = {**mission.blackboard, **values}  # --set
        return mission.run(**options)

    return run_placed


def warn_unplaced(path: Path, robot: str | None, world: str | None) -> None:
    """A tree file run without a robot runs its tree alone, on no robot: say so."""
    if path.suffix.lower() == ".xml" and robot is None:
        _stderr([f"note: {path} names no robot; add --robot PROFILE --world MAP to drive one"])


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
