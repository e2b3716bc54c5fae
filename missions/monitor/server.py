"""The monitor's web application (FastAPI) and where it listens.

Pages: ``/`` the monitor, ``/display`` the robot's tablet. JSON: ``/api/info``,
``/api/structure``, ``/api/snapshot``, ``/api/summary`` (the run at a glance, for the overview of
several runs: ``sources.py``), ``/api/events`` (server-sent events: a delta of what
changed, at most every ``PUSH_S``; ``?since=VERSION`` resumes after a snapshot; ``&stamps=1``
adds when each changed status changed, for the benchmark), ``/api/history?key=K``,
``/api/display``, ``/api/photo?file=photos/…`` (a photo the run took), ``/api/map`` and
``/api/map.png`` (the occupancy grid), ``/api/camera.jpg`` (while teleoperated),
``POST /api/control`` and ``POST /api/teleop`` (live runs); ``/api/range`` and
``/api/at?tick=N`` (finished runs). Server-sent events rather than a WebSocket: one-way is all
the views need, the browser reconnects by itself, and uvicorn serves them with no extra package.

Security: 127.0.0.1 by default. Any other address needs a token (``BOTSTAGE_MONITOR_TOKEN``);
with a token, every control action needs ``Authorization: Bearer <token>``, and viewing stays
read-only and open.
"""

from __future__ import annotations

import asyncio
import hmac
import json
import os
from typing import Any

from fastapi import APIRouter, FastAPI, HTTPException, Request
from fastapi.responses import FileResponse, JSONResponse, Response, StreamingResponse

from botstage.missions.monitor.control import Control, ControlError, MalformedCommand
from botstage.missions.monitor.hub import Hub
from botstage.missions.monitor.pages import pages_router
from botstage.missions.monitor.replay import RecordedRun
from botstage.missions.monitor.robot_view import map_info, map_png
from botstage.missions.monitor.sources import ProcessesView, Source, create_overview_app, summary
from botstage.missions.serving import ServerThread, app_config, bind, is_loopback, start_server

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8470
TOKEN_ENV = "BOTSTAGE_MONITOR_TOKEN"
PUSH_S = 0.05  # the pages hear of a change within this (p99 well under the 200 ms wanted)
KEEPALIVE_S = 15.0
READY_WAIT_S = 20.0  # how long /api/info and /api/structure wait for the run to be built


class MonitorError(Exception):
    """The monitor cannot listen as asked (an address beyond loopback without a token, a port in use)."""


def _dumps(value: Any) -> str:
    return json.dumps(value, default=str, ensure_ascii=False, separators=(",", ":"))


def _json(value: Any) -> Response:
    return Response(_dumps(value), media_type="application/json")


def create_app(
    hub: Hub, control: Control | None = None, *, token: str | None = None, run: RecordedRun | None = None
) -> FastAPI:
    """The application over one run's ``hub``: live with a ``control``, or a finished ``run``."""
    app = FastAPI(title="botstage monitor", docs_url=None, redoc_url=None, openapi_url=None)
    expected = f"Bearer {token}".encode() if token else None
    app.include_router(pages_router({"/": "monitor.html", "/display": "display.html"}))
    app.include_router(run_router(hub, live=control is not None, token_required=expected is not None))
    app.include_router(events_router(hub))
    app.include_router(control_router(hub, control, expected))
    app.include_router(robot_router(hub))
    if run is not None:
        app.include_router(replay_router(run))
    return app


async def started(hub: Hub) -> None:
    """Info and structure exist once the run is built: a page that came first waits a while."""
    waited = 0.0
    while not hub.ready.is_set():
        if waited >= READY_WAIT_S:
            raise HTTPException(503, "the run has not started yet", headers={"Retry-After": "1"})
        await asyncio.sleep(PUSH_S)
        waited += PUSH_S


