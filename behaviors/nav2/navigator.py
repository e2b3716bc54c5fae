"""Nav2's BT navigator: one navigator tree, run for one goal after another on one engine.

Nav2's ``bt_navigator`` takes NavigateToPose (NavigateThroughPoses) goals; for each it writes the
goal to the blackboard (``goal``, ``goals``), sets every ``<prefix>_error_code`` to 0 (its
``error_code_name_prefixes``, cleanErrorCodes), ticks the tree until it ends and halts it. This
does the same on a botstage engine, so a session drives to many goals without building the tree
again, and keeps what the navigation stack learnt on the way (as Nav2's servers keep running).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from py_trees.common import Status

from botstage.behaviors.engine import Engine

# Nav2's default error_code_name_prefixes (nav2_bt_navigator), each as `<prefix>_error_code`
ERROR_CODE_PREFIXES = (
    "assisted_teleop",
    "backup",
    "compute_path",
    "dock_robot",
    "drive_on_heading",
    "follow_path",
    "nav_thru_poses",
    "nav_to_pose",
    "route",
    "spin",
    "undock_robot",
    "wait",
)


@dataclass(frozen=True)
class GoalResult:
    """How one goal ended: the tree's status, the mission time it took and the ticks."""

    status: Status
    seconds: float
    ticks: int

    @property
    def succeeded(self) -> bool:
        return self.status is Status.SUCCESS


class Navigator:
    """Runs ``engine``'s root for each goal. ``step`` runs after every tick (a simulator's world
    moving over it); ``limit`` is the mission time a goal may take."""

    def __init__(self, engine: Engine, step: Callable[[], Any] | None = None) -> None:
        if engine.root is None:
            raise ValueError("the engine has no tree: set_root() the navigator tree first")
        self.engine = engine
        self.step = step

    def navigate(self, values: Mapping[str, Any], limit: float = 600.0) -> GoalResult:
        """Write ``values`` (``{"goal": ...}`` or ``{"goals": [...]}``) and run the tree to its end."""
        engine = self.engine
        board = engine.blackboard
        board.update({f"{prefix}_error_code": 0 for prefix in ERROR_CODE_PREFIXES}, writer="navigator")
        board.update(values, writer="navigator")
        start, ticks = engine.clock.now(), 0
        status = Status.RUNNING
        while status is Status.RUNNING or status is Status.INVALID:
            if engine.clock.now() - start >= limit:
                break
            status = engine.tick()
            ticks += 1
            if self.step is not None:
                self.step()
        engine.halt("the navigator ended the goal")
        return GoalResult(status, engine.clock.now() - start, ticks)
