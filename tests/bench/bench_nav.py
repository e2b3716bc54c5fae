"""Navigation benchmarks. Run with `python -m tests.bench nav`.

- **Pose drift** over a 56 m museum loop, odometry vs EKF vs map-corrected: see
  ``bench_localization.py`` (run from here too).
- **Planning**: global planning time on a 1000 x 1000-cell map (target: median <= 100 ms per
  plan). A seeded map of 300 rectangular obstacles (50 x 50 m at 5 cm), inflated for a 0.3 m
  robot, and 50 random start-goal pairs on free floor. pyastar2d does not report its
  expansions, so they are counted beside it: with its consistent heuristic (diagonal distance,
  every cell costs at least 1), A* must expand every cell with g + h < C* (C* the cost of the
  path it found), and an exact Dijkstra from the start (scipy, same moves and costs) finds g for
  every cell. Cells expanded per second is that count over the plan's time: a lower bound
  (re-expansions and ties at C* are not counted).
- **Final pose accuracy** with the protocol of the PeopleBot paper's Table 2: 50 movements of
  1-2 m with rotation (random direction and final heading) by the simulated PeopleBot in the
  museum hall, navigate's tolerances 2 cm / 0.02 rad. Errors are the robot's true final pose
  in the simulator against the goal, in the goal's frame (x forward, y left), as the paper
  measured; and separately the pose estimate the robot drove by against the true pose. The
  headline run uses seed 11; eight more seeds show how much a 50-goal mean moves by chance.
"""

from __future__ import annotations

import json
import math
import time
from typing import Any

import numpy as np

from botstage.robots.gridmap import FREE, OCCUPIED, GridMap
from botstage.skills.nav.costmap import inflated_costs
from botstage.skills.nav.planner import Planner, Unreachable

EXPANSION_SAMPLES = 10  # plans whose expansions are counted (an exact Dijkstra each)

TARGET_MS = 100.0


def random_map(seed: int, size: int = 1000) -> GridMap:
    rng = np.random.default_rng(seed)
    data = np.full((size, size), FREE, dtype=np.int8)
    for _ in range(300):
        r, c = rng.integers(0, size - 60, 2)
        h, w = rng.integers(5, 60, 2)
        data[r : r + h, c : c + w] = OCCUPIED
    return GridMap(data, 0.05)


def grid_graph(costs: np.ndarray) -> Any:
    """pyastar2d's moves as a sparse graph: 8 neighbours, a move costs the cell it enters."""
    from scipy.sparse import csr_matrix

    rows, cols = costs.shape
    index = np.arange(costs.size).reshape(rows, cols)
    sources, targets, weights = [], [], []
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            if dr == dc == 0:
                continue
            a = index[max(-dr, 0) : rows - max(dr, 0), max(-dc, 0) : cols - max(dc, 0)]
            b = index[max(dr, 0) : rows - max(-dr, 0), max(dc, 0) : cols - max(-dc, 0)]
            weight = costs.ravel()[b.ravel()]
            usable = np.isfinite(weight) & np.isfinite(costs.ravel()[a.ravel()])
            sources.append(a.ravel()[usable])
            targets.append(b.ravel()[usable])
            weights.append(weight[usable])
    return csr_matrix(
        (np.concatenate(weights), (np.concatenate(sources), np.concatenate(targets))), shape=(costs.size, costs.size)
    )


def must_expand(graph: Any, costs: np.ndarray, start: tuple[int, int], goal: tuple[int, int]) -> int:
    """Cells with g + h < C*: those A* with pyastar2d's heuristic cannot avoid expanding."""
    from scipy.sparse.csgraph import dijkstra

    width = costs.shape[1]
    g = dijkstra(graph, directed=True, indices=start[0] * width + start[1])
    best = g[goal[0] * width + goal[1]]
    rows, cols = np.divmod(np.arange(costs.size), width)
    h = np.maximum(np.abs(rows - goal[0]), np.abs(cols - goal[1]))
    return int(np.count_nonzero(g + h < best - 1e-6))


def bench_planning(plans: int) -> dict[str, Any]:
    grid = random_map(0)
    start = time.perf_counter()
    costs = inflated_costs(grid, 0.3)
    costmap_s = time.perf_counter() - start
    planner = Planner(grid, costs)
    rng = np.random.default_rng(1)
    free = np.argwhere(np.isfinite(costs))
    times, unreachable, pairs = [], 0, []
    while len(times) < plans:
        a, b = free[rng.integers(len(free))], free[rng.integers(len(free))]
        start = time.perf_counter()
        try:
            planner.plan(grid.point(*a), grid.point(*b))
            pairs.append((tuple(a), tuple(b), time.perf_counter() - start))
        except Unreachable:
            unreachable += 1
        times.append(time.perf_counter() - start)
    median = float(np.median(times))
    assert float(costs[np.isfinite(costs)].min()) >= 1.0  # the heuristic is admissible and consistent
    graph = grid_graph(planner.costs)
    rates = [must_expand(graph, planner.costs, a, b) / seconds for a, b, seconds in pairs[:EXPANSION_SAMPLES]]
    return {
        "bench": "plan_1000x1000",
        "plans": plans,
        "median_ms": round(median * 1e3, 2),
        "p90_ms": round(float(np.percentile(times, 90)) * 1e3, 2),
        "max_ms": round(max(times) * 1e3, 2),
        "target_ms": TARGET_MS,
        "cells_expanded_per_s_median": round(float(np.median(rates))),
        "expansion_samples": len(rates),
        "map_cells_per_s": round(grid.data.size / median),
        "unreachable": unreachable,
        "costmap_build_s": round(costmap_s, 3),
    }


