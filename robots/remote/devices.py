"""A backend's devices served call by call, and proxies that make remote devices look local.

The host answers ``describe`` (each device's methods and attributes) and ``call`` (one method
call or attribute read, its arguments and result as tagged JSON). A proxy class is built per
device from the description, so ``isinstance(proxy, Laser)`` and ``hasattr(speaker, "play")``
say what they say about the real device, and every call or attribute read is one request, in the
order the caller makes them: a simulated sensor draws its noise in the same order as in one
process. An exception the device raised is raised again on the caller's side with its message
(as the same built-in type when it is one), so a skill that reports it says the same words.

A result that is not data (a stateful helper such as a people tracker's crowd tracker) stays
where it was made: the caller gets a *handle*, a proxy of the same kind addressed as ``@h<n>``,
and a handle passed back as an argument is the object itself again on the serving side. A host
keeps at most ``MAX_HANDLES`` (the oldest are forgotten first).
"""

from __future__ import annotations

import builtins
import itertools
import threading
from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Protocol

from botstage.robots.remote import values

MAX_HANDLES = 4096
HANDLE = "@h"  # the prefix of a handle's address (never an interface name)


class RemoteDeviceError(Exception):
    """A device in another process raised an exception that is not a built-in one."""


class RemoteLost(ConnectionError):
    """The process that serves the devices is gone; the message names it."""


@dataclass(frozen=True)
class Member:
    """A device's public method or attribute."""

    name: str
    method: bool


def members_of_object(device: Any) -> list[Member]:
    """An object's public members (what a proxy of it will offer)."""
    members = []
    for name in dir(device):
        if name.startswith("_"):
            continue
        try:
            value = getattr(type(device), name, None) or getattr(device, name)
        except Exception:  # a property that cannot be read now is still an attribute
            value = None
        members.append(Member(name, callable(value) and not isinstance(value, property)))
    return members


def describe(devices: Mapping[str, Any]) -> dict[str, list[Member]]:
    """Each device's public members (what a proxy will offer)."""
    return {interface: members_of_object(device) for interface, device in devices.items()}


def error_fields(error: BaseException) -> tuple[str, str]:
    """What crosses of an exception: its type's name and its message."""
    return type(error).__name__, str(error)


def raise_again(kind: str, message: str) -> None:
    """Raise what the device raised: the built-in type of that name, else ``RemoteDeviceError``."""
    builtin = getattr(builtins, kind, None)
    if isinstance(builtin, type) and issubclass(builtin, Exception):
        try:
            error = builtin(message)
        except Exception:  # a built-in that takes other arguments (UnicodeDecodeError)
            error = RemoteDeviceError(f"{kind}: {message}")
        raise error
    raise RemoteDeviceError(f"{kind}: {message}")


class DeviceHost:
    """Serves the devices of an open backend, one call at a time."""

    def __init__(self, devices: Mapping[str, Any]) -> None:
        self.devices = devices
        self._lock = threading.Lock()  # a device is not made for two callers at once
        self.members = describe(devices)
        self._handles: OrderedDict[str, tuple[Any, list[Member]]] = OrderedDict()
        self._handle_of: dict[int, str] = {}
        self._numbers = itertools.count(1)

    @property
    def lock(self) -> threading.Lock:
        """Held while a call runs: whoever else touches the devices in this process takes it too."""
        return self._lock

    def _target(self, interface: str) -> tuple[Any, list[Member]]:
        if interface.startswith(HANDLE):
            held = self._handles.get(interface)
            if held is None:
                raise LookupError(f"no object {interface} here any more (the robot process restarted?)")
            return held
        device = self.devices.get(interface)
        if device is None:
            raise LookupError(f"this robot has no '{interface}' interface (it has: {', '.join(sorted(self.devices))})")
        return device, self.members[interface]

    def call(self, interface: str, member: str, args: tuple[Any, ...], kwargs: Mapping[str, Any]) -> Any:
        """Call ``interface.member(*args, **kwargs)`` (or read the attribute); errors as the device raised them."""
        device, members = self._target(interface)
        if member.startswith("_") or not any(m.name == member for m in members):
            raise AttributeError(f"the {interface} device has no public member {member!r}")
        value = getattr(device, member)
        return value(*args, **kwargs) if callable(value) else value

    def _handle(self, value: Any, path: str) -> Any:
        """A result that is not data: kept here, addressed by a handle."""
        address = self._handle_of.get(id(value))
        if address is None or self._handles.get(address, (None,))[0] is not value:
            address = f"{HANDLE}{next(self._numbers)}"
            self._handles[address] = (value, members_of_object(value))
            self._handle_of[id(value)] = address
            while len(self._handles) > MAX_HANDLES:
                _, (forgotten, _members) = self._handles.popitem(last=False)
                self._handle_of.pop(id(forgotten), None)
        self._handles.move_to_end(address)
        members = self._handles[address][1]
        return {"$handle": [address, [[m.name, m.method] for m in members]]}

    def _resolve(self, inner: Any) -> Any:
        return self._target(str(inner[0]))[0]

    def answer(self, interface: str, member: str, args_json: str) -> tuple[str, str, str]:
        """One request from its wire fields: (result JSON, error type, error message)."""
        try:
            with self._lock:
                call = (
                    values.loads(args_json, "the arguments", self._resolve) if args_json else {"args": (), "kwargs": {}}
                )
                result = self.call(interface, member, tuple(call["args"]), dict(call["kwargs"]))
                return values.dumps(result, "the result", self._handle), "", ""
        except Exception as error:
            kind, message = error_fields(error)
            return "", kind, message


