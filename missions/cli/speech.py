"""Speech verbs: the listen skill's recogniser on WAV files."""

from __future__ import annotations

import sys
from pathlib import Path

import typer
from botstage.missions.cli.common import _fail, _stderr

speech_app = typer.Typer(no_args_is_help=True, help="Speech: the listen skill's recogniser on WAV files.")


@speech_app.command("recognize")
def speech_recognize(
    files: list[Path] = typer.Argument(..., help="WAV files: 16 kHz mono 16-bit PCM"),
    mode: str = typer.Option("command", help="command (PHOTO, YES, WHATSUP, CANCEL, CIAO) or free (any English)"),
    recognizer: str = typer.Option("embedding", help="for commands: embedding (the default) or pocketsphinx"),
) -> None:
    """Print FILE<TAB>COMMAND per file (`-` when nothing was recognised); in free mode FILE<TAB>TEXT."""
    from botstage.skills.speech.recognizer import MODES, RECOGNIZERS, recognizer_named
    from botstage.skills.speech.recording import recognize_recording
    from botstage.skills.speech.wav import WavFormatError, read_wav

    if mode not in MODES:
        raise _fail(f"error: --mode must be one of {', '.join(MODES)}, got {mode!r}", 2)
    if recognizer not in RECOGNIZERS:
        raise _fail(f"error: --recognizer must be one of {', '.join(RECOGNIZERS)}, got {recognizer!r}", 2)
    chosen = recognizer_named(recognizer)
    failed = False
    for path in files:
        if path.exists() and not path.is_file():  # a folder, or a device or pipe that may never end
            _stderr([f"error: {path}: not a file"])
            failed = True
            continue
        try:
            samples = read_wav(path)
        except (OSError, WavFormatError) as exc:
            _stderr([f"error: {exc}" if isinstance(exc, WavFormatError) else f"error: {path}: {exc.strerror or exc}"])
            failed = True
            continue
        heard = recognize_recording(chosen, samples, mode)
        if heard.clipped >= 0.01:
            _stderr([f"warning: {path}: {heard.clipped:.0%} of the speech is clipped (recorded too loud)"])
        sys.stdout.write(f"{path}\t{'-' if heard.found is None else heard.found}\n")
        sys.stdout.flush()
    if failed:
        raise typer.Exit(1)


@speech_app.command("train")
def speech_train(
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
    """Train the command classifier on espeak-ng speech (needs espeak-ng); see missions/bench/train_speech.py."""
    import shutil

    from botstage.missions.bench import train_speech

    if shutil.which("espeak-ng") is None:
        raise _fail("error: espeak-ng is missing: training makes its audio with it (apt-get install espeak-ng)", 1)
    if thresholds_only:
        if out is not None and not out.exists():
            raise _fail(f"error: --thresholds-only: no weights at {out}", 2)
        train_speech.rethreshold(out, cache, workers)
        return
    train_speech.main(out, quick, cache, workers)
