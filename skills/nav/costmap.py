"""Costmaps for planning: obstacles grown by the robot's radius, and a cost that falls off beyond.

Cells within the robot's radius of an obstacle (or of unknown space) are lethal: the robot's
centre may not enter them. Beyond that, the cost decays exponentially up to ``inflation_m``, so
planned paths keep clear of walls where there is room, as ROS's inflation layer does.
"""

from __future__ import annotations

import math

import numpy as np

from botstage.robots.gridmap import FREE, GridMap

LETHAL = math.inf


def _distance_to_blocked(blocked: np.ndarray, max_cells: int) -> np.ndarray:
    """Euclidean distance in cells from each cell to the nearest blocked one (inf beyond ``max_cells``)."""
    from scipy.ndimage import distance_transform_edt  # on first use: scipy's import costs every command

    distance = distance_transform_edt(~blocked)
    distance[distance > max_cells] = np.inf
    return distance


def inflated_costs(grid: GridMap, robot_radius: float, inflation_m: float = 0.6, scale: float = 8.0) -> np.ndarray:
    """Per-cell traversal cost (>= 1, inf where lethal) for A*: 1 on open floor."""
    blocked = grid.data != FREE
    radius_cells = robot_radius / grid.resolution
    reach = math.ceil(max(inflation_m, robot_radius) / grid.resolution)
    distance = _distance_to_blocked(blocked, reach)
    costs = np.ones(blocked.shape, dtype=np.float32)
    near = np.isfinite(distance)
    beyond = (distance - radius_cells) * grid.resolution  # metres beyond the robot's edge
    costs[near] = 1.0 + scale * np.exp(-3.0 * np.maximum(beyond[near], 0.0) / max(inflation_m, 1e-6))
    costs[distance <= radius_cells] = LETHAL
    return costs
