"""Securing botstage's Zenoh sessions: where they may listen, TLS with mutual authentication, access control.

Everything here is Zenoh configuration by path (``Ros2Node(..., options=...)``), in the keys of
eclipse-zenoh 1.10, each checked by running it (tests/test_ros2_security.py).

**Listening.** A session listens on loopback unless asked otherwise (``check_listen``); anything
wider must be asked for and authenticated: a ``tls/`` endpoint of a session with mutual TLS.

**TLS** (``tls_options``). Every process has a certificate signed by the deployment's authority
(robots.ros2.certs) and uses it both when it listens and when it connects
(``transport/link/tls/{listen,connect}_{certificate,private_key}``); ``enable_mtls`` makes a
listener demand one from whoever connects, so a peer without a certificate of that authority
(none, self-signed, another authority's) never gets a session. ``verify_name_on_connect`` stays on
(Zenoh's default): the listener's certificate must name the host it is reached at, which
``botstage certs --host`` puts in. ``transport/link/protocols: ["tls"]`` refuses every other
link, so no plain-TCP side door is left open. Keys are passed by path, never inline, so a config
dump names files and holds no key material; ``redacted`` hides even those paths for logs.

**Access control** (``access_control``). Zenoh's ACL filters the messages crossing each link of a
process by the peer's certificate common name (its process name). Decided: the default is
*deny*, so an identity the policy does not name (a certificate of the authority for a process the
deployment does not have) gets nothing at all; every named process may do everything (data,
queries, declarations, and the ROS graph's liveliness tokens under ``@ros2_lv``, which ``**``
does not cover since Zenoh wildcards never match ``@`` chunks) except, per protected resource:

- a topic (``/cmd_vel``, data keys ``<domain>/cmd_vel/**``): a process not listed for it may not
  put, delete or reply on it (ingress: the receiving process drops it), and is not told of its
  subscribers (egress ``declare_subscriber``), so its Zenoh has nowhere to route a wildcard put;
- a service or action (``/kinect/skill_tick``, queries under ``<domain>/kinect/skill_tick/**``,
  which covers an action's ``_action/*`` services too): a process not listed may not query it and
  is not told of its queryables.

Zenoh's rules are key sets and a deny wins, so "everything but" is deny rules for the unlisted.
A rule only covers the keys it *includes*: a put (or query) on the wildcard ``0/**`` is not denied
by ``0/cmd_vel/**``, yet reaches every subscriber of the process it is routed to, cmd_vel's too.
No ACL rule can close that (any rule including ``0/**`` covers every key), so a receiver must
accept only its own exact key: rmw_zenoh's publishers and clients never use wildcards.

Every process of a deployment runs with the same policy: each filters its own links, and a
router (``forwarders``) passes on what others publish, so it is trusted with every resource and
filters its own ingress for them.
"""

from __future__ import annotations

import ipaddress
import json
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from botstage.robots.ros2.certs import Credentials
from botstage.robots.ros2.liveliness import ADMIN_SPACE
from botstage.robots.ros2.names import check_domain_id, fully_qualified_name, validate_node_name

TLS = "transport/link/tls"
PROTOCOLS = "transport/link/protocols"
ACCESS_CONTROL = "access_control"
SECURE_PROTOCOL = "tls"
LOCAL_PROTOCOLS = frozenset({"unixsock-stream", "unixpipe", "vsock"})  # never reachable over a network
ALL_MESSAGES = (
    "put",
    "delete",
    "declare_subscriber",
    "query",
    "reply",
    "declare_queryable",
    "liveliness_token",
    "liveliness_query",
    "declare_liveliness_subscriber",
)
# `**` never matches a chunk starting with '@': the graph's tokens and zenoh-ext's advanced
# publishers' caches (`<key>/@adv/...`, transient_local topics) need their own key expressions
EVERYTHING = ("**", f"{ADMIN_SPACE}/**", "**/@adv/**")
_SECRET = re.compile(r"private_key|password|_base64|_pem$|dictionary_file|known_keys_file", re.IGNORECASE)
REDACTED = "<redacted>"


# -- listening ----------------------------------------------------------------------------------


class ListenError(ValueError):
    """A listen endpoint the security policy refuses, with what to do instead."""


