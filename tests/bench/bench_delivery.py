"""Delivery benchmark: Chefbot's delivery mission in the restaurant (the book's hotel stand-in).

Runs ``missions/examples/chefbot_delivery.yaml`` on the simulator for several seeds, as shipped (three
orders: tables 2, 4 and 6) and reports:

- **time per delivery**, in mission (sim) seconds: from leaving the kitchen loaded to the
  guest's confirmation (drive, announce, hear YES), and the whole round trip (until the robot
  is back at the kitchen); and the wall time the simulator needed per delivery;
- **pose error at the end of a run** against the simulator's ground truth, for three
  estimators on the same devices: the wheel odometry alone, the EKF (odometry + the MPU-6050's
  gyro, no map) and the map-corrected localiser the mission navigates with (+ the depth
  camera's scan matched to the map). The first two ride along passively: they are read
  between ticks and never steer.

Run with ``python -m tests.bench delivery`` (``--quick``: one seed).
"""

from __future__ import annotations

import json
import math
import statistics
import tempfile
from pathlib import Path
from typing import Any

from botstage.behaviors.engine import Engine
from botstage.missions import EXAMPLES_DIR
from botstage.missions.runner import run
from botstage.robots import PROFILES_DIR
from botstage.robots.interfaces import Pose2D
from botstage.robots.profile import load_profile
from botstage.skills.nav.ekf import wrap
from botstage.skills.nav.localization import Localizer

MISSION = EXAMPLES_DIR / "chefbot_delivery.yaml"
SEEDS = (1, 2, 3, 4, 5)


class Riders:
    """The odometry-only and EKF estimates, updated before every tick from the run's devices."""

    def __init__(self) -> None:
        self.ekf: Localizer | None = None
        self.odometry: Any = None

    def __call__(self, engine: Engine) -> None:
        if self.ekf is None:
            profile, _, _ = load_profile(PROFILES_DIR / "chefbot.yaml")
            devices = engine.interfaces
            self.odometry = devices["odometry"]
            self.ekf = Localizer.for_devices({"odometry": devices["odometry"], "imu": devices["imu"]}, None, profile)
        self.ekf.update()

    def final(self) -> tuple[Pose2D, Pose2D]:
        assert self.ekf is not None
        self.ekf.update()
        return self.odometry.read().pose, self.ekf.estimate().pose


def error(estimate: list[float] | Pose2D, truth: list[float]) -> tuple[float, float]:
    """Position error (cm) and heading error (deg)."""
    x, y, theta = (estimate.x, estimate.y, estimate.theta) if isinstance(estimate, Pose2D) else estimate
    return math.hypot(x - truth[0], y - truth[1]) * 100, math.degrees(abs(wrap(theta - truth[2])))


def deliveries(trace: Path) -> list[dict[str, float]]:
    """Per delivered order: when the robot left the kitchen loaded, when the guest confirmed,
    and when it was back at the kitchen."""
    found: list[dict[str, float]] = []
    current: dict[str, float] = {}
    for line in trace.read_text(encoding="utf-8").splitlines():
        event = json.loads(line)
        if event["ev"] == "transition" and event["source"] == "loading" and event["dest"] == "going":
            current = {"left": event["t"]}
        elif event["ev"] == "skill_outcome" and event["skill"] == "finish_order" and "delivered" in event["reason"]:
            current["confirmed"] = event["t"]
        elif event["ev"] == "transition" and event["source"] == "returning" and "confirmed" in current:
            current["back"] = event["t"]
            found.append(current)
            current = {}
    return found


def bench_seed(seed: int, folder: Path) -> dict[str, Any]:
    riders = Riders()
    result = run(MISSION, seed=seed, out=folder / f"seed{seed}", before_tick=riders)
    summary = result.summary
    truth = summary["sim"]["final_pose"]
    odometry, ekf = riders.final()
    done = deliveries(folder / f"seed{seed}" / "trace.jsonl")
    return {
        "seed": seed,
        "outcome": result.outcome,
        "delivered": summary["counters"]["delivered"],
        "failed": len(summary["counters"]["failed"]),
        "sim_s": summary["sim_time_s"],
        "wall_s": summary["wall_time_s"],
        "distance_m": summary["sim"]["distance_m"],
        "to_confirmation_s": [round(d["confirmed"] - d["left"], 1) for d in done],
        "round_trip_s": [round(d["back"] - d["left"], 1) for d in done],
        "final_error": {
            "odometry": [round(v, 2) for v in error(odometry, truth)],
            "ekf": [round(v, 2) for v in error(ekf, truth)],
            "map": [summary["localization"]["final_error_cm"], summary["localization"]["final_error_deg"]],
        },
    }


def missed(results: list[dict[str, Any]]) -> list[str]:
    """The seeds with which an order failed."""
    return [str(r["seed"]) for r in results if "seed" in r and r["failed"]]


def main(quick: bool = False) -> list[dict[str, Any]]:
    seeds = SEEDS[:1] if quick else SEEDS
    results = []
    with tempfile.TemporaryDirectory(prefix="botstage-bench-delivery-") as tmp:
        for seed in seeds:
            result = bench_seed(seed, Path(tmp))
            print(json.dumps({"bench": "delivery_run", **result}), flush=True)
            results.append(result)
    delivered = sum(r["delivered"] for r in results)
    confirmations = [t for r in results for t in r["to_confirmation_s"]]
    trips = [t for r in results for t in r["round_trip_s"]]

    def mean_of(name: str, index: int) -> float:
        return round(statistics.fmean(r["final_error"][name][index] for r in results), 2)

    summary = {
        "bench": "delivery",
        "runs": len(results),
        "orders": sum(r["delivered"] + r["failed"] for r in results),
        "delivered": delivered,
        "to_confirmation_s": {"median": statistics.median(confirmations), "max": max(confirmations)},
        "round_trip_s": {"median": statistics.median(trips), "max": max(trips)},
        "wall_s_per_delivery": round(sum(r["wall_s"] for r in results) / max(delivered, 1), 2),
        "sim_s_per_delivery_whole_run": round(sum(r["sim_s"] for r in results) / max(delivered, 1), 1),
        "final_error_mean": {
            name: {"cm": mean_of(name, 0), "deg": mean_of(name, 1)} for name in ("odometry", "ekf", "map")
        },
        "final_error_max_cm": {
            name: max(r["final_error"][name][0] for r in results) for name in ("odometry", "ekf", "map")
        },
    }
    print(json.dumps(summary), flush=True)
    return [*results, summary]


if __name__ == "__main__":
    main()
