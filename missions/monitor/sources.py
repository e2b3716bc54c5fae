"""Several runs on one page: the monitor of each (a run of this process, a finished run's folder,
or another process's live monitor reached over HTTP) served under ``/s/<name>/``, with an overview
at ``/`` that shows them all live, and, for a deployment, its processes.

Each source keeps its own application: a page under ``/s/<name>/`` is the ordinary monitor page
(its URLs are relative), so every view, control and replay works there as it does alone. Another
process's monitor is proxied (requests and server-sent events forwarded as they come), so one
browser tab on one address sees runs on several processes and machines.

Security as for one monitor: loopback by default, a token beyond it; a control action that comes
through this server must carry this server's token before it is forwarded (with its header, which
the source checks again against its own).
"""

from __future__ import annotations

import hmac
import re
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any
from urllib.parse import urlsplit

import httpx
from fastapi import FastAPI, HTTPException, Request
from fastapi.responses import RedirectResponse, Response, StreamingResponse
from starlette.background import BackgroundTask

from botstage.missions.monitor.hub import Hub
from botstage.missions.monitor.pages import pages_router

SUMMARY_EVENTS = 8  # the newest timeline entries an overview card shows
PROXY_TIMEOUT_S = 10.0
_FORWARDED = ("authorization", "content-type", "accept", "last-event-id")
_UNSAFE = re.compile(r"[^A-Za-z0-9_.-]+")

ProcessesView = Callable[[], list[dict[str, Any]]]


# -- what an overview card shows ------------------------------------------------------------------


def _titles(structure: Mapping[str, Any]) -> dict[str, tuple[str, str]]:
    """Every node's path → (kind, title), from the structure the pages draw."""
    found: dict[str, tuple[str, str]] = {}
    stack = [structure] if structure else []
    while stack:
        node = stack.pop()
        found.setdefault(node["path"], (node.get("kind", ""), node.get("title", "")))
        stack.extend(node.get("children", ()))
    return found


def skill_of(title: str) -> str:
    """The skill a skill node runs, from its title (``name: skill``, or ``skill`` when they agree)."""
    return title.rsplit(": ", 1)[-1]


def summary(hub: Hub) -> dict[str, Any]:
    """One run at a glance: where it is, its machines' active states, the skills running now and
    the newest timeline entries (what the overview polls, small whatever the run's size)."""
    titles = _titles(hub.structure) if hub.ready.is_set() else {}
    with hub.lock:
        flags = hub.flags.plain()
        # a machine that left its last state (halted, ended) has none active: "machine/" is not shown
        states = {machine: state for machine, (state, _) in hub.states.items() if not state.endswith("/")}
        running = sorted(path for path, (status, _) in hub.statuses.items() if status == "RUNNING")
        newest = [entry for _, entry in list(hub.timeline)[-SUMMARY_EVENTS:]]
        version = hub.version
    skills = []
    for path in running:
        kind, title = titles.get(path, ("", ""))
        if kind in ("skill", "condition"):
            skills.append({"path": path, "skill": skill_of(title)})
    return {
        "version": version,
        "info": hub.info,
        **flags,
        "states": states,
        "running": skills,
        "timeline": newest,
    }


# -- sources ----------------------------------------------------------------------------------------


@dataclass
class Source:
    """One run on the overview: its name in URLs, what it is, and the application that serves it."""

    name: str
    kind: str  # "live", "finished" or "remote"
    app: FastAPI
    where: str = ""  # a run folder or the remote monitor's URL

    def plain(self) -> dict[str, Any]:
        return {"name": self.name, "kind": self.kind, "where": self.where, "url": f"s/{self.name}/"}


def source_name(text: str, taken: Iterable[str] = ()) -> str:
    """A name fit for a URL path segment, unlike any ``taken`` (``-2``, ``-3``… appended)."""
    base = _UNSAFE.sub("-", text).strip("-.") or "run"
    taken = set(taken)
    name, n = base, 1
    while name in taken:
        n += 1
        name = f"{base}-{n}"
    return name


def remote_name(url: str) -> str:
    parts = urlsplit(url)
    return f"{parts.hostname}-{parts.port}" if parts.port else str(parts.hostname)


