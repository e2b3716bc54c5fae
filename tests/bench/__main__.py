"""`python -m tests.bench NAME`: run a benchmark from a checkout (`--quick`: a smoke run).

Every figure in the docs' benchmarks page comes from one of these commands; each prints its
figures as JSON lines and says on stderr what missed its target. `train-speech` makes the speech
skill's shipped command classifier (skills/speech/models/commands.npz).
"""

from __future__ import annotations

import sys
from pathlib import Path

import typer


def _stderr(lines: list[str]) -> None:
    sys.stderr.write("".join(line + "\n" for line in lines))
    sys.stderr.flush()


def _fail(line: str, code: int) -> typer.Exit:
    _stderr([line])
    return typer.Exit(code)


bench_app = typer.Typer(
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_show_locals=False,
    help="Benchmarks: figures and ratios against a baseline run alongside; and the speech-model trainer.",
)


@bench_app.command("tick")
def bench_tick(quick: bool = typer.Option(False, help="fewer repeats: a smoke run, not figures to quote")) -> None:
    """Engine tick cost vs plain py_trees, machine trigger cost vs raw transitions, 10,000 sim ticks."""
    from tests.bench import bench_tick as bench

    over = bench.missed(bench.main(quick=quick))
    if over and not quick:
        _stderr([f"over target: {', '.join(over)}"])


@bench_app.command("sim")
def bench_sim(quick: bool = typer.Option(False, help="a shorter run: a smoke test, not figures to quote")) -> None:
    """Simulation speed of the PeopleBot in the museum with 20 people and the laser at 10 Hz."""
    from tests.bench import bench_sim as bench

    slow = bench.missed(bench.main(quick=quick))
    if slow and not quick:
        _stderr([f"under target: {', '.join(slow)}"])


@bench_app.command("nav")
def bench_nav(quick: bool = typer.Option(False, help="fewer plans: a smoke test, not figures to quote")) -> None:
    """Planning time on a 1000 x 1000-cell map; final pose accuracy (the paper's Table 2); pose drift on a loop."""
    from tests.bench import bench_nav as bench

    slow = bench.missed(bench.main(quick=quick))
    if slow and not quick:
        _stderr([f"over target: {', '.join(slow)}"])


@bench_app.command("chat")
def bench_chat(quick: bool = typer.Option(False, help="fewer repeats: a smoke test, not figures to quote")) -> None:
    """Maya's brain: learning the AIML against loading the cached brain; reply latency; memory."""
    from tests.bench import bench_chat as bench

    slow = bench.missed(bench.main(quick=quick))
    if slow and not quick:
        _stderr([f"under target: {', '.join(slow)}"])


@bench_app.command("crowd")
def bench_crowd(quick: bool = typer.Option(False, help="fewer trials: a smoke test, not figures to quote")) -> None:
    """Crowd centre-of-mass error against the simulator's truth (the paper's figure); cost per frame."""
    from tests.bench import bench_crowd as bench

    over = bench.missed(bench.main(quick=quick))
    if over and not quick:
        _stderr([f"target missed: {', '.join(over)}"])


@bench_app.command("bittle")
def bench_bittle(quick: bool = typer.Option(False, help="fewer commands and seeds: a smoke test")) -> None:
    """Bittle's NyBoard driver (parser, token latency, acknowledgement round trip) and its gait odometry."""
    from tests.bench import bench_bittle as bench

    missed = bench.missed(bench.main(quick=quick))
    if missed and not quick:
        _stderr([f"target missed: {', '.join(missed)}"])


@bench_app.command("gesture")
def bench_gesture(quick: bool = typer.Option(False, help="fewer samples, a shorter stream: a smoke test")) -> None:
    """The gesture controller: rosserial parser and IMU sample latency; the chapter's converter vs the fixed one."""
    from tests.bench import bench_gesture as bench

    missed = bench.missed(bench.main(quick=quick))
    if missed and not quick:
        _stderr([f"target missed: {', '.join(missed)}"])


@bench_app.command("facetracker")
def bench_facetracker(quick: bool = typer.Option(False, help="fewer frames, one walking speed: a smoke test")) -> None:
    """The face tracker: detection rate at 640x480; pixel error on a walk and re-centring, fixed vs proportional."""
    from tests.bench import bench_facetracker as bench

    missed = bench.missed(bench.main(quick=quick))
    if missed and not quick:
        _stderr([f"target missed: {', '.join(missed)}"])


@bench_app.command("upload")
def bench_upload(quick: bool = typer.Option(False, help="fewer photos: a smoke test, not figures to quote")) -> None:
    """Photos through the durable outbox to the local gallery against a plain HTTP POST; the paper's 3.26 MB photo."""
    from tests.bench import bench_upload as bench

    slow = bench.missed(bench.main(quick=quick))
    if slow and not quick:
        _stderr([f"under target: {', '.join(slow)}"])


@bench_app.command("entertainer")
def bench_entertainer(quick: bool = typer.Option(False, help="one seed, 2 minutes: a smoke test")) -> None:
    """The default mission's wall time for 10 simulated minutes (target < 60 s), on several seeds."""
    from tests.bench import bench_entertainer as bench

    slow = bench.missed(bench.main(quick=quick))
    if slow and not quick:
        raise typer.Exit(1)


@bench_app.command("serial")
def bench_serial(quick: bool = typer.Option(False, help="smaller buffers, fewer commands: a smoke test")) -> None:
    """Chefbot's Launchpad link: lines parsed per second (parser alone and through a pty), command latency."""
    from tests.bench import bench_serial as bench

    missed = bench.missed(bench.main(quick=quick))
    if missed and not quick:
        _stderr([f"target missed: {', '.join(missed)}"])


