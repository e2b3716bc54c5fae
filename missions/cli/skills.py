"""`botstage skills`: the skills the registry finds, with their contracts."""

from __future__ import annotations

from rich.table import Table

from botstage.missions.cli.common import _stderr, console


def skills() -> None:
    """List the skills the registry finds (built-in and plugins) with their contracts."""
    from botstage.skills.registry import Registry

    registry = Registry.default()
    table = Table("skill", "inputs", "outputs", "outcomes", "from")
    for name in registry:
        info = registry.get(name).describe()
        table.add_row(
            name,
            ", ".join(info["inputs"]) or "-",
            ", ".join(info["outputs"]) or "-",
            ", ".join(info["outcomes"]),
            registry.origin(name),
        )
    console.print(table)
    _stderr([f"plugin {problem.entry_point}: {problem.reason}" for problem in registry.problems])
