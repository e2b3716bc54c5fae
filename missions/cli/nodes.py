"""`botstage nodes`: the node kinds trees can use, with their options."""

from __future__ import annotations

from botstage.missions.cli.common import _stderr, console
from rich.table import Table


def nodes() -> None:
    """List the node kinds trees can use (built-in and plugins): what each takes and where it comes from."""
    from botstage.behaviors.kinds import NodeKinds

    kinds = NodeKinds.default()
    table = Table("kind", "written", "options", "description", "from")
    for name in kinds:
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