def endpoint_host(endpoint: str) -> tuple[str, str | None]:
    """``(protocol, host)`` of a Zenoh endpoint (``tls/127.0.0.1:7447#iface=lo``); host None for local sockets."""
    locator = endpoint.split("#", 1)[0].split("?", 1)[0]
    protocol, sep, address = locator.partition("/")
    if not sep or not protocol or not address:
        raise ListenError(f"{endpoint!r} is not a Zenoh endpoint (<protocol>/<address>, e.g. tcp/127.0.0.1:0)")
    protocol = protocol.lower()
    if protocol in LOCAL_PROTOCOLS:
        return protocol, None
    match = re.fullmatch(r"\[([^\]]*)\](?::\d+)?|([^:]*)(?::\d+)?", address)
    host = (match.group(1) if match.group(1) is not None else match.group(2)) if match else ""
    if not host:
        raise ListenError(f"{endpoint!r}: no host in {address!r}")
    return protocol, host


def is_loopback(endpoint: str) -> bool:
    """Whether only this machine can reach ``endpoint``: a loopback address, ``localhost``, or a local socket."""
    _, host = endpoint_host(endpoint)
    if host is None or host.lower() == "localhost":  # RFC 6761: localhost is loopback, always
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False  # another host name: it resolves to something else (or later to anything)


def is_authenticated(options: Mapping[str, Any] | None) -> bool:
    """Whether ``options`` make every link mutual TLS (as ``tls_options`` does)."""
    options = options or {}
    return (
        options.get(f"{TLS}/enable_mtls") is True
        and all(options.get(f"{TLS}/{name}") for name in ("root_ca_certificate", "listen_certificate"))
        and bool(options.get(f"{TLS}/listen_private_key"))
        and list(options.get(PROTOCOLS) or ()) == [SECURE_PROTOCOL]
    )


def check_listen(
    endpoints: Iterable[str], options: Mapping[str, Any] | None = None, *, allow_remote: bool = False
) -> list[str]:
    """``endpoints`` if the policy lets a session with ``options`` listen on them, else a ListenError.

    Loopback always passes. Anything wider needs ``allow_remote`` (asked for) and a ``tls/``
    endpoint on a session whose ``options`` demand mutual TLS (authenticated).
    """
    checked = list(endpoints)
    for endpoint in checked:
        if is_loopback(endpoint):
            continue
        protocol, host = endpoint_host(endpoint)
        if not allow_remote:
            raise ListenError(
                f"listen endpoint {endpoint!r} is reachable beyond this machine ({host} is not loopback): "
                "botstage listens on 127.0.0.1 unless asked for more (and then only with TLS certificates)"
            )
        if protocol != SECURE_PROTOCOL or not is_authenticated(options):
            raise ListenError(
                f"listen endpoint {endpoint!r} is reachable beyond this machine: it must be tls/{host}:PORT "
                "on a session with mutual TLS (certificates from `botstage certs`)"
            )
    return checked


# -- TLS ----------------------------------------------------------------------------------------


def tls_options(credentials: Credentials, *, verify_name: bool = True) -> dict[str, Any]:
    """Mutual TLS with ``credentials`` (paths) on every link, and no other protocol.

    ``verify_name=False`` accepts a listener whose certificate does not name the host connected to
    (any certificate of the authority): only for hosts whose address the certificates cannot know.
    """
    missing = credentials.missing()
    if missing:
        raise FileNotFoundError(
            f"TLS credentials missing: {', '.join(map(str, missing))} (make them with `botstage certs`)"
        )
    ca, cert, key = (str(path.resolve()) for path in (credentials.ca, credentials.cert, credentials.key))
    return {
        f"{TLS}/root_ca_certificate": ca,
        f"{TLS}/listen_certificate": cert,
        f"{TLS}/listen_private_key": key,
        f"{TLS}/connect_certificate": cert,
        f"{TLS}/connect_private_key": key,
        f"{TLS}/enable_mtls": True,
        f"{TLS}/verify_name_on_connect": verify_name,
        PROTOCOLS: [SECURE_PROTOCOL],
    }


# -- access control -----------------------------------------------------------------------------


