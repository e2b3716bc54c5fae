"""One upload attempt to the gallery over HTTP, and what its answer means for the outbox.

A multipart POST (httpx) of the photo with its content hash twice: as the ``Idempotency-Key``
header and as the ``hash`` form field, so the gallery can both deduplicate and check the bytes
it got. The answer is sorted into what the outbox does next:

- 2xx: uploaded (the only answer that marks a photo done);
- 400, 413, 415, 422: rejected, the photo itself is refused: retrying cannot help;
- anything else (connection refused, timeouts, 5xx, 429, 401/403, 404): retried with backoff.
  A refused token or a wrong address is the configuration's fault, not the photo's: it waits
  for the operator rather than being thrown away.

The token (from the environment) goes only into the ``Authorization`` header; it is never part
of a reason, a repr or a log line.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Literal
from urllib.parse import urlsplit, urlunsplit

import httpx

from skills.outbox.images import MEDIA_TYPES
from skills.outbox.store import Item

REJECTING = frozenset({400, 413, 415, 422})
Verdict = Literal["uploaded", "rejected", "retry", "damaged"]


@dataclass(frozen=True, slots=True)
class Attempt:
    """How one attempt ended; ``duplicate`` when the gallery already had the photo."""

    verdict: Verdict
    reason: str = ""
    status: int | None = None
    duplicate: bool = False


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
        if status in REJECTING:
            return Attempt("rejected", f"the gallery refused the photo (HTTP {status}: {detail})", status)
        if status in (401, 403):
            return Attempt("retry", f"the gallery refused the token (HTTP {status}): check {self._token_env}", status)
        return Attempt("retry", f"HTTP {status} from {self._shown}: {detail}", status)

    def close(self) -> None:
        self._http.close()
