"""The maps botstage ships: reproducible, places on free floor, every place reachable from every other."""

from __future__ import annotations

from collections import deque

import numpy as np
import pytest

from botstage.robots.gridmap import FREE, GridMap, load
from botstage.robots.mapdraw import MAPS, MAPS_DIR

ROBOT_RADIUS = {"museum": 0.25, "restaurant": 0.2}  # PeopleBot, Chefbot (half their footprint)


def passable(grid: GridMap, radius: float) -> np.ndarray:
    """Cells whose disk of ``radius`` holds only free cells (unknown counts as blocked)."""
    blocked = grid.data != FREE
    r = int(np.ceil(radius / grid.resolution))
    grown = blocked.copy()
    for dr in range(-r, r + 1):
        for dc in range(-r, r + 1):
            if dr * dr + dc * dc > r * r:
                continue
            shifted = np.zeros_like(blocked)
            rows = slice(max(dr, 0), blocked.shape[0] + min(dr, 0))
            cols = slice(max(dc, 0), blocked.shape[1] + min(dc, 0))
            source_rows = slice(max(-dr, 0), blocked.shape[0] + min(-dr, 0))
            source_cols = slice(max(-dc, 0), blocked.shape[1] + min(-dc, 0))
            shifted[rows, cols] = blocked[source_rows, source_cols]
            grown |= shifted
    return ~grown


def component(ok: np.ndarray, start: tuple[int, int]) -> np.ndarray:
    seen = np.zeros_like(ok)
    queue = deque([start])
    seen[start] = True
    while queue:
        row, col = queue.popleft()
        for nr, nc in ((row + 1, col), (row - 1, col), (row, col + 1), (row, col - 1)):
            if 0 <= nr < ok.shape[0] and 0 <= nc < ok.shape[1] and ok[nr, nc] and not seen[nr, nc]:
                seen[nr, nc] = True
                queue.append((nr, nc))
    return seen


@pytest.mark.parametrize("name", sorted(MAPS))
def test_shipped_maps_are_what_the_drawing_code_makes(name: str) -> None:
    shipped = load(MAPS_DIR / f"{name}.yaml")
    drawn = MAPS[name]()
    assert np.array_equal(shipped.data, drawn.data), "run `python -m botstage.robots.mapdraw` and commit"
    assert shipped.places == drawn.places


@pytest.mark.parametrize("name", sorted(MAPS))
def test_every_place_reaches_every_other(name: str) -> None:
    grid = load(MAPS_DIR / f"{name}.yaml")
    assert len(grid.places) >= 5
    ok = passable(grid, ROBOT_RADIUS[name])
    first = next(iter(grid.places.values()))
    reach = component(ok, grid.cell(first[0], first[1]))
    for place, (x, y, _) in grid.places.items():
        cell = grid.cell(x, y)
        assert ok[cell], f"{place} is closer than {ROBOT_RADIUS[name]} m to an obstacle"
        assert reach[cell], f"{place} cannot be reached from the others"


def test_the_museum_gallery_is_only_reached_through_its_doorway() -> None:
    grid = load(MAPS_DIR / "museum.yaml")
    ok = passable(grid, ROBOT_RADIUS["museum"])
    doorway = grid.cell(22.0, 10.0)
    assert ok[doorway]
    ok[doorway[0] - 50 : doorway[0] + 50, doorway[1]] = False  # close the doorway
    reach = component(ok, grid.cell(*grid.places["hall_centre"][:2]))
    assert not reach[grid.cell(*grid.places["gallery_model"][:2])]
