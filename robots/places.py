"""A robot put on a map: a shipped or given profile, a map, and a start (a place of the map or
"x,y,theta"), as `botstage emulate` and `botstage teleop` take them."""

from __future__ import annotations

import math

from botstage.robots.gridmap import GridMap, MapError, map_path
from botstage.robots.gridmap import load as load_map
from botstage.robots.interfaces import Pose2D
from botstage.robots.profile import Profile, load_profile, profile_path


class PlaceError(Exception):
    """The robot, the map or the start cannot be found: one line per problem."""

    def __init__(self, lines: list[str]) -> None:
        super().__init__("\n".join(lines))
        self.lines = lines


def robot_place(profile_name: str, world: str, start: str) -> tuple[Profile, GridMap, Pose2D]:
    path = profile_path(profile_name)
    profile, problems, _ = load_profile(path) if path is not None else (None, [], None)
    if profile is None:
        raise PlaceError([str(p) for p in problems] or [f"error: unknown robot {profile_name!r}"])
    where = map_path(world)
    if where is None:
        raise PlaceError([f"error: unknown world {world!r}"])
    try:
        grid = load_map(where)
    except MapError as exc:
        raise PlaceError([f"error: {exc}"]) from None
    if start in grid.places:
        return profile, grid, Pose2D(*grid.places[start])
    try:
        x, y, theta = (float(part) for part in start.split(","))
    except ValueError:
        known = ", ".join(sorted(grid.places)) or "none"
        raise PlaceError([f"error: start {start!r} is neither a place of {world} ({known}) nor x,y,theta"]) from None
    if not all(math.isfinite(v) for v in (x, y, theta)):
        raise PlaceError([f"error: start {start!r}: x, y and theta should be finite numbers"])
    return profile, grid, Pose2D(x, y, theta)
