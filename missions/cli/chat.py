"""The chat verb: Maya's converse kernel and command routing in the terminal."""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from botstage.missions.cli.common import NON_NEGATIVE, _fail, _stderr, console, no_special_files, output_dir


def chat(
    visitor: str = typer.Option("visitor", help="who you are: Maya remembers each visitor apart"),
    alice: bool = typer.Option(True, help="learn the A.L.I.C.E. set python-aiml ships (small talk)"),
    aiml: list[Path] = typer.Option(
        [], help="more AIML files or folders, learnt last (repeatable)", callback=no_special_files
    ),
    cache_dir: Path | None = typer.Option(
        None, help="brain cache folder (default: the user cache)", callback=output_dir
    ),
    seed: int | None = typer.Option(
        None, help="seed Maya's random choices (default: a new one each time)", callback=NON_NEGATIVE
    ),
) -> None:
    """Chat with Maya in the terminal: the converse skill's kernel and command routing.

    One line is one utterance; a robot command (PHOTO, YES, WHATSUP, CANCEL, CIAO, "take a
    picture"...) is shown as the event the mission would get. `/visitor NAME` lets another
    visitor speak (Maya remembers each apart). `quit` or end of input ends.
    """
    import random

    from rich.markup import escape

    from botstage.skills.chat.cache import load_brain
    from botstage.skills.chat.chatbot import Chatbot
    from botstage.skills.chat.persona import aiml_files

    brain = load_brain(aiml_files(alice, aiml), cache_dir)
    _stderr([str(problem) for problem in brain.problems] + [f"note: {note}" for note in brain.notes])
    if brain.trie.template_count == 0:
        raise _fail("error: no AIML category was learnt", 2)
    how = "loaded from the cache" if brain.origin == "cache" else "learnt and cached" if brain.path else "learnt"
    _stderr([f"Maya: {brain.trie.template_count:,} categories {how} in {brain.seconds:.2f} s"])
    maya = Chatbot(brain.trie, seed=seed if seed is not None else random.randrange(2**32))
    interactive = sys.stdin.isatty()
    while True:
        if interactive:
            sys.stdout.write(f"{visitor}> ")
            sys.stdout.flush()
        line = sys.stdin.readline()
        if not line:  # end of input
            break
        text = line.strip()
        if not text:
            continue
        if text.lower() in ("quit", "exit", "/quit"):
            break
        if text.startswith("/visitor"):
            visitor = text.removeprefix("/visitor").strip() or visitor
            console.print(f"({visitor} speaks now)", highlight=False, markup=False)
            continue
        turn = maya.turn(text, visitor)
        if turn.command is not None:
            console.print(f"[bold]-> {turn.command}[/] (command: the mission's `command` outcome)", highlight=False)
        else:
            console.print(f"[bold]Maya:[/] {escape(turn.reply)}", highlight=False, soft_wrap=True)
