"""`botstage nodes`: the node kinds trees can use, with their options."""

from __future__ import annotations

import typer
from rich.table import Table

from botstage.missions.cli.common import _fail, _stderr, console


def nodes(
    scope: str = typer.Option(
        "botstage",
        "--scope",
        help="botstage: what a YAML mission writes; btcpp: the node sets an XML file adds "
        "(BehaviorTree.CPP's, Nav2's). One scope per listing, so no concept shows under two names",
    ),
) -> None:
    """List the node kinds trees can use (built-in and plugins): what each takes and where it comes from."""
    from botstage.behaviors.kinds import NodeKinds

    kinds = NodeKinds.default(scope)
    if scope != "botstage" and not kinds.sets:
        raise _fail(f"error: --scope {scope!r}: no installed node set has that scope", 2)
    table = Table("kind", "written", "options", "description", "from")
    for name in kinds.listed():
        kind = kinds.get(name)
        table.add_row(
            name,
            kind.written(),
            ", ".join(sorted(kind.option_names() - {"child"})) or "-",
            kind.description,
            kinds.origin(name),
        )
    console.print(table)
    _stderr([f"plugin {problem.entry_point}: {problem.reason}" for problem in kinds.problems])