def run_router(hub: Hub, *, live: bool, token_required: bool) -> APIRouter:
    """What the run is and where it is: read-only, open to every viewer."""
    router = APIRouter()

    @router.get("/api/info")
    async def info() -> dict[str, Any]:
        await started(hub)
        return {**hub.info, "token_required": token_required, "control": live, "map": hub.grid is not None}

    @router.get("/api/structure")
    async def structure() -> Response:
        await started(hub)
        return _json(hub.structure)

    @router.get("/api/snapshot")
    def snapshot() -> Response:
        return _json(hub.snapshot())

    @router.get("/api/summary")
    def at_a_glance() -> dict[str, Any]:
        return summary(hub)

    @router.get("/api/history")
    def history(key: str) -> list[dict[str, Any]]:
        writes = hub.key_history(key)
        if writes is None:
            raise HTTPException(404, f"no key {key!r} was written")
        return writes

    @router.get("/api/display")
    def display() -> dict[str, Any]:
        return hub.current_layout()

    return router


def events_router(hub: Hub) -> APIRouter:
    """``/api/events``: what changed, as server-sent events, until the run ends."""
    router = APIRouter()

    @router.get("/api/events")
    async def events(request: Request, since: int | None = None, stamps: bool = False) -> StreamingResponse:
        start = hub.version if since is None else since

        async def stream() -> Any:
            seen, quiet = start, 0.0
            while not await request.is_disconnected():
                if hub.version > seen:
                    delta = hub.delta(seen, stamps)
                    seen = delta["version"]
                    quiet = 0.0
                    yield f"data: {_dumps(delta)}\n\n"
                elif hub.flags.ended:  # all said: the stream ends cleanly before the server goes
                    return
                elif quiet >= KEEPALIVE_S:
                    quiet = 0.0
                    yield ": still here\n\n"
                await asyncio.sleep(PUSH_S)
                quiet += PUSH_S

        headers = {"Cache-Control": "no-cache", "X-Accel-Buffering": "no"}
        return StreamingResponse(stream(), media_type="text/event-stream", headers=headers)

    return router


def control_router(hub: Hub, control: Control | None, expected: bytes | None) -> APIRouter:
    """The requests that act on the run (``expected``: the ``Authorization`` header they need)."""
    router = APIRouter()

    async def controlled(request: Request) -> tuple[Control, dict[str, Any]]:
        """The control and the request's JSON object, once the token and the run allow it."""
        if control is None:
            raise HTTPException(409, "this is a finished run: there is nothing to control")
        given = request.headers.get("authorization", "").encode()
        if expected is not None and not hmac.compare_digest(given, expected):
            raise HTTPException(401, "control needs the monitor's token", headers={"WWW-Authenticate": "Bearer"})
        await started(hub)  # what a request may name is known once the run is built
        try:
            body = await request.json()
        except ValueError:
            raise HTTPException(400, "the body is not JSON") from None
        if not isinstance(body, dict):
            raise HTTPException(400, "the body must be a JSON object")
        return control, body

    @router.post("/api/control")
    async def control_action(request: Request) -> JSONResponse:
        control, body = await controlled(request)
        try:
            message = control.request(body)
        except ControlError as exc:
            raise HTTPException(422, str(exc)) from None
        return JSONResponse({"ok": True, "message": message})

    @router.post("/api/teleop")
    async def teleop(request: Request) -> JSONResponse:
        control, body = await controlled(request)
        try:
            message = control.teleop(body.get("v"), body.get("w"))
        except MalformedCommand as exc:  # the request's fault: nothing moves
            raise HTTPException(422, str(exc)) from None
        except ControlError as exc:  # not now: the run is not held, or the robot cannot be driven
            raise HTTPException(409, str(exc)) from None
        return JSONResponse({"ok": True, "message": message})

    return router


