"""`botstage validate` on large missions, against parsing the same file with plain PyYAML.

Two missions of 20,000 tree nodes, written to a temporary folder: 20,000 `wait` siblings in one
sequence (the shape that once made checking cubic), and the same count spread over nested
selectors, sequences, guards and timeouts with conditions, subtrees and a machine around them.
Each row gives the check's time (the whole of `botstage.missions.check.check`: reading, YAML, the
mission's keys, building every node, machines, key usage), `yaml.safe_load` of the same file
in the same run as the baseline, and their ratio. Target: under 5 s for 20,000 nodes.

Run with ``python -m tests.bench validate``.
"""

from __future__ import annotations

import json
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import yaml

from botstage.missions import EXAMPLES_DIR
from botstage.missions.check import check

NODES = 20_000
TARGET_S = 5.0


def siblings(nodes: int) -> str:
    """``nodes`` wait leaves side by side in one sequence."""
    lines = ["name: siblings", "trees:", "  main:", "    sequence:"]
    lines += ["      - wait: {duration: 1}"] * (nodes - 1)
    return "\n".join(lines) + "\n"


def mixed(nodes: int) -> str:
    """About ``nodes`` nodes in nested composites, guards and timeouts, a subtree and a machine."""
    group = [
        "        - selector:",
        "            - while: battery_pct > 20 and not estop",
        "              child:",
        "                timeout: 30",
        "                child:",
        "                  sequence:",
        "                    - condition: len(people) >= 2 or battery_pct < 90",
        "                    - wait: {duration: 1}",
        "                    - set: {key: visits, value: 1}",
        "            - subtree: rest",
    ]
    per_group = 9  # selector, while, timeout, sequence, condition, wait, set, subtree, its wait
    lines = [
        "name: mixed",
        "blackboard: {battery_pct: 80, estop: false, people: [], visits: 0}",
        "trees:",
        "  rest: {wait: {duration: 2}}",
        "  main:",
        "    sequence:",
    ]
    for _ in range(max(nodes // per_group, 1)):
        lines += group
    lines += [
        "machine:",
        "  states:",
        "    work:",
        "      tree: main",
        "      timeout: 600",
        "      transitions: {success: success, failure: failure, timeout: failure}",
        "  preemptions:",
        "    - {when: estop, to: failure}",
    ]
    return "\n".join(lines) + "\n"


def _best(fn: Callable[[], Any], repeats: int) -> tuple[float, float]:
    """The shortest wall time of ``repeats`` runs, and the CPU time of that run (a loaded machine
    stretches the first, not the second)."""
    times = []
    for _ in range(repeats):
        start, cpu = time.perf_counter(), time.process_time()
        fn()
        times.append((time.perf_counter() - start, time.process_time() - cpu))
    return min(times)


def bench(name: str, text: str, nodes: int, folder: Path, repeats: int) -> dict[str, Any]:
    path = folder / f"{name}.yaml"
    path.write_text(text, encoding="utf-8")
    checked = check(path)
    assert checked.ok, [str(p) for p in checked.problems[:3]]
    validate_s, validate_cpu_s = _best(lambda: check(path), repeats)
    safe_load_s, safe_load_cpu_s = _best(lambda: yaml.safe_load(path.read_text(encoding="utf-8")), repeats)
    return {
        "bench": f"validate_{name}",
        "nodes": nodes,
        "file_kb": round(len(text.encode()) / 1024),
        "validate_s": round(validate_s, 3),
        "validate_cpu_s": round(validate_cpu_s, 3),
        "baseline": "yaml.safe_load of the same file",
        "baseline_s": round(safe_load_s, 3),
        "baseline_cpu_s": round(safe_load_cpu_s, 3),
        "ratio_vs_baseline": round(validate_s / safe_load_s, 2),
        "target_s": TARGET_S * nodes / NODES,
    }


def missed(results: list[dict[str, Any]]) -> list[str]:
    """The benches slower than their target."""
    return [r["bench"] for r in results if r["validate_s"] > r["target_s"]]


def main(quick: bool = False) -> list[dict[str, Any]]:
    nodes = 2_000 if quick else NODES
    repeats = 1 if quick else 3
    check(EXAMPLES_DIR / "hello.yaml")  # skills and node kinds loaded once, outside the timing
    results = []
    with tempfile.TemporaryDirectory(prefix="botstage-bench-") as folder:
        for name, make in (("siblings", siblings), ("mixed", mixed)):
            result = bench(name, make(nodes), nodes, Path(folder), repeats)
            print(json.dumps(result), flush=True)
            results.append(result)
    return results


if __name__ == "__main__":
    main()
