"""Drills: bad input, as a careless user or an attacker would give it, through the real command line.

Every drill runs `botstage` in a subprocess under a memory cap (RLIMIT_AS) and a CPU cap
(RLIMIT_CPU), with a wall-clock failsafe far above what a refusal needs. Each must end in a clean
result or a clean refusal: the exit status the drill expects (1 for a refused input, 2 for a
usage error), the message it names, and never a traceback or an "internal error". The families
are the ones of issue 17: loading (aliases, special files, sizes, includes, nesting), conditions
(depth, size, repetition, powers), numbers (NaN, infinities, negatives, overflow), names
(non-ASCII), scenarios (undeclared keys), the command line (output paths, ports, numbers) and
the gallery's limits.
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
MEMORY_CAP = 1_500_000_000  # bytes of address space: a botstage process needs about a third of it
CPU_CAP = 60  # seconds of CPU
FAILSAFE = 120  # seconds of wall time: only a hang reaches it (a FIFO opened for reading, say)

TREE = "trees:\n  main: {wait: {duration: 1}}\n"
MINIMAL = "name: drill\nuntil: 5\n" + TREE


def capped() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_CAP, MEMORY_CAP))
    resource.setrlimit(resource.RLIMIT_CPU, (CPU_CAP, CPU_CAP))


@dataclass
class Drill:
    """``files`` are written into a fresh folder; ``args`` may name them by relative path."""

    name: str
    args: list[str]
    files: dict[str, str | bytes] = field(default_factory=dict)
    exit: int | tuple[int, ...] = 1
    says: str = ""  # a fragment the output must hold (the located error, the refused value)
    setup: Callable[[Path], None] | None = None


def mission(body: str, header: str = "name: drill\nuntil: 5\n") -> str:
    return header + body


def alias_bomb(levels: int, width: int) -> str:
    lines = ['a0: &a0 ["lol"]']
    for level in range(1, levels + 1):
        lines.append(f"a{level}: &a{level} [" + ", ".join([f"*a{level - 1}"] * width) + "]")
    return "\n".join(lines) + f"\nblackboard: {{bomb: *a{levels}}}\nuntil: 5\n" + TREE


def mapping_bomb(levels: int) -> str:
    lines = ["k0: &k0 {a: 1, b: 2, c: 3, d: 4, e: 5, f: 6, g: 7, h: 8, i: 9, j: 10}"]
    for level in range(1, levels + 1):
        keys = ", ".join(f"{chr(97 + n)}: *k{level - 1}" for n in range(10))
        lines.append(f"k{level}: &k{level} {{{keys}}}")
    return "\n".join(lines) + f"\nblackboard: {{bomb: *k{levels}}}\nuntil: 5\n" + TREE


def nested(depth: int) -> str:
    return mission("trees:\n  main: " + "{sequence: [" * depth + "{wait: {duration: 1}}" + "]}" * depth + "\n")


def condition(text: str, keys: str = "x: str") -> str:
    return mission(f"keys: {{{keys}}}\nblackboard: {{x: ab}}\ntrees:\n  main: {{condition: {text!r}}}\n")


def fifo(folder: Path) -> None:
    os.mkfifo(folder / "pipe.yaml")


def symlink_out(folder: Path) -> None:
    (folder / "sub").mkdir()
    (folder / "sub" / "lib.yaml").symlink_to("/etc/hostname")


DRILLS = [
    # -- loading: aliases, special files, sizes, includes, nesting --------------------------------
    Drill("alias bomb of lists", ["validate", "m.yaml"], {"m.yaml": alias_bomb(9, 10)}, says="m.yaml:"),
    Drill("alias bomb of mappings", ["validate", "m.yaml"], {"m.yaml": mapping_bomb(8)}, says="m.yaml:"),
    Drill("alias bomb, running", ["run", "m.yaml", "--out", "out"], {"m.yaml": alias_bomb(7, 9)}, says="m.yaml:"),
    Drill("the mission is /dev/zero", ["validate", "/dev/zero"], exit=(1, 2)),
    Drill("the mission is a folder", ["validate", "."], exit=(1, 2)),
    Drill("the mission is a FIFO", ["validate", "pipe.yaml"], setup=fifo, exit=(1, 2)),
    Drill("include /dev/zero", ["validate", "m.yaml"], {"m.yaml": mission("include: [/dev/zero]\n" + TREE)}),
    Drill("include a FIFO", ["validate", "m.yaml"], {"m.yaml": MINIMAL + "include: [pipe.yaml]\n"}, setup=fifo),
    Drill("include /etc/passwd", ["validate", "m.yaml"], {"m.yaml": MINIMAL + "include: [/etc/passwd]\n"}),
    Drill("include ../ escaping", ["validate", "m.yaml"], {"m.yaml": MINIMAL + "include: [../../../../etc/passwd]\n"}),
    Drill(
        "include a symlink out",
        ["validate", "m.yaml"],
        {"m.yaml": MINIMAL + "include: [sub/lib.yaml]\n"},
        setup=symlink_out,
    ),
    Drill("include a folder", ["validate", "m.yaml"], {"m.yaml": MINIMAL + "include: [.]\n"}),
    Drill("a 6 MB mission", ["validate", "m.yaml"], {"m.yaml": MINIMAL + "#" * 6_000_000 + "\n"}),
    Drill("invalid UTF-8", ["validate", "m.yaml"], {"m.yaml": b"name: \xff\xfe\nuntil: 5\n"}, says="m.yaml:"),
    Drill("binary bytes", ["validate", "m.yaml"], {"m.yaml": bytes(range(256)) * 20}, says="m.yaml:"),
    Drill("empty file", ["validate", "m.yaml"], {"m.yaml": ""}, says="m.yaml:"),
    Drill("a list, not a mapping", ["validate", "m.yaml"], {"m.yaml": "- 1\n- 2\n"}, says="m.yaml:"),
    Drill("10,000-deep node nesting", ["validate", "m.yaml"], {"m.yaml": nested(10_000)}, says="m.yaml:"),
    Drill(
        "10,000-deep list value",
        ["validate", "m.yaml"],
        {"m.yaml": mission("blackboard: {v: " + "[" * 10_000 + "]" * 10_000 + "}\n" + TREE)},
        says="m.yaml:",
    ),
    Drill("10,000-deep drawing", ["tree", "m.yaml"], {"m.yaml": nested(10_000)}, says="m.yaml:"),
    # -- conditions ---------------------------------------------------------------------------------
    Drill("2,500 nots", ["validate", "m.yaml"], {"m.yaml": condition("not " * 2500 + "x")}, says="m.yaml:"),
    Drill("9,999 minuses", ["validate", "m.yaml"], {"m.yaml": condition("-" * 9999 + "1 > 0")}, says="m.yaml:"),
    Drill(
        "500 nested brackets",
        ["validate", "m.yaml"],
        {"m.yaml": condition("(" * 500 + "1" + ")" * 500 + " > 0")},
        says="m.yaml:",
    ),
    Drill(
        "a 100 KB condition",
        ["validate", "m.yaml"],
        {"m.yaml": condition(" or ".join(["x == 'a'"] * 10_000))},
        says="m.yaml:",
    ),
    Drill(
        "repetition of a string",
        ["run", "m.yaml", "--out", "out"],
        {"m.yaml": condition("len(x * 1000000000) > 0")},
        exit=(1, 3),
    ),
    Drill(
        "repetition of a tuple",
        ["run", "m.yaml", "--out", "out"],
        {"m.yaml": condition("len((1, 2) * 1000000000) > 0")},
        exit=(1, 3),
    ),
    Drill(
        "a tower of powers", ["run", "m.yaml", "--out", "out"], {"m.yaml": condition("10 ** 10 ** 10 > 0")}, exit=(1, 3)
    ),
    # -- numbers ------------------------------------------------------------------------------------
    Drill(
        "until: .nan",
        ["validate", "m.yaml"],
        {"m.yaml": "name: d\nuntil: .nan\ntrees: {main: {wait: {duration: 1}}}\n"},
        says="finite",
    ),
    Drill(
        "until: -1",
        ["validate", "m.yaml"],
        {"m.yaml": "name: d\nuntil: -1\ntrees: {main: {wait: {duration: 1}}}\n"},
        says="until",
    ),
    Drill(
        "until: 1e308",
        ["validate", "m.yaml"],
        {"m.yaml": "name: d\nuntil: 1e308\ntrees: {main: {wait: {duration: 1}}}\n"},
        says="until",
    ),
    Drill(
        "rate_hz: .inf",
        ["validate", "m.yaml"],
        {"m.yaml": "name: d\nrate_hz: .inf\nuntil: 5\ntrees: {main: {wait: {duration: 1}}}\n"},
        says="rate_hz",
    ),
    Drill(
        "duration: .nan",
        ["validate", "m.yaml"],
        {"m.yaml": mission("trees: {main: {wait: {duration: .nan}}}\n")},
        says="m.yaml:3",
    ),
    Drill(
        "duration: -.inf",
        ["validate", "m.yaml"],
        {"m.yaml": mission("trees: {main: {wait: {duration: -.inf}}}\n")},
        says="m.yaml:3",
    ),
    Drill(
        "timeout: .nan",
        ["validate", "m.yaml"],
        {"m.yaml": mission("trees: {main: {timeout: .nan, child: {wait: {duration: 1}}}}\n")},
        says="m.yaml:3",
    ),
    Drill(
        "timeout: -3",
        ["validate", "m.yaml"],
        {"m.yaml": mission("trees: {main: {timeout: -3, child: {wait: {duration: 1}}}}\n")},
        says="m.yaml:3",
    ),
    Drill(
        "repeat: -2",
        ["validate", "m.yaml"],
        {"m.yaml": mission("trees: {main: {repeat: -2, child: {wait: {duration: 1}}}}\n")},
        says="m.yaml:3",
    ),
    Drill(
        "a state timeout of .nan",
        ["validate", "m.yaml"],
        {
            "m.yaml": mission(
                "machine:\n  initial: a\n  outcomes: [done]\n  states:\n"
                "    a: {skill: wait, inputs: {duration: 1}, timeout: .nan,\n"
                "        transitions: {success: done, failure: done, timeout: done}}\n"
            )
        },
        says="m.yaml:",
    ),
    Drill(
        "--until nan", ["run", "m.yaml", "--until", "nan", "--out", "out"], {"m.yaml": MINIMAL}, exit=2, says="finite"
    ),
    Drill(
        "--until -5", ["run", "m.yaml", "--until", "-5", "--out", "out"], {"m.yaml": MINIMAL}, exit=2, says="--until"
    ),
    Drill(
        "--until inf", ["run", "m.yaml", "--until", "inf", "--out", "out"], {"m.yaml": MINIMAL}, exit=2, says="finite"
    ),
    Drill(
        "--seed huge",
        ["run", "m.yaml", "--seed", "99999999999999999999999", "--out", "out"],
        {"m.yaml": MINIMAL},
        exit=(0, 2),
    ),
    # -- names --------------------------------------------------------------------------------------
    Drill(
        "a key of CJK characters",
        ["validate", "m.yaml"],
        {"m.yaml": mission("keys: {電池: float}\nblackboard: {電池: 50.0}\ntrees: {main: {condition: '電池 > 20'}}\n")},
        exit=0,
    ),
    Drill(
        "a key that is no identifier",
        ["validate", "m.yaml"],
        {"m.yaml": mission("keys: {'a b': float}\ntrees: {main: {wait: {duration: 1}}}\n")},
        says="m.yaml:3",
    ),
    Drill(
        "a name in Japanese",
        ["run", "m.yaml", "--out", "out"],
        {"m.yaml": MINIMAL.replace("drill", "見学ツアー")},
        exit=0,
    ),
    Drill(
        "a name with a slash",
        ["validate", "m.yaml"],
        {"m.yaml": MINIMAL.replace("drill", "../../evil")},
        says="m.yaml:1",
    ),
    # -- scenarios ----------------------------------------------------------------------------------
    Drill(
        "a scenario naming an undeclared key",
        ["test", "s/case.yaml"],
        {
            "m.yaml": mission("keys: {loops: int}\nblackboard: {loops: 0}\ntrees: {main: {wait: {duration: 1}}}\n"),
            "s/case.yaml": "mission: ../m.yaml\nexpect:\n  never: ['lops >= 1']\n",
        },
        says="case.yaml:3",
    ),
    # -- the command line ---------------------------------------------------------------------------
    Drill(
        "--out under /proc",
        ["run", "m.yaml", "--out", "/proc/nope"],
        {"m.yaml": MINIMAL},
        exit=(1, 2),
        says="/proc/nope",
    ),
    Drill(
        "--out is a file",
        ["run", "m.yaml", "--out", "afile"],
        {"m.yaml": MINIMAL, "afile": "x"},
        exit=(1, 2),
        says="afile",
    ),
    Drill(
        "--out /dev/null", ["run", "m.yaml", "--out", "/dev/null"], {"m.yaml": MINIMAL}, exit=(1, 2), says="/dev/null"
    ),
    Drill("gallery --port 70000", ["gallery", "--port", "70000", "--dir", "g"], exit=2, says="--port"),
    Drill("gallery --port -1", ["gallery", "--port", "-1", "--dir", "g"], exit=2, says="--port"),
    Drill("gallery --max-mb nan", ["gallery", "--max-mb", "nan", "--dir", "g"], exit=2, says="--max-mb"),
    Drill("gallery --max-mb 0", ["gallery", "--max-mb", "0", "--dir", "g"], exit=2, says="--max-mb"),
    Drill(
        "tree --at -4",
        ["tree", "m.yaml", "--trace", "t.jsonl", "--at", "-4"],
        {"m.yaml": MINIMAL, "t.jsonl": ""},
        exit=2,
        says="--at",
    ),
    Drill(
        "a trace of garbage",
        ["tree", "m.yaml", "--trace", "t.jsonl", "--at", "1"],
        {"m.yaml": MINIMAL, "t.jsonl": "{not json\n\x00\x01"},
        exit=(1, 2),
        says="t.jsonl",
    ),
    Drill(
        "from-trace of garbage",
        ["scenario", "from-trace", "t.jsonl", "-o", "s.yaml"],
        {"t.jsonl": "]]]\n"},
        exit=(1, 2),
        says="t.jsonl",
    ),
    Drill("from-trace of /dev/zero", ["scenario", "from-trace", "/dev/zero", "-o", "s.yaml"], exit=(1, 2)),
    Drill("places of /dev/zero", ["places", "/dev/zero"], exit=(1, 2)),
    Drill("an unknown map", ["places", "atlantis"], exit=2, says="atlantis"),
    Drill(
        "machine -f json", ["machine", str(ROOT / "missions/examples/peoplebot_entertainer.yaml"), "-f", "json"], exit=0
    ),
    Drill(
        "machine -f unicode",
        ["machine", str(ROOT / "missions/examples/peoplebot_entertainer.yaml"), "-f", "unicode"],
        exit=0,
    ),
    Drill("speech on a text file", ["speech", "recognize", "a.wav"], {"a.wav": "not audio"}, exit=(1, 2), says="a.wav"),
]


@pytest.mark.parametrize("drill", DRILLS, ids=[d.name for d in DRILLS])
def test_drill(drill: Drill, tmp_path: Path) -> None:
    for name, content in drill.files.items():
        path = tmp_path / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(content if isinstance(content, bytes) else content.encode())
    if drill.setup is not None:
        drill.setup(tmp_path)
    env = {**os.environ, "PYTHONPATH": str(ROOT), "COLUMNS": "200", "BOTSTAGE_CACHE_DIR": str(tmp_path / "cache")}
    done = subprocess.run(
        [sys.executable, "-m", "botstage.missions.cli", *drill.args],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        errors="replace",
        preexec_fn=capped,
        timeout=FAILSAFE,
        env=env,
    )
    output = done.stdout + done.stderr
    expected = drill.exit if isinstance(drill.exit, tuple) else (drill.exit,)
    assert done.returncode in expected, f"exit {done.returncode}, expected {expected}:\n{output[-3000:]}"
    assert "Traceback" not in output, output[-3000:]
    assert "internal error" not in output, output[-3000:]
    assert "MemoryError" not in output and "RecursionError" not in output, output[-3000:]
    assert drill.says in output, f"{drill.says!r} not in:\n{output[-3000:]}"
