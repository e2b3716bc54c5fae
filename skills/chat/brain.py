"""The learned AIML pattern tree in a flat form that loads in milliseconds.

python-aiml keeps its patterns as nested dicts (A.L.I.C.E.: about 700,000 of them) and saves
its brain file with ``marshal``. Loading that file takes longer than learning the AIML again
(4.5 s against 3.8 s here): the cyclic garbage collector rescans the growing heap of dicts
over and over. So the tree is stored flat: every edge is one int64 key ``node << 32 | symbol``
in a sorted array with the child's number beside it, words are numbered once, and templates
stay marshalled bytes until a reply first needs them. Loading is reading a few arrays; no
container per node is ever made.

``FlatBrain`` is python-aiml's own ``PatternMgr`` with its root swapped for a view of the
arrays, so matching (``_match``, ``star``) is python-aiml's code, unchanged.
"""

from __future__ import annotations

import marshal
import sys
from array import array
from bisect import bisect_left
from collections.abc import Mapping
from typing import Any

from aiml.PatternMgr import PatternMgr

from botstage.skills.chat.learn import Categories

_SPECIAL = (
    PatternMgr._UNDERSCORE,
    PatternMgr._STAR,
    PatternMgr._TEMPLATE,
    PatternMgr._THAT,
    PatternMgr._TOPIC,
    PatternMgr._BOT_NAME,
)
_TEMPLATE = PatternMgr._TEMPLATE
_FIRST_WORD = 8  # symbols below are python-aiml's special keys (0-5)
_SHIFT = 32
_LITTLE = sys.byteorder == "little"


class FlatTrie:
    """The pattern tree as sorted edge keys, child numbers, a word table and marshalled templates.

    Immutable once made, so one trie serves every kernel of the process from any thread; a
    template is unmarshalled the first time a reply needs it and kept.
    """

    def __init__(
        self,
        words: list[str],
        keys: array,
        values: array,
        template_offsets: array,
        template_blob: bytes,
    ) -> None:
        if len(keys) != len(values) or not template_offsets or template_offsets[-1] != len(template_blob):
            raise ValueError("inconsistent brain arrays")
        self.words = words
        self._symbols = {word: i + _FIRST_WORD for i, word in enumerate(words)}
        self._keys = keys
        self._values = values
        self._offsets = template_offsets
        self._blob = memoryview(template_blob)
        self._templates: list[Any] = [None] * (len(template_offsets) - 1)

    @property
    def template_count(self) -> int:
        return len(self._templates)

    @property
    def edge_count(self) -> int:
        return len(self._keys)

    def find(self, node: int, key: Any) -> int:
        """The child (or template number) under ``node`` for a python-aiml key; -1 if none."""
        symbol = key if type(key) is int else self._symbols.get(key)
        if symbol is None:
            return -1
        wanted = (node << _SHIFT) | symbol
        keys = self._keys
        i = bisect_left(keys, wanted)
        if i < len(keys) and keys[i] == wanted:
            return self._values[i]
        return -1

    def template(self, index: int) -> Any:
        template = self._templates[index]
        if template is None:
            template = marshal.loads(self._blob[self._offsets[index] : self._offsets[index + 1]])
            self._templates[index] = template
        return template

    # -- making and storing ----------------------------------------------------------------------

    @classmethod
    def from_tree(cls, root: Mapping[Any, Any]) -> FlatTrie:
        """Flatten python-aiml's nested-dict tree (``PatternMgr._root``).

        Nodes are numbered breadth first and each node's edges are emitted in symbol order, so
        the keys come out sorted with no sort, and the same AIML always gives the same bytes.
        """
        words: set[str] = set()
        stack = [root]
        while stack:
            node = stack.pop()
            for key, child in node.items():
                if type(key) is not int:
                    words.add(key)
                if not (type(key) is int and key == _TEMPLATE):
                    stack.append(child)
        ordered = sorted(words)
        symbols: dict[Any, int] = {word: i + _FIRST_WORD for i, word in enumerate(ordered)}
        symbols.update({special: special for special in _SPECIAL})
        keys, values, offsets = array("q"), array("q"), array("q", [0])
        blobs: list[bytes] = []
        size = 0
        queue = [root]
        for number, node in enumerate(queue):  # the queue grows while it is walked: breadth first
            base = number << _SHIFT
            for symbol, key in sorted((symbols[k], k) for k in node):
                keys.append(base | symbol)
                if symbol == _TEMPLATE:
                    blob = marshal.dumps(node[key])
                    blobs.append(blob)
                    size += len(blob)
                    offsets.append(size)
                    values.append(len(blobs) - 1)
                else:
                    values.append(len(queue))
                    queue.append(node[key])
        return cls(ordered, keys, values, offsets, b"".join(blobs))

    def sections(self) -> list[bytes]:
        """The trie as byte strings (words, keys, values, template offsets, templates), for a file."""
        return [
            marshal.dumps(self.words),
            _raw(self._keys),
            _raw(self._values),
            _raw(self._offsets),
            bytes(self._blob),
        ]

    @classmethod
    def from_sections(cls, sections: list[bytes] | list[memoryview]) -> FlatTrie:
        if len(sections) != 5:
            raise ValueError(f"a brain has 5 sections, got {len(sections)}")
        words = marshal.loads(sections[0])
        if not isinstance(words, list) or not all(type(w) is str for w in words):
            raise ValueError("the word table is not a list of strings")
        keys, values, offsets = (_int64s(s) for s in sections[1:4])
        return cls(words, keys, values, offsets, bytes(sections[4]))


