"""Sends the outbox's pending photos in the background, retrying with backoff; no tick waits for it.

HTTP runs in the worker's own threads; everything else (choosing what to send, applying the
answers to the store, scheduling retries) happens in ``pump()``, called from one thread at a
time. That makes the worker work on either kind of clock:

- **simulated** (a mission on ``SimClock``, and the tests): the run calls ``pump()`` then
  ``settle()`` once per tick. ``settle`` waits for the attempts in flight, so their answers are
  applied at the same tick in every run, and backoff waits are counted in mission time: a
  retry 4 s later is 40 ticks later, however long the HTTP took in wall time.
- **real time**: ``start()`` runs the pump on a thread of its own that sleeps until the next
  retry is due or something changes (a new photo, an answer).

Backoff is exponential with "equal jitter" (half the delay fixed, half random) from a seeded
generator; the random draw is made when an attempt starts, in recording order, so a seed gives
the same schedule every run. A ``Retry-After`` from the gallery lengthens that wait, up to the
longest backoff (a gallery asking for a day must not silence the robot for a day). A photo is
marked uploaded only after a 2xx.
"""

from __future__ import annotations

import logging
import random
import threading
from collections import Counter
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor, wait
from dataclasses import dataclass

from botstage.skills.outbox.client import Attempt, GalleryClient
from botstage.skills.outbox.store import DAMAGED, PENDING, REJECTED, Item, OutboxStore

_log = logging.getLogger("botstage.outbox")
IDLE_WAKE_S = 1.0  # the real-time loop's longest sleep: it also notices being stopped


@dataclass(frozen=True, slots=True)
class Backoff:
    initial: float = 1.0
    maximum: float = 60.0

    def delay(self, attempt: int, rng: random.Random) -> float:
        """Seconds to wait after failed attempt number ``attempt`` (1, 2, ...)."""
        full = min(self.maximum, self.initial * 2.0 ** min(attempt - 1, 62))
        return full / 2 + rng.uniform(0.0, full / 2)


class UploadWorker:
    def __init__(
        self,
        store: OutboxStore,
        client: GalleryClient,
        now: Callable[[], float],
        *,
        concurrency: int = 2,
        backoff: Backoff | None = None,
        seed: int = 0,
        on_change: Callable[[Item], None] | None = None,
    ) -> None:
        self.store = store
        self.client = client
        self.now = now
        self.concurrency = concurrency
        self.backoff = backoff or Backoff()
        self.stats: Counter[str] = Counter()
        self._rng = random.Random(seed)
        self._on_change = on_change
        self._pool = ThreadPoolExecutor(concurrency, thread_name_prefix="botstage-upload")
        self._in_flight: dict[str, tuple[Future[Attempt], float]] = {}  # hash -> (attempt, delay if it fails)
        self._due: dict[str, float] = {}  # hash -> clock time before which it is not tried again
        self._wake = threading.Event()
        self._thread: threading.Thread | None = None
        self._stopping = False
        self._closed = False

    # -- driving ----------------------------------------------------------------------------

    def pump(self) -> None:
        """Apply the answers that came back, then start what is due (up to ``concurrency``)."""
        if self._closed:
            return
        self._collect()
        free = self.concurrency - len(self._in_flight)
        if free <= 0:
            return
        now = self.now()
        for item in self.store.pending():
            if free <= 0:
                break
            if item.hash in self._in_flight or self._due.get(item.hash, now) > now:
                continue
            delay = self.backoff.delay(item.attempts + 1, self._rng)  # drawn in a deterministic order
            future = self._pool.submit(self._attempt, item)
            future.add_done_callback(lambda _f: self._wake.set())
            self._in_flight[item.hash] = (future, delay)
            self.stats["attempts"] += 1
            free -= 1

    def settle(self, timeout: float | None = None) -> None:
        """Wait for the attempts in flight and apply their answers (the simulated clock's step)."""
        if self._in_flight:
            wait([f for f, _ in self._in_flight.values()], timeout=timeout)
            self._collect()

    def notify(self) -> None:
        """Something changed (a photo was recorded): the real-time loop looks again now."""
        self._wake.set()

    @property
    def in_flight(self) -> int:
        return len(self._in_flight)

    def next_due(self) -> float | None:
        """Clock time of the next retry, None when nothing waits for one."""
        waiting = [
            self._due[item.hash]
            for item in self.store.pending()
            if item.hash in self._due and item.hash not in self._in_flight
        ]
        return min(waiting, default=None)

    # -- real time --------------------------------------------------------------------------

    def start(self) -> None:
        """Pump on a thread of its own (real-time clocks only: its sleeps are wall time)."""
        if self._thread is None:
            self._thread = threading.Thread(target=self._loop, name="botstage-outbox", daemon=True)
            self._thread.start()

    def _loop(self) -> None:
        while not self._stopping:
            self._wake.clear()
            try:
                self.pump()
            except Exception:  # keep uploading: one bad answer must not stop the outbox
                _log.exception("outbox worker")
            due = self.next_due()
            if due is None or len(self._in_flight) >= self.concurrency:
                sleep = IDLE_WAKE_S  # an answer or a new photo wakes it sooner
            else:
                sleep = min(IDLE_WAKE_S, max(0.0, due - self.now()))
            if sleep > 0:
                self._wake.wait(sleep)

    def stop(self, grace: float = 0.0) -> None:
        """Stop the loop; give attempts in flight up to ``grace`` s to finish and count."""
        self._stopping = True
        self._wake.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        if grace > 0:
            self.settle(grace)

    def close(self, grace: float = 0.0) -> None:
        """Stop; answers arriving after ``grace`` are dropped (the photos stay pending: a crash)."""
        self.stop(grace)
        self._closed = True
        self._pool.shutdown(wait=False, cancel_futures=True)

    # -- one attempt ------------------------------------------------------------------------

    def _attempt(self, item: Item) -> Attempt:
        data = self.store.read_verified(item)
        if isinstance(data, str):
            return Attempt("damaged", data)
        return self.client.upload(item, data)

    def _collect(self) -> None:
        for h, (future, delay) in list(self._in_flight.items()):  # in the order they started
            if not future.done():
                continue
            del self._in_flight[h]
            try:
                attempt = future.result()
            except Exception as error:  # a bug or an OS error in the attempt: retried like a failure
                attempt = Attempt("retry", f"{type(error).__name__}: {error}")
            self._apply(h, attempt, delay)

    def _apply(self, h: str, attempt: Attempt, delay: float) -> None:
        if attempt.verdict == "uploaded":
            item = self.store.mark_uploaded(h)
            self._due.pop(h, None)
            self.stats["uploaded"] += 1
            if attempt.duplicate:
                self.stats["duplicates"] += 1  # the gallery had it: a resend after a lost answer
        elif attempt.verdict in ("rejected", "damaged"):
            item = self.store.mark_final(h, REJECTED if attempt.verdict == "rejected" else DAMAGED, attempt.reason)
            self._due.pop(h, None)
            self.stats[attempt.verdict] += 1
            _log.warning("photo %s %s: %s", h[:12], item.state, attempt.reason)
        else:
            if attempt.retry_after is not None:  # honoured, within the longest backoff
                delay = min(self.backoff.maximum, max(delay, attempt.retry_after))
            item = self.store.mark_failed_attempt(h, attempt.reason)
            self._due[h] = self.now() + delay
            self.stats["retries"] += 1
            _log.info("photo %s: %s; retry in %.1f s", h[:12], attempt.reason, delay)
        assert item.state != PENDING or attempt.verdict == "retry"
        if self._on_change is not None:
            self._on_change(item)
