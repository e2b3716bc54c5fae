"""Global planning on inflated costmaps."""

from __future__ import annotations

import itertools
import math
import os
from pathlib import Path

import numpy as np
import pytest

from botstage.robots.gridmap import FREE, OCCUPIED, GridMap, load
from botstage.skills.nav.costmap import inflated_costs
from botstage.skills.nav.planner import Planner, Unreachable

RADIUS = {"museum": 0.30, "restaurant": 0.2}


@pytest.mark.parametrize("name", sorted(RADIUS))
def test_every_place_plans_to_every_other(name: str) -> None:
    grid = load(Path("robots/maps") / f"{name}.yaml")
    costs = inflated_costs(grid, RADIUS[name])
    planner = Planner(grid, costs)
    for (a, pa), (b, pb) in itertools.permutations(grid.places.items(), 2):
        plan = planner.plan(pa[:2], pb[:2])
        assert plan.points[0] == pa[:2] and plan.points[-1] == pb[:2]
        for x, y in plan.points[1:-1]:
            row, col = grid.cell(x, y)
            assert math.isfinite(costs[row, col]), f"{a} -> {b} passes through a lethal cell"
        assert plan.length >= math.hypot(pb[0] - pa[0], pb[1] - pa[1]) - 0.1


def test_goals_in_walls_enclosed_or_off_the_map_are_unreachable() -> None:
    data = np.full((60, 60), FREE, dtype=np.int8)
    data[[0, -1], :] = OCCUPIED
    data[:, [0, -1]] = OCCUPIED
    data[20:41, 20] = data[20:41, 40] = data[20, 20:41] = data[40, 20:41] = OCCUPIED  # a closed room
    grid = GridMap(data, 0.1)
    planner = Planner(grid, inflated_costs(grid, 0.2))
    with pytest.raises(Unreachable, match="enclosed"):
        planner.plan((0.6, 0.6), (3.0, 3.0))  # inside the closed room
    with pytest.raises(Unreachable, match="inside an obstacle"):
        planner.plan((0.6, 0.6), (2.0, 3.0))  # on its wall
    with pytest.raises(Unreachable, match="off the map"):
        planner.plan((0.6, 0.6), (9.0, 3.0))


def test_paths_keep_clear_of_walls_where_there_is_room() -> None:
    data = np.full((40, 100), FREE, dtype=np.int8)
    data[[0, -1], :] = OCCUPIED  # a 4 m wide corridor, 10 m long
    grid = GridMap(data, 0.1)
    plan = Planner(grid, inflated_costs(grid, 0.2, inflation_m=1.0)).plan((0.5, 0.6), (9.5, 0.6))
    middle = [y for x, y in plan.points if 3.0 < x < 7.0]
    assert middle and min(middle) > 1.2  # it moved away from the wall it started next to


def test_maps_from_ros_tooling_plan_too() -> None:
    shared = Path(__file__).resolve().parents[2] / "shared" / "maps" / "tb3_sandbox.yaml"
    if not shared.exists():
        if os.environ.get("CI") == "true":
            pytest.fail(f"{shared} is missing: CI runs with ../shared beside the clone")
        pytest.skip("../shared/maps is not beside this checkout")
    grid = load(shared)
    plan = Planner(grid, inflated_costs(grid, 0.105)).plan((-1.8, -0.5), (1.8, 0.5))  # across the pillars
    assert plan.length > math.hypot(3.6, 1.0) - 0.05


def test_start_and_goal_in_one_cell_still_end_at_the_goal() -> None:
    grid = load(Path("robots/maps/museum.yaml"))
    plan = Planner(grid, inflated_costs(grid, 0.3)).plan((4.5, 1.5), (4.51, 1.5))
    assert plan.points == [(4.5, 1.5), (4.51, 1.5)]