@bench_app.command("delivery")
def bench_delivery(quick: bool = typer.Option(False, help="one seed: a smoke test, not figures to quote")) -> None:
    """Chefbot's delivery mission: time per delivery; final pose error, odometry alone vs EKF vs map."""
    from tests.bench import bench_delivery as bench

    short = bench.missed(bench.main(quick=quick))
    if short and not quick:
        _stderr([f"orders failed with seeds: {', '.join(short)}"])


@bench_app.command("speech")
def bench_speech(
    quick: bool = typer.Option(False, help="three voices, one speed, three conditions: a smoke test"),
    tune: bool = typer.Option(False, help="sweep pocketsphinx's thresholds on the tuning voices instead"),
    only: str = typer.Option(None, help="one recogniser (embedding or pocketsphinx) instead of both side by side"),
) -> None:
    """Both command recognisers side by side: rate per word (clean, white and pink noise at 20 and
    10 dB), false accepts, real-time factor with the VAD."""
    from tests.bench import bench_speech as bench

    if only not in (None, "embedding", "pocketsphinx"):
        _stderr([f"error: --only must be embedding or pocketsphinx, got {only!r}"])
        raise typer.Exit(2)
    results = bench.main(quick=quick, sweep=tune, only=only)
    if not results and not tune:
        raise typer.Exit(1)  # espeak-ng missing: said why
    missed = bench.missed(results)
    if missed and not quick:
        _stderr([f"under target: {', '.join(missed)}"])


@bench_app.command("validate")
def bench_validate(quick: bool = typer.Option(False, help="2,000 nodes, one repeat: a smoke test")) -> None:
    """`validate` of 20,000-node missions (target < 5 s) against yaml.safe_load of the same file."""
    from tests.bench import bench_validate as bench

    slow = bench.missed(bench.main(quick=quick))
    if slow and not quick:
        _stderr([f"over target: {', '.join(slow)}"])


@bench_app.command("zenoh")
def bench_zenoh(
    quick: bool = typer.Option(False, help="fewer calls, shorter streams, 30 s of mission: a smoke test"),
    calls: int | None = typer.Option(None, min=1, help="skill calls timed each way (default 2000; 200 with --quick)"),
    seconds: float | None = typer.Option(
        None, min=0.1, help="each stream window's length in s (default 10; 2 with --quick)"
    ),
    seed: int = typer.Option(1, min=0, help="the entertainer's seed, the same for both runs"),
    until: float | None = typer.Option(
        None, min=0.1, help="the entertainer's mission time in s (default: the whole mission; 30 with --quick)"
    ),
    only: list[str] | None = typer.Option(
        None,
        help="run only these benches (repeat or comma list): skill_call, stream_scan, stream_image, entertainer",
    ),
) -> None:
    """Remote skill calls and sensor streams against raw Zenoh; the entertainer on five processes against one."""
    from tests.bench import bench_zenoh as bench

    try:
        bench.selected(only)
    except ValueError as error:
        raise typer.BadParameter(str(error), param_hint="--only") from None
    missed = bench.missed(bench.main(quick=quick, calls=calls, seconds=seconds, seed=seed, until=until, only=only))
    if missed and not quick:
        _stderr([f"target missed: {', '.join(missed)}"])


@bench_app.command("monitor")
def bench_monitor(
    quick: bool = typer.Option(False, help="shorter runs, one repeat: a smoke test (about a minute)"),
) -> None:
    """The live monitor with a real page (headless Chromium): tick cost with the page against without
    (target <= 1.1x), status-to-page latency (p99 <= 200 ms), a 2,000-node tree's frames per second,
    the page's memory over a simulated hour."""
    from tests.bench import bench_monitor as bench

    results = bench.main(quick=quick)
    if not results:
        raise typer.Exit(1)  # Playwright or chromium missing: said why
    missed = bench.missed(results)
    if missed:
        _stderr([f"target missed: {', '.join(missed)}"])
        if not quick:
            raise typer.Exit(1)


@bench_app.command("train-speech")
def train_speech_command(
    out: Path = typer.Option(
        None, help="where to write the weights (default: the shipped skills/speech/models/commands.npz)"
    ),
    quick: bool = typer.Option(
        False, help="8 training voices: a smoke run, not weights to ship (written to ./commands-quick.npz unless --out)"
    ),
    cache: Path = typer.Option(None, help="a folder to keep the training features in between runs"),
    workers: int = typer.Option(2, min=1, help="processes synthesising and embedding"),
    thresholds_only: bool = typer.Option(
        False,
        "--thresholds-only",
        help="keep the network of the weights at --out (default: the shipped ones) and choose its thresholds "
        "again on the tuning set",
    ),
) -> None:
    """Train the command classifier on espeak-ng speech (needs espeak-ng); see tests/bench/train_speech.py."""
    import shutil

    from tests.bench import train_speech

    if shutil.which("espeak-ng") is None:
        raise _fail("error: espeak-ng is missing: training makes its audio with it (apt-get install espeak-ng)", 1)
    if thresholds_only:
        if out is not None and not out.exists():
            raise _fail(f"error: --thresholds-only: no weights at {out}", 2)
        train_speech.rethreshold(out, cache, workers)
        return
    train_speech.main(out, quick, cache, workers)


if __name__ == "__main__":
    bench_app(prog_name="python -m tests.bench")
