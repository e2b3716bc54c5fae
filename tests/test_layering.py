"""Imports point one way: missions -> behaviors -> skills -> robots; skills never see py_trees."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
ORDER = ["robots", "skills", "behaviors", "missions"]
FORBIDDEN_EVERYWHERE_BELOW_BEHAVIORS = {"py_trees", "transitions"}


def imported_top_levels(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {alias.name.split(".")[0] for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module.split(".")[0])
    return names


@pytest.mark.parametrize("layer", ORDER)
def test_layers_import_only_downwards(layer: str) -> None:
    higher = set(ORDER[ORDER.index(layer) + 1 :])
    offenders = []
    for path in sorted((ROOT / layer).rglob("*.py")):
        bad = imported_top_levels(path) & higher
        if layer in ("robots", "skills"):
            bad |= imported_top_levels(path) & FORBIDDEN_EVERYWHERE_BELOW_BEHAVIORS
        if bad:
            offenders.append(f"{path.relative_to(ROOT)} imports {sorted(bad)}")
    assert offenders == []
