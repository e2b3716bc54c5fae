"""Global planning time on a 1000 x 1000-cell map (target: median <= 100 ms per plan).

A seeded map of 300 rectangular obstacles (50 x 50 m at 5 cm), inflated for a 0.3 m robot,
and 50 random start-goal pairs on free floor. pyastar2d does not report its expansions, so the
throughput figure is map cells per second of median planning time. Run with `botstage bench nav`.
"""

from __future__ import annotations

import json
import time
from typing import Any

import numpy as np

from robots.gridmap import FREE, OCCUPIED, GridMap
from skills.nav.costmap import inflated_costs
from skills.nav.planner import Planner, Unreachable

TARGET_MS = 100.0


def random_map(seed: int, size: int = 1000) -> GridMap:
    rng = np.random.default_rng(seed)
    data = np.full((size, size), FREE, dtype=np.int8)
    for _ in range(300):
        r, c = rng.integers(0, size - 60, 2)
        h, w = rng.integers(5, 60, 2)
        data[r : r + h, c : c + w] = OCCUPIED
    return GridMap(data, 0.05)


def bench_planning(plans: int) -> dict[str, Any]:
    grid = random_map(0)
    start = time.perf_counter()
    costs = inflated_costs(grid, 0.3)
    costmap_s = time.perf_counter() - start
    planner = Planner(grid, costs)
    rng = np.random.default_rng(1)
    free = np.argwhere(np.isfinite(costs))
    times, unreachable = [], 0
    while len(times) < plans:
        a, b = free[rng.integers(len(free))], free[rng.integers(len(free))]
        start = time.perf_counter()
        try:
            planner.plan(grid.point(*a), grid.point(*b))
        except Unreachable:
            unreachable += 1
        times.append(time.perf_counter() - start)
    median = float(np.median(times))
    return {
        "bench": "plan_1000x1000",
        "plans": plans,
        "median_ms": round(median * 1e3, 2),
        "p90_ms": round(float(np.percentile(times, 90)) * 1e3, 2),
        "max_ms": round(max(times) * 1e3, 2),
        "target_ms": TARGET_MS,
        "map_cells_per_s": round(grid.data.size / median),
        "unreachable": unreachable,
        "costmap_build_s": round(costmap_s, 3),
    }


def main(quick: bool = False) -> list[dict[str, Any]]:
    results = [bench_planning(10 if quick else 50)]
    for result in results:
        print(json.dumps(result), flush=True)
    return results


if __name__ == "__main__":
    main()
