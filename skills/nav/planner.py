"""Global planning: A* on an inflated costmap, in C++ through pyastar2d.

pyastar2d plans a 1000 x 1000 grid in a few milliseconds (`python -m tests.bench nav`), where a
pure-Python A* would take seconds; scikit-image's minimum-cost paths were measured 30 times
slower. Paths come back as world points, thinned to one every ``spacing`` metres.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pyastar2d

from botstage.robots.gridmap import GridMap


@dataclass(frozen=True)
class Plan:
    points: list[tuple[float, float]]  # world coordinates, start to goal
    length: float  # metres
    cost: float


class Unreachable(Exception):
    """No path: the reason says why (goal in an obstacle, off the map, or enclosed)."""


class Planner:
    def __init__(self, grid: GridMap, costs: np.ndarray) -> None:
        if costs.shape != grid.data.shape:
            raise ValueError(f"costs shape {costs.shape} differs from the map's {grid.data.shape}")
        self.grid = grid
        self.costs = np.ascontiguousarray(costs, dtype=np.float32)

    def _cell(self, x: float, y: float, what: str) -> tuple[int, int]:
        row, col = self.grid.cell(x, y)
        if not self.grid.inside(row, col):
            raise Unreachable(f"the {what} ({x:g}, {y:g}) is off the map")
        if not math.isfinite(self.costs[row, col]):
            raise Unreachable(f"the {what} ({x:g}, {y:g}) is inside an obstacle or too close to one for the robot")
        return row, col

    def plan(self, start: tuple[float, float], goal: tuple[float, float], spacing: float = 0.25) -> Plan:
        a = self._cell(*start, "start")
        b = self._cell(*goal, "goal")
        cells = pyastar2d.astar_path(self.costs, a, b, allow_diagonal=True)
        if cells is None:
            raise Unreachable(
                f"no path from ({start[0]:g}, {start[1]:g}) to ({goal[0]:g}, {goal[1]:g}): the goal is enclosed"
            )
        points = [self.grid.point(int(r), int(c)) for r, c in cells]
        steps = np.diff(np.asarray(cells, dtype=float), axis=0)
        length = float(np.hypot(steps[:, 0], steps[:, 1]).sum()) * self.grid.resolution if len(cells) > 1 else 0.0
        cost = float(self.costs[cells[:, 0], cells[:, 1]].sum())
        if len(cells) == 1:  # start and goal share a cell
            return Plan([start, goal], math.hypot(goal[0] - start[0], goal[1] - start[1]), cost)
        every = max(1, round(spacing / self.grid.resolution))
        thinned = points[::every]
        if thinned[-1] != points[-1]:
            thinned.append(points[-1])
        thinned[-1] = goal
        thinned[0] = start
        return Plan(thinned, length, cost)
