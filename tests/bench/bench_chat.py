"""Chat benchmarks. Run with `python -m tests.bench chat`.

- **brain**: learning Maya's AIML (the A.L.I.C.E. set python-aiml ships plus her own: parse,
  python-aiml's PatternMgr, flatten, write the cache file) against loading the cached brain
  file, each as the converse skill and `botstage chat` do it at start-up (hashing the AIML
  files included). Target: the cached load at least 10x faster. Beside it, python-aiml's own
  brain file (``Kernel.saveBrain`` / ``loadBrain``, marshal) as the book uses it.
- **reply**: latency of one turn (routing, then the kernel) over a mix of Maya's categories,
  A.L.I.C.E. small talk, names, cues, unmatched input and commands, for several visitors; the
  first turns after a load unmarshal their templates, so the first pass is reported apart.
- **memory**: what the loaded flat brain holds (Python allocations, tracemalloc), and, in the
  full run, python-aiml's nested-dict brain of the same AIML.

The brain file is read from the page cache after the first load (a warm start, as on a robot
that restarts its mission); timings are wall-clock medians of several repeats.
"""

from __future__ import annotations

import gc
import json
import random
import statistics
import tempfile
import time
import tracemalloc
from pathlib import Path
from typing import Any

from botstage.skills.chat.cache import fingerprint, load_brain, read_brain
from botstage.skills.chat.chatbot import Chatbot
from botstage.skills.chat.persona import aiml_files

TARGET_RATIO = 10.0

PROMPTS = [
    "Hello",
    "Hi Maya!",
    "Good morning",
    "How are you?",
    "What is your name?",
    "My name is {name}",
    "What is my name?",
    "Are you a robot?",
    "What can you do?",
    "Who made you?",
    "How old are you?",
    "Where are you?",
    "What is this place?",
    "How do I look?",
    "Can you take pictures?",
    "Thank you",
    "Do you like music?",
    "What is your favorite color?",
    "Tell me a joke",
    "What is 2 plus 2?",
    "I am sad",
    "Who is your master?",
    "What is the meaning of life?",
    "Can you dance?",
    "I like turtles",
    "Do you have a body?",
    "Are you a boy or a girl?",
    "colourless green ideas sleep furiously",
    "CUE GREETING",
    "CUE INFORMATION",
    "CUE COMPLIMENT",
    "CUE GOODBYE",
    "Take a picture of us please",
    "yes",
    "What's up?",
    "never mind",
    "bye",
]
NAMES = ["Ada", "Grace", "Alan", "Edsger", "Barbara", "Donald", "Margaret", "Ken", "Frances", "Dennis"]


def _median_ms(samples: list[float]) -> float:
    return round(statistics.median(samples) * 1e3, 2)


def bench_brain(folder: Path, learn_repeats: int, load_repeats: int, baseline: bool) -> dict[str, Any]:
    """Learn into fresh cache folders under ``folder``; the last one (``folder/brain``) stays."""
    files = aiml_files()
    learn_s, load_s, hash_s, read_s = [], [], [], []
    for n in range(learn_repeats):
        cache = folder / ("brain" if n == learn_repeats - 1 else f"learn-{n}")
        gc.collect()
        learned = load_brain(files, cache)
        assert learned.origin == "learned", learned.notes
        learn_s.append(learned.seconds)
    brain_file = learned.path
    assert brain_file is not None
    for _ in range(load_repeats):
        gc.collect()
        loaded = load_brain(files, cache)
        assert loaded.origin == "cache", loaded.notes
        load_s.append(loaded.seconds)
        started = time.perf_counter()
        key = fingerprint(files)
        hash_s.append(time.perf_counter() - started)
        started = time.perf_counter()
        read_brain(brain_file, key)
        read_s.append(time.perf_counter() - started)
    size = brain_file.stat().st_size
    result: dict[str, Any] = {
        "bench": "brain_learn_vs_cached_load",
        "aiml_files": len(files),
        "aiml_bytes": sum(p.stat().st_size for p in files),
        "categories": loaded.trie.template_count,
        "edges": loaded.trie.edge_count,
        "learn_s": round(statistics.median(learn_s), 3),
        "cached_load_ms": _median_ms(load_s),
        "ratio": round(statistics.median(learn_s) / statistics.median(load_s), 1),
        "target_ratio": TARGET_RATIO,
        "of_which_hashing_aiml_ms": _median_ms(hash_s),
        "of_which_reading_brain_ms": _median_ms(read_s),
        "brain_file_mb": round(size / 2**20, 1),
        "repeats": {"learn": learn_repeats, "load": load_repeats},
    }
    if baseline:
        result["pyaiml_brain"] = _pyaiml_brain(files)
    return result


