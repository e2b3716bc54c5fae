"""One upload attempt to the gallery over HTTP, and what its answer means for the outbox.

A multipart POST (httpx) of the photo with its content hash twice: as the ``Idempotency-Key``
header and as the ``hash`` form field, so the gallery can both deduplicate and check the bytes
it got. The answer is sorted into what the outbox does next:

- 2xx: uploaded (the only answer that marks a photo done);
- transient (connection errors, timeouts, 5xx, 408, 425, 429): retried with backoff; a
  ``Retry-After`` (seconds, or an HTTP-date read against the answer's own ``Date``) is the
  least wait before the next try;
- the configuration's fault, not the photo's (401, 403, 407: the token; 404, 405, 410, 421:
  the address): retried, so the photo waits for the operator rather than being thrown away;
- any other 4xx (400, 413, 415, 422, ...): rejected, the photo itself is refused and sending
  it again unchanged cannot help;
- anything else (1xx, 3xx: httpx follows no redirect for a POST): retried.

The token (from the environment) goes only into the ``Authorization`` header; it is never part
of a reason, a repr or a log line.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from datetime import UTC, datetime
from email.utils import parsedate_to_datetime
from typing import Literal
from urllib.parse import urlsplit, urlunsplit

import httpx

from botstage.skills.outbox.images import MEDIA_TYPES
from botstage.skills.outbox.store import Item

TRANSIENT = frozenset({408, 425, 429})  # besides every 5xx
TOKEN_REFUSED = frozenset({401, 403, 407})
NO_SUCH_ADDRESS = frozenset({404, 405, 410, 421})
Verdict = Literal["uploaded", "rejected", "retry", "damaged"]


@dataclass(frozen=True, slots=True)
class Attempt:
    """How one attempt ended; ``duplicate`` when the gallery already had the photo;
    ``retry_after``: the least wait, in seconds, the gallery asked for before the next try."""

    verdict: Verdict
    reason: str = ""
    status: int | None = None
    duplicate: bool = False
    retry_after: float | None = None


def redact(url: str) -> str:
    """The URL without any user:password part, for messages and summaries."""
    parts = urlsplit(url)
    if parts.username is None and parts.password is None:
        return url
    host = parts.hostname or ""
    netloc = f"{host}:{parts.port}" if parts.port else host
    return urlunsplit((parts.scheme, netloc, parts.path, parts.query, parts.fragment))


def _detail(response: httpx.Response) -> str:
    try:
        body = response.json()
    except ValueError:
        return response.reason_phrase
    detail = body.get("detail") if isinstance(body, dict) else None
    return str(detail) if detail else response.reason_phrase


def retry_after(response: httpx.Response) -> float | None:
    """Seconds the ``Retry-After`` header asks to wait (never negative), None without a valid one.

    An HTTP-date is counted from the answer's own ``Date`` (the server's clock, so a skewed
    robot clock does not matter), or from now when the answer has none.
    """
    value = response.headers.get("retry-after", "").strip()
    if not value:
        return None
    if value.isascii() and value.isdigit():
        return float(value)
    try:
        when = parsedate_to_datetime(value)
        sent = response.headers.get("date")
        reference = parsedate_to_datetime(sent) if sent else datetime.now(UTC)
        return max(0.0, (when - reference).total_seconds())
    except (TypeError, ValueError, IndexError, OverflowError):
        return None


def _asked(wait: float | None) -> str:
    return "" if wait is None else f" (asked to retry after {wait:g} s)"


class GalleryClient:
    """Uploads photos to one endpoint; safe to share between upload threads."""

    def __init__(
        self,
        endpoint: str,
        token: str | None = None,
        *,
        timeout: float = 30.0,
        connections: int = 2,
        token_env: str = "the token variable",
    ) -> None:
        self.endpoint = endpoint
        self._shown = redact(endpoint)
        self._token = token or None
        self._token_env = token_env
        self._http = httpx.Client(
            timeout=httpx.Timeout(timeout, connect=min(timeout, 5.0)),
            limits=httpx.Limits(max_connections=connections, max_keepalive_connections=connections),
        )

    def __repr__(self) -> str:
        return f"GalleryClient({self._shown!r}, token={'set' if self._token else 'none'})"

    def upload(self, item: Item, data: bytes) -> Attempt:
        headers = {"Idempotency-Key": item.hash}
        if self._token:
            headers["Authorization"] = f"Bearer {self._token}"
        media = MEDIA_TYPES.get(item.file.suffix, "application/octet-stream")
        form = {"hash": item.hash, "metadata": json.dumps(item.metadata), "name": item.name}
        try:
            response = self._http.post(
                self.endpoint, headers=headers, data=form, files={"file": (item.name, data, media)}
            )
        except httpx.TimeoutException as error:
            return Attempt("retry", f"the gallery at {self._shown} did not answer in time ({type(error).__name__})")
        except httpx.TransportError as error:
            return Attempt("retry", f"the gallery at {self._shown} is unreachable ({type(error).__name__})")
        status = response.status_code
        if 200 <= status < 300:
            try:
                duplicate = bool(response.json().get("duplicate", False))
            except (ValueError, AttributeError):
                duplicate = False
            return Attempt("uploaded", "", status, duplicate)
        detail = _detail(response)
        if status in TOKEN_REFUSED:
            return Attempt("retry", f"the gallery refused the token (HTTP {status}): check {self._token_env}", status)
        if status in NO_SUCH_ADDRESS:
            reason = f"no upload address at {self._shown} (HTTP {status}: {detail}): check the endpoint"
            return Attempt("retry", reason, status)
        if 400 <= status < 500 and status not in TRANSIENT:
            return Attempt("rejected", f"the gallery refused the photo (HTTP {status}: {detail})", status)
        wait = retry_after(response)
        return Attempt("retry", f"HTTP {status} from {self._shown}: {detail}{_asked(wait)}", status, retry_after=wait)

    def close(self) -> None:
        self._http.close()
