"""The command recognisers by name, for ``listen`` and ``botstage speech``: the one module that knows
both (the embedding recogniser delegates free speech to pocketsphinx's, never the other way)."""

from __future__ import annotations

from botstage.skills.speech.embedding import shared_embedding_recognizer
from botstage.skills.speech.recognizer import RECOGNIZERS, CommandRecognizer, shared_recognizer


def recognizer_named(name: str = RECOGNIZERS[0]) -> CommandRecognizer:
    """The process's recogniser of that name (``embedding``, the default, or ``pocketsphinx``)."""
    if name == "pocketsphinx":
        return shared_recognizer()
    if name == "embedding":
        return shared_embedding_recognizer()
    raise ValueError(f"recognizer must be one of {', '.join(RECOGNIZERS)}, got {name!r}")
