"""`botstage places MAP`: what a shipped or given map holds, and the places a mission may name."""

from __future__ import annotations

import json
import math

import typer
from rich.table import Table

from botstage.missions.cli.common import _fail, console


def places(
    world: str = typer.Argument(..., help="a shipped map's name (museum, restaurant) or a map_server YAML's path"),
    as_json: bool = typer.Option(False, "--json", help="print the places as JSON: {name: [x, y, yaw]}"),
) -> None:
    """List a map's named places (what `start:`, `goal:` and `gatherings: at:` may name), with the map's size."""
    from botstage.robots.gridmap import MapError, known_maps, map_path
    from botstage.robots.gridmap import load as load_map

    where = map_path(world)
    if where is None:
        shipped = ", ".join(known_maps())
        raise _fail(f"error: unknown map {world!r} (shipped maps: {shipped}; or give a map YAML's path)", 2)
    try:
        grid = load_map(where)
    except MapError as exc:
        raise _fail(f"error: {exc}", 1) from None
    if as_json:
        typer.echo(json.dumps({name: list(pose) for name, pose in sorted(grid.places.items())}, indent=2))
        return
    width, height = grid.width * grid.resolution, grid.height * grid.resolution
    console.print(
        f"{where}: {width:g} × {height:g} m ({grid.width} × {grid.height} cells of {grid.resolution:g} m), "
        f"{len(grid.places)} places",
        soft_wrap=True,
    )
    if not grid.places:
        console.print(f"(no places: name them in {where.with_suffix('.places.yaml').name} beside the map)")
        return
    table = Table("place", "x (m)", "y (m)", "yaw (°)")
    for name, (x, y, yaw) in sorted(grid.places.items()):
        table.add_row(name, f"{x:.2f}", f"{y:.2f}", f"{math.degrees(yaw):.0f}")
    console.print(table)
