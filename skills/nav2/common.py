"""What the Nav2 skills share: paths and goals as botstage values, Nav2's error codes, ignored ports.

A Nav2 ``nav_msgs/Path`` is here a list of ``[x, y]`` points in the map frame, the last one
``[x, y, theta]`` when the goal has a heading; a ``PoseStamped`` goal is a place name or
``[x, y]``/``[x, y, theta]`` (what ``NavStack.resolve`` reads); ``Goals`` is a list of those.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from botstage.skills.base import In, Port
from botstage.skills.nav.stack import NavStack, blocked_cells

PATH = list[list[float]]
GOAL = str | list[float]
GOALS = list[str | list[float]]
CODES = str | list[int] | None  # Nav2's vector<int>: "101;104" in XML, or a list

# Nav2's action result codes (nav2_msgs/action/*.action), so WouldA*RecoveryHelp read them as Nav2 does
FOLLOW_PATH = {"UNKNOWN": 100, "INVALID_PATH": 103, "PATIENCE_EXCEEDED": 104, "FAILED_TO_MAKE_PROGRESS": 105}
FOLLOW_PATH |= {"NO_VALID_CONTROL": 106, "CONTROLLER_TIMED_OUT": 107}
COMPUTE_PATH = {"UNKNOWN": 200, "START_OUTSIDE_MAP": 203, "GOAL_OUTSIDE_MAP": 204, "START_OCCUPIED": 205}
COMPUTE_PATH |= {"GOAL_OCCUPIED": 206, "TIMEOUT": 207, "NO_VALID_PATH": 208}
THROUGH_POSES = {key: code + 100 for key, code in COMPUTE_PATH.items()} | {"NO_VIAPOINTS_GIVEN": 309}
SMOOTHER = {"UNKNOWN": 500, "TIMEOUT": 501, "SMOOTHED_PATH_IN_COLLISION": 502, "FAILED_TO_SMOOTH_PATH": 503}
BEHAVIOR = {"UNKNOWN": 700, "TIMEOUT": 701, "TF_ERROR": 702, "COLLISION_AHEAD": 703, "INVALID_INPUT": 704}
WAIT = {"UNKNOWN": 750}


def ignored(what: str, default: Any = None) -> Port:
    """A Nav2 port that only addresses ROS (a server, a topic, a frame, a plug-in): accepted, unused.
    ``default``: Nav2's, so the node's contract reads as nav2_tree_nodes.xml declares it."""
    return In(Any, default=default, doc=f"ignored on botstage ({what})")


SERVER = {
    "server_name": ignored("botstage calls the navigation stack directly, no action server"),
    "server_timeout": ignored("no action server to wait for"),
}


def codes(value: CODES, default: tuple[int, ...]) -> set[int]:
    """Nav2's ``error_codes_to_check``: "a;b" text, a list, or the node's default set."""
    if value is None or value == "":
        return set(default)
    if isinstance(value, str):
        try:
            return {int(part) for part in value.replace(",", ";").split(";") if part.strip()}
        except ValueError:
            raise ValueError(f"error_codes_to_check: expected numbers separated by ';', got {value!r}") from None
    return set(value)


def as_path(points: list[tuple[float, float]], heading: float | None) -> PATH:
    """A planner's points as a path value; the goal's heading, when it has one, on the last point."""
    path = [[round(x, 4), round(y, 4)] for x, y in points]
    if heading is not None:
        path[-1].append(round(heading, 4))
    return path


def xy(path: PATH) -> np.ndarray:
    return np.asarray([p[:2] for p in path], dtype=float).reshape(-1, 2)


def path_heading(path: PATH) -> float | None:
    return float(path[-1][2]) if path and len(path[-1]) > 2 else None


def closest_index(path: PATH, x: float, y: float, search: float = -1.0, start: int = 0) -> int:
    """The index of the path point nearest (x, y), looking ``search`` metres on from ``start``
    (all the path when negative), as Nav2's IsGoalNearby and TruncatePathLocal bound it."""
    points = xy(path)
    end = len(points)
    if search >= 0:
        steps = np.hypot(*np.diff(points[start:], axis=0).T) if end - start > 1 else np.empty(0)
        within = np.nonzero(np.cumsum(steps) > search)[0]
        end = start + int(within[0]) + 2 if len(within) else end
    d = np.hypot(points[start:end, 0] - x, points[start:end, 1] - y)
    return start + int(np.argmin(d))


def length(points: np.ndarray) -> float:
    return float(np.hypot(*np.diff(points, axis=0).T).sum()) if len(points) > 1 else 0.0


ON_MAP = 0.15  # m: a return this close to the map's obstacles is the map (a wall), not something new


def sense(stack: NavStack) -> None:
    """Put what the range sensors see now, and the map does not have, on the obstacle layer:
    Nav2's costmaps take sensor data all the time, so planning and checking here see what is in
    the way now, even after a clear. Walls are the map's already (marking them would only make
    every plan pay for a costmap of its own)."""
    pose, points = stack.pose(), stack.obstacles()
    if not len(points):
        return
    c, s = math.cos(pose.theta), math.sin(pose.theta)
    rows, cols = stack.grid.cells(
        pose.x + c * points[:, 0] - s * points[:, 1], pose.y + s * points[:, 0] + c * points[:, 1]
    )
    gap, _ = blocked_cells(stack.grid).query(np.column_stack((rows + 0.5, cols + 0.5)))
    new = points[gap * stack.grid.resolution > ON_MAP]
    if len(new):
        stack.mark(pose, new)


def goal_xy(stack: NavStack, goal: Any) -> tuple[float, float, float | None]:
    return stack.resolve(goal)


def distance(a: tuple[float, float], b: tuple[float, float]) -> float:
    return math.hypot(a[0] - b[0], a[1] - b[1])
