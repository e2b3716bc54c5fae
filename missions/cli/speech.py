"""`botstage speech recognize`: the listen skill's recogniser on WAV files (the speech set)."""

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
    from botstage.skills.speech.recognizer import MODES, RECOGNIZERS
    from botstage.skills.speech.recognizers import recognizer_named
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
