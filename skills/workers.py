"""The worker pool behind ``ctx.submit``: blocking work runs here so a tick never blocks."""

from __future__ import annotations

import threading
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor, wait
from typing import Any


class Workers:
    """A thread pool that remembers which futures are still outstanding.

    On the sim clock the engine calls ``drain()`` after every tick, so work submitted during
    tick N is always complete when tick N+1 looks at it: its completion is observed at a
    deterministic tick, however long the work took in wall time.
    """

    def __init__(self, max_workers: int = 4, name: str = "botstage-worker") -> None:
        self._max_workers = max_workers
        self._name = name
        self._pool: ThreadPoolExecutor | None = None
        self._pending: set[Future[Any]] = set()
        self._lock = threading.Lock()
        self._closed = False

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future[Any]:
        if self._closed:
            raise RuntimeError("the worker pool is shut down")
        if self._pool is None:
            self._pool = ThreadPoolExecutor(self._max_workers, thread_name_prefix=self._name)
        future = self._pool.submit(fn, *args, **kwargs)
        with self._lock:
            self._pending.add(future)
        future.add_done_callback(self._forget)
        return future

    def _forget(self, future: Future[Any]) -> None:
        with self._lock:
            self._pending.discard(future)

    @property
    def outstanding(self) -> int:
        with self._lock:
            return len(self._pending)

    def drain(self, timeout: float | None = None) -> bool:
        """Wait until every submitted future is done. Returns False on timeout."""
        while True:
            with self._lock:
                pending = list(self._pending)
            if not pending:
                return True
            _done, not_done = wait(pending, timeout=timeout)
            if not_done:
                return False

    def shutdown(self, wait_for_work: bool = True) -> None:
        self._closed = True
        if self._pool is not None:
            self._pool.shutdown(wait=wait_for_work, cancel_futures=not wait_for_work)
            self._pool = None
