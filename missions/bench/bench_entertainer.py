"""The PeopleBot entertainer's default run: wall time of 10 simulated minutes. Run with
`botstage bench entertainer`.

The default mission (missions/peoplebot_entertainer.yaml) runs as `botstage run` runs it — the
simulated museum with its people, the Kinect-like tracker, the rendered camera, the simulated
visitors' voices through pocketsphinx, AIML, espeak-ng speech when installed, photos to the
run's own gallery over loopback — on several seeds. Each line: wall time, how many times faster
than real time, the ratio of the 60 s target to the wall time (above 1: met), and the run's
counters, so a figure that is fast because nothing happened shows itself.
"""

from __future__ import annotations

import json
import statistics
import tempfile
from pathlib import Path
from typing import Any

from missions import DEFAULT_MISSION
from missions.runner import run

TARGET_WALL_S = 60.0  # for 600 s of mission time


def one(seed: int, until: float | None, folder: Path) -> dict[str, Any]:
    result = run(DEFAULT_MISSION, seed=seed, until=until, out=folder / f"seed-{seed}")
    summary = result.summary
    wall = summary["wall_time_s"]
    return {
        "bench": "entertainer_run",
        "seed": seed,
        "sim_s": summary["sim_time_s"],
        "wall_s": wall,
        "x_real_time": round(summary["sim_time_s"] / wall, 1),
        "target_ratio": round(TARGET_WALL_S * summary["sim_time_s"] / 600.0 / wall, 2),
        "counters": summary["counters"],
        "utterances": summary.get("sim", {}).get("utterances"),
    }


def missed(results: list[dict[str, Any]]) -> list[str]:
    """The runs slower than the 60 s target."""
    return [r["bench"] for r in results if r.get("bench") == "entertainer_run" and r["target_ratio"] < 1.0]


def main(quick: bool = False) -> list[dict[str, Any]]:
    seeds = (1,) if quick else (1, 2, 3, 4, 5)
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
    }
    print(json.dumps(summary), flush=True)
    return [*results, summary]


if __name__ == "__main__":
    main()
