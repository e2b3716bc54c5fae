"""Opening a robot from the command line, as `run`, `teleop`, `emulate` and `serve` do: the options
that pick a backend and observers, and a profile placed on a map."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from botstage.missions.cli.common import _fail, _stderr

if TYPE_CHECKING:
    from botstage.robots.backend import Backend, OpenRequest


def backend_help() -> str:
    """The --backend help: every installed backend with its description."""
    from botstage.robots.backend_registry import BackendRegistry

    registry = BackendRegistry.default()
    listed = "; ".join(f"{name} ({kind.description})" for name, kind in registry.items())
    return f"the backend to run on ({listed}); `botstage backends` lists their options"


def observer_help() -> str:
    """The --observe help: every installed observer."""
    from botstage.missions.session.plugins import observer_registry

    registry = observer_registry()
    listed = "; ".join(f"{name} ({registry.description(name)})" for name in registry)
    return f"watch the run with an installed observer, repeatable: {listed}"


def backend_options(items: list[str]) -> dict[str, Any]:
    """``--backend-opt key=value`` items as a mapping (values read as YAML scalars), or exit 2."""
    from botstage.robots.backend import BackendError
    from botstage.robots.backend_options import parse_assignments

    try:
        return parse_assignments(items)
    except BackendError as exc:
        raise _fail(f"error: {exc}", 2) from None


def observers(names: list[str]) -> list[object]:
    """A new instance of each named observer, or exit 2 naming the unknown one."""
    from botstage.missions.session.plugins import PluginError, observer_registry

    registry = observer_registry()
    if names:  # a plugin that failed to load may be the one asked for: say why
        _stderr([f"warning: plugin {p.entry_point}: {p.reason}" for p in registry.problems])
    try:
        return [registry.create(name) for name in names]
    except PluginError as exc:
        raise _fail(f"error: {exc}", 2) from None


def open_backend(name: str, request: OpenRequest, items: list[str], port: str | None, robot: str) -> Backend:
    """Backend ``name`` opened for ``request`` with the options of ``robot``'s profile, ``--port`` and
    ``--backend-opt``; or exit 2 with the reason (located in the profile when it is there)."""
    from botstage.robots.backend import BackendError
    from botstage.robots.backend_options import OptionSources
    from botstage.robots.backend_registry import BackendRegistry
    from botstage.robots.located_yaml import load_document
    from botstage.robots.profile import profile_path

    path = profile_path(robot)
    locations = load_document(path).locations if path is not None else None
    given = OptionSources(backend_options(items), port=port)
    try:
        return BackendRegistry.default().open(name, request, given, locations)[1]
    except BackendError as exc:
        raise _fail(exc.lines(), 2) from None


def robot_place(profile_name: str, world: str, start: str) -> Any:
    """A shipped or given profile, a map, and a start (a place of the map or "x,y,theta"); or exit 2."""
    from botstage.robots.places import PlaceError, robot_place

    try:
        return robot_place(profile_name, world, start)
    except PlaceError as exc:
        raise _fail(exc.lines, 2) from None
