"""A backend's options, gathered from where they can be given and checked against its ``Options``.

In order, later ones winning: the robot profile's ``backends: {name: {option: value}}`` section
(errors located at file:line:col), ``--port`` (a shortcut for a ``port`` option, used only by
backends that have one), then ``--backend-opt key=value`` (values read as YAML scalars) or the
Python API's mapping. Every error names the option and where it was given.
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import yaml
from pydantic import ValidationError

from botstage.robots.backend import BackendError, BackendKind, BackendOptions
from botstage.robots.located_yaml import Location, Locations, Problem
from botstage.robots.profile import Profile


@dataclass(frozen=True)
class Given:
    """One option value and where it came from (a label, and a location when it is in a file)."""

    value: Any
    origin: str
    location: Location | None = None


@dataclass
class OptionSources:
    """What the caller gives besides the profile: explicit options and the ``--port`` shortcut."""

    options: Mapping[str, Any] = field(default_factory=dict)
    origin: str = "--backend-opt"
    port: str | None = None


def parse_assignments(items: Sequence[str]) -> dict[str, Any]:
    """``key=value`` strings (``--backend-opt``) as a mapping; values are YAML scalars (5, 0.5, true, text)."""
    options: dict[str, Any] = {}
    for item in items:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise BackendError(f"--backend-opt {item!r}: expected key=value, e.g. --backend-opt ready_timeout=10")
        try:
            value = yaml.safe_load(text) if text.strip() else ""
        except yaml.YAMLError:
            value = text
        if isinstance(value, dict | list):
            value = text  # a scalar option: keep what was typed
        options[key] = value
    return options


def gather(
    kind: BackendKind, profile: Profile | None, locations: Locations | None, given: OptionSources
) -> dict[str, Given]:
    """Every source's values for ``kind``, later sources winning."""
    values: dict[str, Given] = {}
    if profile is not None:
        for key, value in profile.backends.get(kind.name, {}).items():
            where = locations.find(("backends", kind.name, key)) if locations is not None else None
            values[key] = Given(value, "the robot profile", where)
    if given.port:  # a backend without a port option says so, rather than ignoring it
        values["port"] = Given(given.port, "--port")
    for key, value in given.options.items():
        values[key] = Given(value, given.origin)
    return values


def resolve(
    kind: BackendKind,
    profile: Profile | None = None,
    locations: Locations | None = None,
    given: OptionSources | None = None,
) -> BackendOptions:
    """``kind``'s options from every source, validated; a ``BackendError`` names each bad option."""
    values = gather(kind, profile, locations, given or OptionSources())
    try:
        return kind.Options.model_validate({key: g.value for key, g in values.items()})
    except ValidationError as exc:
        messages: list[str] = []
        located: list[Problem] = []
        for error in exc.errors():
            key = str(error["loc"][0]) if error["loc"] else ""
            message = _message(kind, key, error, values.get(key))
            where = values.get(key)
            if where is not None and where.location is not None:
                located.append(Problem(where.location, message))
            else:
                messages.append(message)
        raise BackendError("\n".join(messages), located) from None  # one line per option


def _message(kind: BackendKind, key: str, error: Any, given: Given | None) -> str:
    fields = kind.Options.model_fields
    if error["type"] == "extra_forbidden":
        close = difflib.get_close_matches(key, list(fields), n=1, cutoff=0.6)
        hint = f"did you mean {close[0]!r}? " if close else ""
        known = ", ".join(fields) or "none"
        origin = given.origin if given is not None else "?"
        return f"backend {kind.name!r} has no option {key!r} (from {origin}; {hint}options: {known})"
    if error["type"] == "missing":
        what = f" ({fields[key].description})" if fields[key].description else ""
        shortcut = "--port VALUE, " if key == "port" else ""
        return (
            f"the {kind.name} backend needs its {key!r} option{what}: give {shortcut}--backend-opt {key}=VALUE "
            f"or `backends: {{{kind.name}: {{{key}: ...}}}}` in the robot profile"
        )
    value = f" {given.value!r} from {given.origin}" if given is not None else ""
    return f"backend {kind.name!r} option {key!r}:{value}: {error['msg']}"
