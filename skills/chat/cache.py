"""The brain file cache: learn the AIML once, then load the flat brain at start-up.

A brain file is named by the hash of what it was learnt from (the AIML files' contents in
order, the python-aiml version, the Python version and this file format), so a changed AIML
file simply finds no brain and is learnt again. Files live in ``$BOTSTAGE_CACHE_DIR``, else
``$XDG_CACHE_HOME/botstage``, else ``~/.cache/botstage``, under ``chat/``. A file is written to
a temporary name and renamed, so a crash never leaves half a brain; one that is unreadable
anyway (disk trouble, a hand edit) fails its checksum and is rebuilt. The problems found when
learning are stored in the file, so every start reports them, not just the first.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
import threading
import time
import zlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from aiml.constants import VERSION as PYAIML_VERSION

from botstage.robots.located_yaml import Location, Problem
from botstage.skills.chat.brain import FlatTrie, build
from botstage.skills.chat.learn import learn_files
from botstage.skills.files import write_atomically

FORMAT = 1
MAGIC = b"botstage-aiml-brain\n"
ENV_CACHE_DIR = "BOTSTAGE_CACHE_DIR"
KEEP = 4  # brain files kept per cache folder (the newest): other AIML sets, other versions


def cache_root() -> Path:
    """botstage's user cache folder: $BOTSTAGE_CACHE_DIR, $XDG_CACHE_HOME/botstage or ~/.cache/botstage."""
    override = os.environ.get(ENV_CACHE_DIR)
    if override:
        return Path(override).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME", "")
    if xdg and Path(xdg).is_absolute():  # the XDG spec: a relative value is to be ignored
        return Path(xdg) / "botstage"
    return Path.home() / ".cache" / "botstage"


def brain_dir(override: str | Path | None = None) -> Path:
    return Path(override).expanduser() if override else cache_root() / "chat"


def fingerprint(files: Sequence[Path]) -> str:
    """The hash a brain is filed under: the AIML contents in order and what reads them."""
    digest = hashlib.sha256()
    python = f"{sys.version_info.major}.{sys.version_info.minor}"
    digest.update(f"format {FORMAT}; python-aiml {PYAIML_VERSION}; python {python}\n".encode())
    for path in files:
        try:
            content = path.read_bytes()
        except OSError as error:
            content = f"<unreadable: {error.strerror}>".encode()
        digest.update(f"{path.name} {len(content)}\n".encode())
        digest.update(content)
    return digest.hexdigest()


@dataclass
class LoadedBrain:
    """A brain ready to answer, where it came from, and what went wrong on the way."""

    trie: FlatTrie
    key: str
    origin: Literal["cache", "learned"]
    problems: list[Problem] = field(default_factory=list)  # located problems in the AIML files
    notes: list[str] = field(default_factory=list)  # about the cache itself (rebuilt, not writable)
    path: Path | None = None  # the brain file, when there is one
    seconds: float = 0.0  # wall time to load or learn (and store) it


def load_brain(
    files: Sequence[Path], cache_dir: str | Path | None = None, *, use_cache: bool = True, key: str | None = None
) -> LoadedBrain:
    """The brain of ``files``: from its cache file when there is a good one, else learnt and stored."""
    started = time.perf_counter()
    key = key or fingerprint(files)
    notes: list[str] = []
    path = brain_dir(cache_dir) / f"brain-{key[:32]}.brn" if use_cache else None
    if path is not None and path.exists():
        try:
            trie, problems = read_brain(path, key)
        except Exception as error:  # whatever is wrong with a cache file, it is only a cache: rebuild
            notes.append(f"brain cache {path} unreadable ({error}): rebuilt")
        else:
            return LoadedBrain(trie, key, "cache", problems, notes, path, time.perf_counter() - started)
    learned = learn_files(files)
    trie = build(learned.categories)
    if path is not None:
        try:
            write_brain(path, key, trie, learned.problems)
            prune(path.parent, keep=KEEP)
        except OSError as error:
            notes.append(f"brain cache {path.parent} not writable ({error.strerror or error}): not cached")
            path = None
    return LoadedBrain(trie, key, "learned", learned.problems, notes, path, time.perf_counter() - started)


def write_brain(path: Path, key: str, trie: FlatTrie, problems: Sequence[Problem]) -> None:
    """Write atomically (skills.files): a crash leaves the old cache or the new one, never half."""
    sections = trie.sections()
    header = {
        "key": key,
        "sections": [len(s) for s in sections],
        "crc32": [zlib.crc32(s) for s in sections],
        "problems": [[p.location.file, p.location.line, p.location.col, p.message, p.hint] for p in problems],
    }
    data = b"".join([MAGIC, json.dumps(header).encode() + b"\n", *sections])
    write_atomically(path, data, sync_folder=False)  # a cache: a lost rename only costs a relearn


def read_brain(path: Path, key: str) -> tuple[FlatTrie, list[Problem]]:
    """A brain file's trie and stored problems; ValueError for anything but a whole, matching file."""
    data = memoryview(path.read_bytes())
    if bytes(data[: len(MAGIC)]) != MAGIC:
        raise ValueError("not a botstage brain file")
    end = bytes(data[len(MAGIC) : len(MAGIC) + 65536]).find(b"\n")
    if end < 0:
        raise ValueError("no header")
    header = json.loads(bytes(data[len(MAGIC) : len(MAGIC) + end]))
    if not isinstance(header, dict) or header.get("key") != key:
        raise ValueError("made from other AIML")
    lengths, checksums = header["sections"], header["crc32"]
    position = len(MAGIC) + end + 1
    if position + sum(lengths) != len(data):
        raise ValueError(f"{len(data)} bytes where the header promises {position + sum(lengths)}")
    sections = []
    for length, checksum in zip(lengths, checksums, strict=True):
        section = data[position : position + length]
        if zlib.crc32(section) != checksum:
            raise ValueError("checksum mismatch")
        sections.append(section)
        position += length
    problems = [
        Problem(Location(file, line, col), message, hint) for file, line, col, message, hint in header["problems"]
    ]
    return FlatTrie.from_sections(sections), problems


def prune(folder: Path, keep: int) -> None:
    """Keep the ``keep`` newest brain files of a folder: old AIML sets do not pile up."""
    dated = []
    for brain in folder.glob("brain-*.brn"):
        try:
            dated.append((brain.stat().st_mtime_ns, brain))
        except OSError:
            continue  # another process removed it meanwhile
    for _, old in sorted(dated, reverse=True)[keep:]:
        old.unlink(missing_ok=True)


_loaded: dict[str, LoadedBrain] = {}
_lock = threading.Lock()


def shared_brain(files: Sequence[Path], cache_dir: str | Path | None = None) -> LoadedBrain:
    """The process's brain for ``files``: loaded (or learnt) once, then shared by every kernel.

    Keyed by the files' contents, so an edited AIML file is picked up by the next run.
    """
    key = fingerprint(files)
    with _lock:  # one load at a time: two runs starting together wait for the same brain
        brain = _loaded.get(key)
        if brain is None:
            brain = load_brain(files, cache_dir, key=key)
            _loaded.clear()  # one AIML set at a time in memory: 20-60 MB each
            _loaded[key] = brain
        return brain
