"""`botstage backends`: what `run --backend` can open, with each backend's options."""

from __future__ import annotations

from typing import Any

from rich.table import Table

from botstage.missions.cli.common import _stderr, console


def _options(described: dict[str, Any]) -> str:
    lines = []
    for name, option in described["options"].items():
        value = "required" if option["required"] else f"default {option['default']!r}"
        lines.append(f"{name} ({option['type']}, {value}): {option['description']}")
    return "\n".join(lines) or "-"


def backends() -> None:
    """List the backends `botstage run --backend` can open (built-in and plugins), with their options."""
    from botstage.robots.backend_registry import BackendRegistry

    registry = BackendRegistry.default()
    table = Table("backend", "description", "clock", "options (--backend-opt, or the profile's backends:)", "from")
    for name, kind in registry.items():
        described = kind.describe()
        clock = "simulated" if kind.simulated else "wall"
        table.add_row(name, kind.description, clock, _options(described), registry.origin(name))
    console.print(table)
    _stderr([f"plugin {problem.entry_point}: {problem.reason}" for problem in registry.problems])
