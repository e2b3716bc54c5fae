"""The maps botstage ships, drawn by code so they can be regenerated and reviewed.

``python -m botstage.robots.mapdraw`` rewrites ``robots/maps/`` (map_server YAML + PGM + named places):

- ``museum``: a 30 x 20 m exhibition hall (PeopleBot): an entrance lobby, exhibits on plinths,
  pillars, a side gallery through a doorway, and the checkpoints the robot patrols.
- ``restaurant``: a 20 x 14 m hotel restaurant (Chefbot): a kitchen behind a wall with a door,
  a charging dock, a service corridor and six tables with their serving spots.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from botstage.robots.gridmap import FREE, OCCUPIED, UNKNOWN, GridMap, save

MAPS_DIR = Path(__file__).resolve().parent / "maps"
RESOLUTION = 0.05
WALL = 0.2  # metres


class Canvas:
    """A map being drawn in world metres, origin at the lower-left corner of the building."""

    def __init__(self, width_m: float, height_m: float, margin_m: float = 0.5) -> None:
        self.margin = margin_m
        cols = round((width_m + 2 * margin_m) / RESOLUTION)
        rows = round((height_m + 2 * margin_m) / RESOLUTION)
        self.data = np.full((rows, cols), UNKNOWN, dtype=np.int8)
        self.width, self.height = width_m, height_m
        self.places: dict[str, tuple[float, float, float]] = {}

    def _cells(self, x0: float, y0: float, x1: float, y1: float) -> tuple[slice, slice]:
        def index(v: float) -> int:
            return round((v + self.margin) / RESOLUTION)

        return slice(index(min(y0, y1)), index(max(y0, y1))), slice(index(min(x0, x1)), index(max(x0, x1)))

    def fill(self, x0: float, y0: float, x1: float, y1: float, value: int) -> None:
        self.data[self._cells(x0, y0, x1, y1)] = value

    def room(self, x0: float, y0: float, x1: float, y1: float) -> None:
        """Free floor inside walls."""
        self.fill(x0 - WALL, y0 - WALL, x1 + WALL, y1 + WALL, OCCUPIED)
        self.fill(x0, y0, x1, y1, FREE)

    def wall(self, x0: float, y0: float, x1: float, y1: float) -> None:
        """A straight wall from (x0, y0) to (x1, y1), axis-aligned."""
        half = WALL / 2
        self.fill(min(x0, x1) - half, min(y0, y1) - half, max(x0, x1) + half, max(y0, y1) + half, OCCUPIED)

    def door(self, x0: float, y0: float, x1: float, y1: float) -> None:
        """An opening cut through a wall."""
        half = WALL / 2 + RESOLUTION
        self.fill(min(x0, x1) - half, min(y0, y1) - half, max(x0, x1) + half, max(y0, y1) + half, FREE)

    def block(self, x: float, y: float, w: float, h: float) -> None:
        """An obstacle centred on (x, y): a plinth, a table, a pillar, a counter."""
        self.fill(x - w / 2, y - h / 2, x + w / 2, y + h / 2, OCCUPIED)

    def place(self, name: str, x: float, y: float, yaw: float = 0.0) -> None:
        self.places[name] = (x, y, yaw)

    def grid(self) -> GridMap:
        grid = GridMap(self.data, RESOLUTION, (-self.margin, -self.margin, 0.0))
        grid.places = dict(self.places)
        return grid


def museum() -> GridMap:
    c = Canvas(30.0, 20.0)
    c.room(0, 0, 30, 20)
    # the side gallery, behind a wall with a wide doorway
    c.wall(22, 0, 22, 20)
    c.door(22, 8, 22, 12)
    # the lobby's reception desk by the entrance (south wall)
    c.door(3, 0, 6, 0)
    c.block(9.0, 3.0, 3.0, 0.8)
    # exhibits on plinths and the hall's pillars
    for x, y in ((6, 10), (11, 14), (16, 10), (11, 6)):
        c.block(x, y, 1.2, 1.2)
    for x in (4.0, 18.0):
        for y in (5.0, 15.0):
            c.block(x, y, 0.5, 0.5)
    c.block(26.0, 15.0, 2.0, 1.0)  # a large model in the gallery
    c.block(26.0, 5.0, 1.0, 1.0)
    for name, x, y, yaw in (
        ("entrance", 4.5, 1.5, 1.57),
        ("reception", 9.0, 4.5, -1.57),
        ("exhibit_a", 6.0, 11.5, -1.57),
        ("exhibit_b", 11.0, 15.5, -1.57),
        ("exhibit_c", 16.0, 11.5, -1.57),
        ("exhibit_d", 11.0, 7.5, -1.57),
        ("hall_centre", 11.0, 10.0, 0.0),
        ("gallery_door", 20.5, 10.0, 0.0),
        ("gallery_model", 26.0, 13.5, -1.57),
        ("gallery_corner", 28.0, 2.0, 3.14),
        ("dock", 2.0, 1.5, 3.14),
    ):
        c.place(name, x, y, yaw)
    return c.grid()


def restaurant() -> GridMap:
    c = Canvas(20.0, 14.0)
    c.room(0, 0, 20, 14)
    # the kitchen along the west side, behind a wall with a door; the pass (counter) inside
    c.wall(5, 0, 5, 14)
    c.door(5, 6, 5, 7.5)
    c.block(2.5, 9.0, 3.0, 0.8)
    c.block(1.0, 3.0, 1.2, 3.0)  # stoves against the wall
    # the dining room: two rows of three tables
    tables = [(9.0, 4.0), (13.0, 4.0), (17.0, 4.0), (9.0, 10.0), (13.0, 10.0), (17.0, 10.0)]
    for x, y in tables:
        c.block(x, y, 1.2, 1.2)
    # the guests' entrance on the east wall and a service corridor wall segment
    c.door(20, 6, 20, 8)
    c.wall(7, 13, 7, 14)
    for index, (x, y) in enumerate(tables, start=1):
        c.place(f"table_{index}", x, y - 1.3 if y < 7 else y + 1.3, 1.57 if y < 7 else -1.57)
    c.place("kitchen", 3.0, 7.0, 0.0)
    c.place("pass", 2.5, 8.0, 1.57)
    c.place("kitchen_door", 6.0, 6.75, 0.0)
    c.place("dock", 6.0, 1.0, -1.57)
    c.place("entrance", 19.0, 7.0, 3.14)
    return c.grid()


MAPS = {"museum": museum, "restaurant": restaurant}


def main() -> None:
    MAPS_DIR.mkdir(exist_ok=True)
    for name, draw in MAPS.items():
        save(draw(), MAPS_DIR / f"{name}.yaml")
        print(f"wrote {MAPS_DIR / name}.yaml, .pgm and .places.yaml")


if __name__ == "__main__":
    main()