def _raw(numbers: array) -> bytes:
    if _LITTLE:
        return numbers.tobytes()
    swapped = array("q", numbers)
    swapped.byteswap()
    return swapped.tobytes()


def _int64s(data: bytes | memoryview) -> array:
    if len(data) % 8:
        raise ValueError("an int64 section's length is not a multiple of 8")
    numbers = array("q")
    numbers.frombytes(data)
    if not _LITTLE:
        numbers.byteswap()
    return numbers


class _Node:
    """One node of a FlatTrie, as python-aiml's matcher uses a dict node: ``in`` and ``[]``."""

    __slots__ = ("_id", "_trie")

    def __init__(self, trie: FlatTrie, node: int) -> None:
        self._trie = trie
        self._id = node

    def __contains__(self, key: Any) -> bool:
        return self._trie.find(self._id, key) >= 0

    def __getitem__(self, key: Any) -> Any:
        found = self._trie.find(self._id, key)
        if found < 0:
            raise KeyError(key)
        if type(key) is int and key == _TEMPLATE:
            return self._trie.template(found)
        return _Node(self._trie, found)


class FlatBrain(PatternMgr):
    """python-aiml's pattern matcher over a FlatTrie: read-only, one per kernel (its bot name)."""

    def __init__(self, trie: FlatTrie) -> None:
        super().__init__()
        self.trie = trie
        self._root = _Node(trie, 0)
        self._templateCount = trie.template_count

    def match(self, pattern: str, that: str, topic: str) -> Any:
        return super().match(pattern, self._words_or_nothing(that), self._words_or_nothing(topic))

    def star(self, starType: str, pattern: str, that: str, topic: str, index: int) -> str:
        return super().star(starType, pattern, self._words_or_nothing(that), self._words_or_nothing(topic), index)

    def _words_or_nothing(self, text: str) -> str:
        # python-aiml tests "that" and "topic" for emptiness before it strips punctuation: a
        # reply of only punctuation left no words to match and no category matched at all
        return text if self._puncStripRE.sub(" ", text).split() else ""

    def setBotName(self, name: str) -> None:
        # python-aiml compares the upper-cased input word with the name as given, so a pattern
        # with <bot name="name"/> never matched "Maya": compare upper case with upper case
        self._botName = "".join(name.split()).upper()

    def add(self, data: Any, template: Any) -> None:
        raise TypeError("a FlatBrain is read-only: learn AIML into a PatternMgr and flatten it")

    def save(self, filename: str) -> None:
        raise TypeError("a FlatBrain is stored by botstage.skills.chat.cache, not by PatternMgr.save")

    def restore(self, filename: str) -> None:
        raise TypeError("a FlatBrain is loaded by botstage.skills.chat.cache, not by PatternMgr.restore")


def build(categories: Categories) -> FlatTrie:
    """The flat trie of learned categories, inserted with python-aiml's own ``PatternMgr.add``."""
    tree = PatternMgr()
    for key, template in categories.items():
        tree.add(key, template)
    return FlatTrie.from_tree(tree._root)
