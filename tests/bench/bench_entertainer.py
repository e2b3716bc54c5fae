"""The PeopleBot entertainer's default run: wall time of 10 simulated minutes, and bumps. Run
with `python -m tests.bench entertainer`.

The default mission (missions/examples/peoplebot_entertainer.yaml) runs as `botstage run` runs it — the
simulated museum with its people, the Kinect-like tracker, the rendered camera, the simulated
visitors' voices through pocketsphinx, AIML, espeak-ng speech when installed, photos to the
run's own gallery over loopback — on seeds 1 to 10. Each line: wall time, how many times faster
than real time, the ratio of the 60 s target to the wall time (above 1: met), the run's
counters, so a figure that is fast because nothing happened shows itself, and its bumps (contact
events, into walls and into people): the target is none.
"""

from __future__ import annotations

import json
import statistics
import tempfile
from pathlib import Path
from typing import Any

from botstage.missions import DEFAULT_MISSION
from botstage.missions.runner import run

TARGET_WALL_S = 60.0  # for 600 s of mission time
SEEDS = tuple(range(1, 11))


def one(seed: int, until: float | None, folder: Path) -> dict[str, Any]:
    result = run(DEFAULT_MISSION, seed=seed, until=until, out=folder / f"seed-{seed}")
    summary = result.summary
    sim = summary.get("sim", {})
    wall = summary["wall_time_s"]
    return {
        "bench": "entertainer_run",
        "seed": seed,
        "sim_s": summary["sim_time_s"],
        "wall_s": wall,
        "x_real_time": round(summary["sim_time_s"] / wall, 1),
        "target_ratio": round(TARGET_WALL_S * summary["sim_time_s"] / 600.0 / wall, 2),
        "counters": summary["counters"],
        "utterances": sim.get("utterances"),
        "bumps": sim.get("bumps"),
        "bumps_walls": sim.get("bumps_walls"),
        "bumps_people": sim.get("bumps_people"),
    }


def missed(results: list[dict[str, Any]]) -> list[str]:
    """The runs slower than the 60 s target, and those that bumped into something."""
    runs = [r for r in results if r.get("bench") == "entertainer_run"]
    slow = [f"seed {r['seed']}: slower than {TARGET_WALL_S:g} s" for r in runs if r["target_ratio"] < 1.0]
    return slow + [f"seed {r['seed']}: {r['bumps']} bump(s)" for r in runs if r["bumps"]]


def main(quick: bool = False) -> list[dict[str, Any]]:
    seeds = (1,) if quick else SEEDS
    results = []
    with tempfile.TemporaryDirectory(prefix="botstage-bench-entertainer-") as tmp:
        for seed in seeds:
            results.append(one(seed, 120.0 if quick else None, Path(tmp)))
            print(json.dumps(results[-1]), flush=True)
    walls = [r["wall_s"] for r in results]
    met = sum(
        r["counters"]["crowds_visited"] >= 2
        and r["counters"]["photos_taken"] >= 2
        and r["counters"]["photos_uploaded"] == r["counters"]["photos_taken"]
        for r in results
    )
    summary = {
        "bench": "entertainer",
        "runs": len(results),
        "wall_s_median": round(statistics.median(walls), 2),
        "wall_s_max": round(max(walls), 2),
        "target_wall_s": TARGET_WALL_S,
        "target_ratio_worst": min(r["target_ratio"] for r in results),
        "runs_with_2_crowds_2_photos_all_uploaded": met,
        "bumps": sum(r["bumps"] or 0 for r in results),
        "runs_without_bumps": sum(not r["bumps"] for r in results),
    }
    print(json.dumps(summary), flush=True)
    return [*results, summary]


if __name__ == "__main__":
    main()