def check_remote_url(url: str) -> str:
    """A remote monitor's base URL, normalised (no trailing slash); a clear error if it is not one."""
    parts = urlsplit(url)
    if parts.scheme not in ("http", "https") or not parts.hostname:
        raise ValueError(f"{url!r} is not a monitor's address (expected http://HOST:PORT)")
    if parts.query or parts.fragment:
        raise ValueError(f"{url!r}: a monitor's address has no query or fragment")
    return url.rstrip("/")


def proxy_app(base_url: str, token: str | None) -> FastAPI:
    """An application that forwards every request to the monitor at ``base_url``; a control
    action (any POST) needs ``token`` first when this server has one. A client per request: the
    connection is made when asked (a monitor not up yet, or gone, is said so) and closed with the
    response, a stream of events included."""
    app = FastAPI(docs_url=None, redoc_url=None, openapi_url=None)
    expected = f"Bearer {token}".encode() if token else None

    @app.api_route("/{path:path}", methods=["GET", "POST"], include_in_schema=False)
    async def forward(path: str, request: Request) -> Response:
        if request.method == "POST" and expected is not None:
            given = request.headers.get("authorization", "").encode()
            if not hmac.compare_digest(given, expected):
                raise HTTPException(401, "control needs the monitor's token", headers={"WWW-Authenticate": "Bearer"})
        headers = {name: value for name, value in request.headers.items() if name in _FORWARDED}
        body = await request.body() if request.method == "POST" else None
        # no read timeout: server-sent events are a response that lasts as long as the run
        client = httpx.AsyncClient(timeout=httpx.Timeout(PROXY_TIMEOUT_S, read=None))
        outgoing = client.build_request(
            request.method, f"{base_url}/{path}", params=request.query_params, headers=headers, content=body
        )
        try:
            answer = await client.send(outgoing, stream=True)
        except httpx.HTTPError as exc:
            await client.aclose()
            why = str(exc) or type(exc).__name__
            raise HTTPException(502, f"the monitor at {base_url} does not answer: {why}") from None
        kept = {
            name: value
            for name, value in answer.headers.items()
            if name in ("content-type", "cache-control", "www-authenticate", "retry-after")
        }

        async def done() -> None:
            await answer.aclose()
            await client.aclose()

        return StreamingResponse(
            answer.aiter_raw(), status_code=answer.status_code, headers=kept, background=BackgroundTask(done)
        )

    return app


def remote_source(url: str, taken: Iterable[str], token: str | None, name: str = "") -> Source:
    """Another process's live monitor, proxied."""
    base = check_remote_url(url)
    return Source(source_name(name or remote_name(base), taken), "remote", proxy_app(base, token), base)


# -- the overview -----------------------------------------------------------------------------------


def create_overview_app(
    sources: list[Source], *, token: str | None = None, processes: ProcessesView | None = None, title: str = ""
) -> FastAPI:
    """The overview at ``/`` and each source under ``/s/<name>/``; ``processes`` (a deployment's)
    adds their states to ``/api/processes``."""
    names = [source.name for source in sources]
    if len(set(names)) != len(names):
        raise ValueError(f"two sources have the same name: {names}")
    app = FastAPI(title="botstage monitor", docs_url=None, redoc_url=None, openapi_url=None)

    app.include_router(pages_router({"/": "overview.html"}))

    @app.get("/api/sources")
    def listed() -> dict[str, Any]:
        return {
            "title": title,
            "sources": [source.plain() for source in sources],
            "processes": processes is not None,
            "token_required": token is not None,
        }

    @app.get("/api/processes")
    def processes_now() -> list[dict[str, Any]]:
        if processes is None:
            raise HTTPException(404, "these runs are not a deployment's: there are no processes to show")
        return processes()

    for source in sources:
        # /s/<name> without its slash would resolve the page's relative URLs against /s/
        app.add_api_route(f"/s/{source.name}", _to_slash(source.name), methods=["GET"], include_in_schema=False)
        app.mount(f"/s/{source.name}", source.app)

    return app


def _to_slash(name: str) -> Callable[[], RedirectResponse]:
    def redirect() -> RedirectResponse:
        return RedirectResponse(f"{name}/", status_code=307)  # relative: behind any prefix too

    return redirect