def _pyaiml_brain(files: list[Path]) -> dict[str, Any]:
    """python-aiml's own way (the book's): Kernel.learn, saveBrain, then loadBrain (marshal)."""
    import aiml

    kernel = aiml.Kernel()
    kernel.verbose(False)
    started = time.perf_counter()
    for path in files:
        kernel.learn(str(path))
    learn = time.perf_counter() - started
    with tempfile.TemporaryDirectory() as folder:
        brain = str(Path(folder) / "standard.brn")
        kernel.saveBrain(brain)
        del kernel
        gc.collect()
        fresh = aiml.Kernel()
        fresh.verbose(False)
        started = time.perf_counter()
        fresh.loadBrain(brain)
        load = time.perf_counter() - started
    return {"learn_s": round(learn, 3), "load_brain_s": round(load, 3), "ratio": round(learn / load, 2)}


def bench_replies(cache: Path, passes: int, visitors: int) -> dict[str, Any]:
    brain = load_brain(aiml_files(), cache)
    maya = Chatbot(brain.trie, seed=1)
    rng = random.Random(2)
    first: list[float] = []
    later: list[float] = []
    commands = 0
    for n in range(passes):
        for v in range(visitors):
            name = NAMES[v % len(NAMES)]
            for prompt in PROMPTS:
                text = prompt.format(name=name)
                started = time.perf_counter()
                turn = maya.turn(text, f"visitor-{v}", rng)
                elapsed = time.perf_counter() - started
                (first if n == 0 and v == 0 else later).append(elapsed)
                commands += turn.command is not None
    every = first + later
    return {
        "bench": "reply_latency",
        "turns": len(every),
        "commands": commands,
        "median_ms": _median_ms(every),
        "p99_ms": round(sorted(every)[int(0.99 * (len(every) - 1))] * 1e3, 2),
        "max_ms": round(max(every) * 1e3, 2),
        "first_pass_median_ms": _median_ms(first),
        "first_pass_max_ms": round(max(first) * 1e3, 2),
    }


def bench_memory(cache: Path, native: bool) -> dict[str, Any]:
    files = aiml_files()
    gc.collect()
    tracemalloc.start()
    loaded = load_brain(files, cache)
    held, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    result: dict[str, Any] = {
        "bench": "brain_memory",
        "flat_brain_held_mb": round(held / 2**20, 1),
        "flat_brain_load_peak_mb": round(peak / 2**20, 1),
        "origin": loaded.origin,
    }
    if native:
        import aiml

        del loaded
        gc.collect()
        tracemalloc.start()
        kernel = aiml.Kernel()
        kernel.verbose(False)
        for path in files:
            kernel.learn(str(path))
        gc.collect()
        result["pyaiml_dict_brain_held_mb"] = round(tracemalloc.get_traced_memory()[0] / 2**20, 1)
        tracemalloc.stop()
    return result


def missed(results: list[dict[str, Any]]) -> list[str]:
    """The benches whose speed-up is under their target ratio."""
    return [r["bench"] for r in results if r.get("ratio", float("inf")) < r.get("target_ratio", 0)]


def main(quick: bool = False) -> list[dict[str, Any]]:
    results = []
    with tempfile.TemporaryDirectory(prefix="botstage-bench-chat-") as folder:
        cache = Path(folder) / "brain"
        for bench in (
            lambda: bench_brain(Path(folder), 1 if quick else 3, 3 if quick else 15, baseline=not quick),
            lambda: bench_replies(cache, 1 if quick else 5, 2 if quick else 10),
            lambda: bench_memory(cache, native=not quick),
        ):
            results.append(bench())
            print(json.dumps(results[-1]), flush=True)
    return results


if __name__ == "__main__":
    main()