PAPER_TABLE_2 = {"mean": [0.04, 3.554, 2.788], "std": [3.35865, 4.8022972, 4.8253035]}  # x cm, y cm, theta deg


def bench_final_pose(goals: int, seed: int = 11) -> dict[str, Any]:
    return final_pose_run(goals, seed)[0]


def final_pose_run(goals: int, seed: int) -> tuple[dict[str, Any], np.ndarray]:
    """The Table 2 protocol once: its figures, and each goal's error (x cm, y cm, theta deg)."""
    from botstage.skills.navigate import Navigate
    from tests.bench.navsim import NavSim

    sim = NavSim("museum", "peoplebot", "hall_centre", seed=seed)
    rng = np.random.default_rng(seed)
    errors, estimate_errors, outcomes = [], [], []
    start = time.perf_counter()
    while len(errors) < goals:
        pose = sim.stack.pose()
        distance, direction, heading = rng.uniform(1, 2), rng.uniform(-math.pi, math.pi), rng.uniform(-math.pi, math.pi)
        goal = (pose.x + distance * math.cos(direction), pose.y + distance * math.sin(direction), heading)
        if not sim.stack.free(goal[0], goal[1], margin=0.3) or math.hypot(goal[0] - 11, goal[1] - 10) > 4:
            continue  # on open floor of the hall, as the paper's test area
        outcome = sim.run(Navigate(), goal=list(goal), tolerance=0.02, heading_tolerance=0.02)
        outcomes.append(outcome.name)
        truth, estimate = sim.truth, sim.stack.pose()
        c, s = math.cos(goal[2]), math.sin(goal[2])
        dx, dy = truth.x - goal[0], truth.y - goal[1]
        errors.append(
            (
                100 * (c * dx + s * dy),
                100 * (-s * dx + c * dy),
                math.degrees(math.remainder(truth.theta - goal[2], 2 * math.pi)),
            )
        )
        estimate_errors.append(
            (
                100 * (estimate.x - truth.x),
                100 * (estimate.y - truth.y),
                math.degrees(math.remainder(estimate.theta - truth.theta, 2 * math.pi)),
            )
        )
    err, est = np.array(errors), np.array(estimate_errors)
    mean, std = err.mean(axis=0), err.std(axis=0, ddof=1)
    better = [bool(abs(m) < p) for m, p in zip(mean, PAPER_TABLE_2["mean"], strict=True)] + [
        bool(s < p) for s, p in zip(std, PAPER_TABLE_2["std"], strict=True)
    ]
    return {
        "bench": "final_pose_table2",
        "goals": goals,
        "succeeded": outcomes.count("succeeded"),
        "mean_error": [round(float(v), 3) for v in mean],  # x cm, y cm, theta deg (signed, as the paper)
        "std": [round(float(v), 3) for v in std],
        "mean_abs_error": [round(float(v), 3) for v in np.abs(err).mean(axis=0)],
        "paper_mean": PAPER_TABLE_2["mean"],
        "paper_std": PAPER_TABLE_2["std"],
        "better_than_paper": dict(
            zip(["mean_x", "mean_y", "mean_theta", "std_x", "std_y", "std_theta"], better, strict=True)
        ),
        "estimate_vs_true_mean": [round(float(v), 3) for v in est.mean(axis=0)],
        "estimate_vs_true_std": [round(float(v), 3) for v in est.std(axis=0, ddof=1)],
        "pose_source": "Localizer: odometry + laser scan matching on the map (the PeopleBot has no IMU)",
        "wall_s": round(time.perf_counter() - start, 2),
    }, err


def bench_final_pose_seeds(seeds: tuple[int, ...], goals: int) -> dict[str, Any]:
    """The protocol again on other seeds: a mean over 50 goals moves by about std / sqrt(50)
    from run to run, so one run's |mean| below the paper's 0.04 cm is partly luck; this shows how
    often it holds, and the mean over all goals."""
    runs, errors = zip(*(final_pose_run(goals, seed) for seed in seeds), strict=True)
    means = np.array([run["mean_error"] for run in runs])
    pooled = np.concatenate(errors)
    return {
        "bench": "final_pose_table2_seeds",
        "seeds": list(seeds),
        "goals_each": goals,
        "mean_x_per_seed": [round(float(v), 3) for v in means[:, 0]],
        "runs_better_on_every_column": sum(all(run["better_than_paper"].values()) for run in runs),
        "pooled_mean_error": [round(float(v), 3) for v in pooled.mean(axis=0)],
        "pooled_std": [round(float(v), 3) for v in pooled.std(axis=0, ddof=1)],
        "pooled_standard_error": [round(float(v), 3) for v in pooled.std(axis=0, ddof=1) / math.sqrt(len(pooled))],
    }


def missed(results: list[dict[str, Any]]) -> list[str]:
    """The benches whose median time is over their target."""
    return [r["bench"] for r in results if r.get("median_ms", 0) > r.get("target_ms", float("inf"))]


def main(quick: bool = False) -> list[dict[str, Any]]:
    headline = bench_final_pose(10 if quick else 50)
    results = [bench_planning(10 if quick else 50), headline]
    results.append(bench_final_pose_seeds((12, 13) if quick else (12, 13, 14, 15, 16, 17, 18, 19), 10 if quick else 50))
    for result in results:
        print(json.dumps(result), flush=True)
    from tests.bench import bench_localization  # pose drift over the 56 m loop: prints its own

    return results + bench_localization.main(quick=quick)


if __name__ == "__main__":
    main()
