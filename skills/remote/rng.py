"""A node's ``random.Random`` state as bytes, so it crosses to a remote skill and back cheaply.

A node's generator travels with each call (the host draws where the mission would have) and
comes back when the skill drew from it. Its state is Mersenne Twister's 624 words and position
plus the cached Gaussian: tagged JSON of those 625 integers cost about 0.8 ms to write and 0.3 ms
to read per call; packed, they take microseconds and 2,510 bytes. A host unpacks and loads them
only if the skill uses the generator (``LazyRandom``): most skills never draw.
"""

from __future__ import annotations

import random
import struct
from typing import Any

VERSION = 3  # random.Random.VERSION: the only state layout CPython writes
_WORDS = struct.Struct("<625I")  # 624 state words and the position
_GAUSS = struct.Struct("<?d")  # whether a Gaussian is cached, and its value
SIZE = 1 + _WORDS.size + _GAUSS.size


def pack(state: tuple[Any, ...]) -> bytes:
    """The bytes of ``random.Random().getstate()``; ValueError for any other shape."""
    try:
        version, internal, gauss = state
        words = _WORDS.pack(*internal)
        cached = _GAUSS.pack(gauss is not None, 0.0 if gauss is None else float(gauss))
    except (TypeError, ValueError, struct.error) as error:
        raise ValueError(f"not a random.Random state: {error}") from None
    if version != VERSION:
        raise ValueError(f"random.Random state version {version!r}, expected {VERSION}")
    return bytes([VERSION]) + words + cached


def unpack(data: bytes) -> tuple[Any, ...]:
    """The state ``pack`` wrote (``random.Random.setstate`` checks the position); ValueError if malformed."""
    if len(data) != SIZE or data[0] != VERSION:
        raise ValueError(f"a random state is {SIZE} bytes starting with {VERSION}, got {len(data)} bytes")
    internal = _WORDS.unpack_from(data, 1)
    cached, gauss = _GAUSS.unpack_from(data, 1 + _WORDS.size)
    return (VERSION, internal, gauss if cached else None)


def check(data: bytes) -> bytes:
    """``data`` if it has the shape ``pack`` writes (its words are read only when used); ValueError if not."""
    if len(data) != SIZE or data[0] != VERSION:
        raise ValueError(f"a random state is {SIZE} bytes starting with {VERSION}, got {len(data)} bytes")
    return data


# What reads or changes a generator's state: CPython's Random routes every draw through
# ``random`` or ``getrandbits`` (its C primitives), ``gauss`` keeps a cached value, and the rest
# set or read it. Overridden below; tests check every public method against this list.
_USES = ("random", "getrandbits", "randbytes", "gauss", "seed", "setstate")


class LazyRandom(random.Random):
    """A node's generator as a remote call receives it: loaded on first use, and knows whether it was.

    Most remote skills never draw, so the host should not pay to unpack, load, read back and
    compare 625 words per call to find out: ``used`` says whether anything but ``getstate`` ran.
    After the first use the instance calls CPython's methods directly: draws cost what they cost
    on a plain ``random.Random`` and give the same numbers. (Only a caller of the base class's
    unbound methods, ``random.Random.random(rng)``, would get past it.)
    """

    def __new__(cls, state: tuple[Any, ...] | bytes | None = None) -> LazyRandom:
        return super().__new__(cls, 0)  # a fixed seed: no OS entropy for a state about to be replaced

    def __init__(self, state: tuple[Any, ...] | bytes | None = None) -> None:
        """Keep ``state`` to load on first use: Random's own seeding is skipped."""
        self._pending: tuple[Any, ...] | bytes | None = state  # the state to load on first use; None: OS entropy
        self.used = False
        self.gauss_next = None

    def initial(self) -> tuple[Any, ...] | None:
        """The state the generator was given (unpacked if it came as bytes), or None."""
        pending = self._pending
        if isinstance(pending, bytes):
            self._pending = pending = unpack(pending)
        return pending

    def _use(self) -> None:
        if self.used:
            return
        state = self.initial()
        if state is None:
            random.Random.seed(self)
        else:
            random.Random.setstate(self, state)
        self.used = True
        for name in _USES:  # from now on the class's own methods, without this indirection
            setattr(self, name, getattr(super(), name))

    def random(self) -> float:
        self._use()
        return super().random()

    def getrandbits(self, k: int, /) -> int:
        self._use()
        return super().getrandbits(k)

    def randbytes(self, n: int) -> bytes:
        self._use()
        return super().randbytes(n)

    def gauss(self, mu: float = 0.0, sigma: float = 1.0) -> float:
        self._use()
        return super().gauss(mu, sigma)

    def seed(self, a: Any = None, version: int = 2) -> None:
        self._use()
        super().seed(a, version)

    def setstate(self, state: tuple[Any, ...]) -> None:
        self._use()
        super().setstate(state)

    def getstate(self) -> tuple[Any, ...]:
        if not self.used:
            state = self.initial()
            if state is not None:
                return state
            self._use()
        return super().getstate()
