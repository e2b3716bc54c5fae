"""The true path of a simulated robot: kept every step, written as trajectory.csv for the report."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

from botstage.robots.interfaces import Pose2D


class Trajectory(list[tuple[float, float, float, float]]):
    """(t, x, y, theta) rows, from the start pose on."""

    def __init__(self, start: Pose2D) -> None:
        super().__init__([(0.0, start.x, start.y, start.theta)])

    def add(self, t: float, pose: Pose2D) -> None:
        self.append((t, pose.x, pose.y, pose.theta))

    def distance(self) -> float:
        """Metres driven along the path."""
        return sum(math.hypot(b[1] - a[1], b[2] - a[2]) for a, b in itertools.pairwise(self))

    def write(self, path: Path) -> None:
        lines = ["t,x,y,theta"] + [f"{t:.6g},{x:.6f},{y:.6f},{theta:.6f}" for t, x, y, theta in self]
        path.write_text("\n".join(lines) + "\n", encoding="utf-8")