@dataclass(frozen=True)
class AccessPolicy:
    """Who may publish which protected topics and call which protected services, by process name.

    ``processes`` are every identity the deployment has (certificate common names); topics and
    services not named here are open to all of them. Names are ROS names (``cmd_vel`` is
    ``/cmd_vel``).
    """

    processes: Sequence[str]
    publishers: Mapping[str, Sequence[str]] = field(default_factory=dict)
    callers: Mapping[str, Sequence[str]] = field(default_factory=dict)
    forwarders: Sequence[str] = ()
    domain_id: int = 0

    def __post_init__(self) -> None:
        if not self.processes:
            raise ValueError("an access policy needs at least one process (Zenoh reads no names as everyone)")
        known = set(self.processes)
        for name in self.processes:
            validate_node_name(name)
        check_domain_id(self.domain_id)
        for what, table in (("publish", self.publishers), ("call", self.callers)):
            for resource, allowed in table.items():
                fully_qualified_name(resource)
                for name in allowed:
                    if name not in known:
                        raise ValueError(f"{name!r} may {what} {resource!r} but is not one of the processes")
        for name in self.forwarders:
            if name not in known:
                raise ValueError(f"forwarder {name!r} is not one of the processes")

    def key_expr(self, name: str) -> str:
        """The key expression of everything a topic or service ``name`` carries in rmw_zenoh's keys."""
        return f"{self.domain_id}/{fully_qualified_name(name).strip('/')}/**"

    def denied(self, allowed: Sequence[str]) -> list[str]:
        """The processes a resource allowed to ``allowed`` is closed to (forwarders never)."""
        open_to = set(allowed) | set(self.forwarders)
        return [name for name in dict.fromkeys(self.processes) if name not in open_to]


def _rule(rule_id: str, permission: str, flows: Sequence[str], messages: Sequence[str], keys: Sequence[str]) -> dict:
    return {
        "id": rule_id,
        "permission": permission,
        "flows": list(flows),
        "messages": list(messages),
        "key_exprs": list(keys),
    }


def access_control(policy: AccessPolicy) -> dict[str, Any]:
    """Zenoh's ``access_control`` section for ``policy`` (default deny; see the module's docstring)."""
    processes = list(dict.fromkeys(policy.processes))
    rules = [_rule("processes may do everything", "allow", ("ingress", "egress"), ALL_MESSAGES, EVERYTHING)]
    subjects = [{"id": "processes", "cert_common_names": processes}]
    policies = [{"rules": ["processes may do everything"], "subjects": ["processes"]}]
    for kind, table, data, declaration in (
        ("publish", policy.publishers, ("put", "delete", "reply"), "declare_subscriber"),
        ("call", policy.callers, ("query",), "declare_queryable"),
    ):
        for resource, allowed in table.items():
            denied = policy.denied(allowed)
            if not denied:
                continue
            name, key = fully_qualified_name(resource), policy.key_expr(resource)
            refused, hidden = f"only listed processes {kind} {name}", f"unlisted processes do not see {name}"
            rules += [
                _rule(refused, "deny", ("ingress",), data, (key,)),
                _rule(hidden, "deny", ("egress",), (declaration,), (key,)),
            ]
            subject = f"may not {kind} {name}"
            subjects.append({"id": subject, "cert_common_names": denied})
            policies.append({"rules": [refused, hidden], "subjects": [subject]})
    return {"enabled": True, "default_permission": "deny", "rules": rules, "subjects": subjects, "policies": policies}


def security_options(credentials: Credentials, policy: AccessPolicy | None = None, **tls: Any) -> dict[str, Any]:
    """Everything a secured process adds to its session: mutual TLS and, given a policy, access control."""
    options = tls_options(credentials, **tls)
    if policy is not None:
        options[ACCESS_CONTROL] = access_control(policy)
    return options


# -- logging ------------------------------------------------------------------------------------


def redacted(options: Mapping[str, Any]) -> dict[str, Any]:
    """``options`` fit for a log: the value of every key or path naming a secret replaced."""

    def scrub(key: str, value: Any) -> Any:
        if _SECRET.search(key.rsplit("/", 1)[-1]) and value is not None:
            return REDACTED
        if isinstance(value, Mapping):
            return {k: scrub(str(k), v) for k, v in value.items()}
        return value

    return {key: scrub(key, value) for key, value in options.items()}


def describe(options: Mapping[str, Any]) -> str:
    """One line for a log: the options, redacted."""
    return json.dumps(redacted(options), sort_keys=True)