def robot_router(hub: Hub) -> APIRouter:
    """Where the robot is and what it saw: the map, the photos the run took, the camera."""
    router = APIRouter()
    drawn: dict[str, bytes] = {}  # the map's image, drawn once

    @router.get("/api/map")
    def map_meta() -> dict[str, Any]:
        if hub.grid is None:
            raise HTTPException(404, "this run has no map")
        return map_info(hub.grid)

    @router.get("/api/map.png")
    def map_image() -> Response:
        if hub.grid is None:
            raise HTTPException(404, "this run has no map")
        if "map.png" not in drawn:
            drawn["map.png"] = map_png(hub.grid)
        return Response(drawn["map.png"], media_type="image/png", headers={"Cache-Control": "max-age=3600"})

    @router.get("/api/photo")
    def photo(file: str) -> FileResponse:
        """A photo the run took (``file`` as the photo skill gave it, relative to the run folder)."""
        folder = hub.folder
        if folder is None or not any(entry["file"] == file for entry in hub.snapshot()["photos"]):
            raise HTTPException(404, f"the run took no photo {file!r}")
        path = (folder / file).resolve()
        if folder.resolve() not in path.parents or not path.is_file():
            raise HTTPException(404, f"no photo {file!r} in the run folder")
        return FileResponse(str(path), headers={"Cache-Control": "max-age=3600"})

    @router.get("/api/camera.jpg")
    def camera() -> Response:
        jpeg, number = hub.camera
        if not number:
            raise HTTPException(404, "no camera frame (frames come while the robot is teleoperated)")
        return Response(jpeg, media_type="image/jpeg", headers={"Cache-Control": "no-store"})

    return router


def replay_router(run: RecordedRun) -> APIRouter:
    """A finished run's ticks, for the page's scrubber."""
    router = APIRouter()

    @router.get("/api/range")
    def tick_range() -> dict[str, int]:
        return {"first": run.first, "last": run.last}

    @router.get("/api/at")
    def at(tick: int) -> Response:
        if not run.first <= tick <= run.last:
            raise HTTPException(422, f"tick {tick} is outside the run ({run.first}..{run.last})")
        return _json(run.at(tick))

    return router


def token_for(host: str, token: str | None = None) -> str | None:
    """The token the monitor needs: given, or from the environment; required beyond loopback."""
    token = token or os.environ.get(TOKEN_ENV) or None
    if not is_loopback(host) and token is None:
        raise MonitorError(
            f"the monitor listens on {host}, beyond this machine: set {TOKEN_ENV} to a secret that "
            "control actions must carry (viewing stays read-only)"
        )
    return token


def start_monitor(
    hub: Hub,
    control: Control | None = None,
    *,
    host: str = DEFAULT_HOST,
    port: int = DEFAULT_PORT,
    token: str | None = None,
    run: RecordedRun | None = None,
) -> ServerThread:
    """Serve the monitor on a thread (port 0: a free one); returns once it accepts connections."""
    token = token_for(host, token)
    try:
        sock = bind(host, port)
    except OSError as exc:
        raise MonitorError(f"the monitor cannot listen on {host}:{port}: {exc.strerror or exc}") from None
    port = sock.getsockname()[1]
    config = app_config(create_app(hub, control, token=token, run=run), host, port)
    return start_server(config, sock, "monitor")


def start_overview(
    sources: list[Source],
    *,
    host: str = DEFAULT_HOST,
    port: int = DEFAULT_PORT,
    token: str | None = None,
    processes: ProcessesView | None = None,
    title: str = "",
) -> ServerThread:
    """Serve several runs on one page (``sources.py``) on a thread; as ``start_monitor`` otherwise."""
    try:
        sock = bind(host, port)
    except OSError as exc:
        raise MonitorError(f"the monitor cannot listen on {host}:{port}: {exc.strerror or exc}") from None
    port = sock.getsockname()[1]
    app = create_overview_app(sources, token=token, processes=processes, title=title)
    return start_server(app_config(app, host, port), sock, "monitor")
