"""`botstage schema`: the JSON Schema of mission files, for editors."""

from __future__ import annotations

import json
import sys

import typer


def schema(
    builtin: bool = typer.Option(
        False, help="only the built-in skills and node kinds (as missions/mission.schema.json has)"
    ),
) -> None:
    """Print the JSON Schema of mission files (for editor completion)."""
    from botstage.behaviors.kinds import NodeKinds
    from botstage.missions.schema import json_schema
    from botstage.skills.registry import Registry

    if builtin:
        schema = json_schema(Registry.shipped(), NodeKinds.builtin())
    else:
        schema = json_schema(Registry.default(), NodeKinds.default())
    sys.stdout.write(json.dumps(schema, indent=2) + "\n")