class DeviceLink(Protocol):
    """Carries device calls to the process that has the devices; raises ``RemoteLost`` when it is gone."""

    remote: str

    def call(self, interface: str, member: str, args_json: str) -> tuple[str, str, str]: ...


def _handle_argument(value: Any, path: str) -> Any:
    if isinstance(value, RemoteDevice) and value.interface.startswith(HANDLE):
        return {"$handle": [value.interface]}
    raise values.ValueCodecError(f"{path}: a {type(value).__name__} cannot be sent to the robot's process")


def invoke(link: DeviceLink, interface: str, member: str, args: tuple[Any, ...], kwargs: Mapping[str, Any]) -> Any:
    """One call over ``link``: the result, or the device's exception raised again here."""
    text = values.dumps({"args": args, "kwargs": dict(kwargs)}, f"{interface}.{member}() arguments", _handle_argument)
    result, kind, message = link.call(interface, member, text)
    if kind:
        raise_again(kind, message)
    if not result:
        return None

    def handle(inner: Any) -> RemoteDevice:
        address, listed = inner
        return proxy_class(str(address), [Member(str(n), bool(m)) for n, m in listed])(link)

    return values.loads(result, f"{interface}.{member}() result", handle)


def _method(interface: str, name: str) -> Any:
    def method(self: RemoteDevice, *args: Any, **kwargs: Any) -> Any:
        return invoke(self._link, interface, name, args, kwargs)

    method.__name__ = name
    return method


def _attribute(interface: str, name: str) -> property:
    return property(lambda self: invoke(self._link, interface, name, (), {}), doc=f"{interface}.{name}, read remotely")


class RemoteDevice:
    """Base of the proxy classes: a device whose every member is served by ``link``'s process."""

    interface = ""

    def __init__(self, link: DeviceLink) -> None:
        self._link = link

    def __repr__(self) -> str:
        return f"<remote {self.interface} of {self._link.remote!r}>"


def proxy_class(interface: str, members: list[Member]) -> type[RemoteDevice]:
    """A class whose instances offer ``members`` of ``interface`` through a link."""
    body: dict[str, Any] = {"interface": interface, "__module__": __name__}
    for member in members:
        body[member.name] = _method(interface, member.name) if member.method else _attribute(interface, member.name)
    return type(f"Remote_{interface}", (RemoteDevice,), body)


def remote_devices(link: DeviceLink, members: Mapping[str, list[Member]]) -> dict[str, RemoteDevice]:
    """A proxy per device the far side described."""
    return {interface: proxy_class(interface, listed)(link) for interface, listed in members.items()}


def members_json(members: Mapping[str, list[Member]]) -> str:
    return values.dumps({i: [[m.name, m.method] for m in listed] for i, listed in members.items()}, "the devices")


def members_of(text: str) -> dict[str, list[Member]]:
    data = values.loads(text, "the devices")
    return {str(i): [Member(str(n), bool(m)) for n, m in listed] for i, listed in data.items()}


class DirectDeviceLink:
    """A link to a host in this process, through the same fields as the wire: for tests and benches."""

    def __init__(self, host: DeviceHost, remote: str = "local") -> None:
        self.host, self.remote = host, remote

    def call(self, interface: str, member: str, args_json: str) -> tuple[str, str, str]:
        return self.host.answer(interface, member, args_json)
