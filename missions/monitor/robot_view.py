"""What the monitor's map shows of the robot: its true pose (simulation), what it believes, the
laser's last scan, the path it is driving (the navigation stack's current plan), the people and
the crowd it is after; and the map itself as an image.

Sampled between ticks, at most every ``SAMPLE_S`` of wall time, from what is already there
(the simulator's state, the localiser's estimate, the laser's latest scan): reading a device
again would turn the simulator's noise generators and change the run's course.
"""

from __future__ import annotations

import math
from typing import Any

import cv2
import numpy as np

from botstage.robots.gridmap import GridMap

SAMPLE_S = 0.1  # the map is redrawn at 10 Hz at most
LASER_POINTS = 181  # a scan is thinned to at most this many endpoints
PATH_POINTS = 200  # a planned path is thinned to at most this many points (its ends kept)
POSES_FILE = "poses.csv"  # the run's poses, as the monitor records them (observer.py)
POSE_COLUMNS = ("tick", "t", "x", "y", "theta", "est_x", "est_y", "est_theta")
POSES_HEADER = ",".join(POSE_COLUMNS)


def map_info(grid: GridMap) -> dict[str, Any]:
    return {
        "width": grid.width,
        "height": grid.height,
        "resolution": grid.resolution,
        "origin": list(grid.origin),
        "places": {name: [round(float(v), 3) for v in place] for name, place in grid.places.items()},
    }


def map_png(grid: GridMap) -> bytes:
    """The occupancy grid as map_server draws it: free white, occupied black, unknown grey; top row first."""
    data = grid.data
    image = np.full(data.shape, 205, dtype=np.uint8)
    image[data == 0] = 254
    image[data >= 50] = 0
    ok, encoded = cv2.imencode(".png", np.flipud(image))
    if not ok:
        raise RuntimeError("OpenCV could not encode the map")
    return encoded.tobytes()


def _pose(pose: Any) -> list[float] | None:
    if pose is None:
        return None
    return [round(float(pose.x), 3), round(float(pose.y), 3), round(float(pose.theta), 4)]


def _laser_points(device: Any, pose: list[float] | None) -> list[list[float]]:
    scan = getattr(device, "latest", None)
    mount = getattr(getattr(device, "device", None), "pose", (0.0, 0.0, 0.0))
    if scan is None or pose is None:
        return []
    ranges = np.asarray(scan.ranges, dtype=float)
    step = max(1, math.ceil(len(ranges) / LASER_POINTS))
    index = np.arange(0, len(ranges), step)
    hits = ranges[index]
    keep = np.isfinite(hits) & (hits < scan.range_max)
    angles = scan.angle_min + index[keep] * scan.angle_increment
    x, y, theta = pose
    mx, my, mtheta = mount
    c, s = math.cos(theta), math.sin(theta)
    sx, sy = x + c * mx - s * my, y + s * mx + c * my
    heading = theta + mtheta + angles
    px = sx + hits[keep] * np.cos(heading)
    py = sy + hits[keep] * np.sin(heading)
    return [[round(float(a), 2), round(float(b), 2)] for a, b in zip(px, py, strict=True)]


def _path(navigation: Any) -> list[list[float]]:
    """The path the navigation stack is driving now (``NavStack.path``), start to goal; [] when none."""
    points = getattr(navigation, "path", None)
    if not points:
        return []
    step = max(1, math.ceil((len(points) - 1) / (PATH_POINTS - 1)))
    kept = list(points[::step])
    if kept[-1] is not points[-1]:
        kept.append(points[-1])  # the goal, whatever the thinning
    return [[round(float(x), 2), round(float(y), 2)] for x, y in kept]


def poses(session: Any) -> tuple[list[float] | None, list[float] | None]:
    """The robot's true pose (a simulation's; None on real hardware) and its localiser's
    estimate (None without one, or before it has one)."""
    backend = session.backend
    if backend is None:
        return None, None
    true_pose = _pose(backend.true_pose())
    localization = session.interfaces.get("localization")
    estimate = None
    if localization is not None:
        try:
            estimate = _pose(localization.pose())
        except Exception:  # a localiser not started yet
            estimate = None
    return true_pose, estimate


def pose_row(tick: int, t: float, true_pose: list[float] | None, estimate: list[float] | None) -> str:
    """One line of poses.csv; an unknown pose is left empty."""
    cells = [str(tick), f"{t:.3f}"]
    for pose in (true_pose, estimate):
        cells += [f"{v:g}" for v in pose] if pose is not None else ["", "", ""]
    return ",".join(cells)


def read_poses(path: Any) -> list[tuple[int, list[float] | None, list[float] | None]]:
    """poses.csv as (tick, true pose, estimate) rows, in tick order."""
    rows = []
    lines = path.read_text(encoding="utf-8").splitlines()
    for line in lines[1:]:
        cells = line.split(",")
        if len(cells) != len(POSE_COLUMNS):
            continue  # a line cut short by a crash
        true_pose = [float(v) for v in cells[2:5]] if cells[2] else None
        estimate = [float(v) for v in cells[5:8]] if cells[5] else None
        rows.append((int(cells[0]), true_pose, estimate))
    return rows


def robot_sample(session: Any, teleop: dict[str, Any], camera: int) -> dict[str, Any] | None:
    """The robot block of the monitor's snapshot, or None for a robot-less run."""
    backend = session.backend
    if backend is None:
        return None
    true_pose, estimate = poses(session)
    interfaces = session.interfaces
    laser = interfaces.get("laser")
    people: list[list[float]] = []
    crowd_of = getattr(backend, "crowd", None)
    if crowd_of is not None:
        people = [[round(p.x, 2), round(p.y, 2)] for p in crowd_of.people]
    crowd = None
    engine = session.engine
    if engine is not None:
        centre = engine.blackboard.get("crowd_centre", None)
        size = engine.blackboard.get("crowd_size", 0)
        if isinstance(centre, list | tuple) and len(centre) == 2:
            crowd = [round(float(centre[0]), 2), round(float(centre[1]), 2), int(size or 0)]
    return {
        "pose": true_pose,
        "estimate": estimate,
        "laser": _laser_points(laser, true_pose or estimate) if laser is not None else [],
        "path": _path(interfaces.get("navigation")),
        "people": people,
        "crowd": crowd,
        "teleop": teleop,
        "camera": camera,
    }
