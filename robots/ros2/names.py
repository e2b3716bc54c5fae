"""ROS 2 names: their validation, fully-qualified names, Zenoh data keys and liveliness mangling.

The rules are ROS 2's (design.ros2.org "Topic and Service names", rcl's and rmw's validators):
a node name is letters, digits and underscores not starting with a digit; a namespace and a
fully-qualified name are absolute, ``/``-separated tokens of the same characters, no token
starting with a digit, no empty token, no trailing ``/``. A name that breaks them gets a
ValueError saying which rule and where, before anything reaches the network.

rmw_zenoh maps a fully-qualified topic ``/ns/topic`` of type ``T`` in domain ``D`` to the data
key ``D/ns/topic/<dds type of T>/<RIHS01 hash of T>`` and, inside liveliness tokens where one
chunk must hold a whole name, replaces every ``/`` by ``%``.
"""

from __future__ import annotations

import re

TOPIC_MAX_LENGTH = 255 - 8  # RMW_TOPIC_MAX_NAME_LENGTH: 8 characters are kept for DDS prefixes
NAMESPACE_MAX_LENGTH = TOPIC_MAX_LENGTH - 2  # room for the shortest topic in it, "/x"
NODE_NAME_MAX_LENGTH = 255  # RMW_NODE_NAME_MAX_NAME_LENGTH
SLASH_REPLACEMENT = "%"

_ALLOWED = re.compile(r"[A-Za-z0-9_/]")
_NODE_ALLOWED = re.compile(r"[A-Za-z0-9_]")
_SUBSTITUTIONS = ("node", "ns", "namespace")


def _check_characters(kind: str, name: str, allowed: re.Pattern[str], what: str) -> None:
    for index, char in enumerate(name):
        if not allowed.fullmatch(char):
            raise ValueError(f"{kind} {name!r}: {char!r} at index {index} is not allowed ({what})")


def _check_tokens(kind: str, name: str) -> None:
    """Absolute-name token rules shared by namespaces and fully-qualified names."""
    if "//" in name:
        raise ValueError(f"{kind} {name!r}: repeated '/' at index {name.index('//') + 1} (empty token)")
    for match in re.finditer(r"/[0-9]", name):
        raise ValueError(f"{kind} {name!r}: a token must not start with a digit (index {match.start() + 1})")


def validate_node_name(name: str) -> str:
    """``name`` if it is a valid ROS 2 node name, else a ValueError naming the rule it breaks."""
    if not isinstance(name, str) or not name:
        raise ValueError(f"node name {name!r}: must be a non-empty string")
    _check_characters("node name", name, _NODE_ALLOWED, "only letters, digits and '_'")
    if name[0].isdigit():
        raise ValueError(f"node name {name!r}: must not start with a digit")
    if len(name) > NODE_NAME_MAX_LENGTH:
        raise ValueError(f"node name {name!r}: {len(name)} characters, at most {NODE_NAME_MAX_LENGTH}")
    return name


def validate_namespace(namespace: str) -> str:
    """``namespace`` if it is a valid absolute ROS 2 namespace (``/`` or ``/a/b``), else a ValueError."""
    kind = "namespace"
    if not isinstance(namespace, str) or not namespace:
        raise ValueError(f"{kind} {namespace!r}: must be a non-empty string ('/' for the root)")
    if not namespace.startswith("/"):
        raise ValueError(f"{kind} {namespace!r}: must be absolute (start with '/')")
    if len(namespace) > 1 and namespace.endswith("/"):
        raise ValueError(f"{kind} {namespace!r}: must not end with '/'")
    _check_characters(kind, namespace, _ALLOWED, "only letters, digits, '_' and '/'")
    _check_tokens(kind, namespace)
    if len(namespace) > NAMESPACE_MAX_LENGTH:
        raise ValueError(f"{kind} {namespace!r}: {len(namespace)} characters, at most {NAMESPACE_MAX_LENGTH}")
    return namespace


def validate_full_topic_name(name: str) -> str:
    """``name`` if it is a valid fully-qualified topic or service name, else a ValueError."""
    kind = "fully-qualified name"
    if not isinstance(name, str) or not name:
        raise ValueError(f"{kind} {name!r}: must be a non-empty string")
    if not name.startswith("/"):
        raise ValueError(f"{kind} {name!r}: must be absolute (start with '/')")
    if name.endswith("/"):
        raise ValueError(f"{kind} {name!r}: must not end with '/'")
    _check_characters(kind, name, _ALLOWED, "only letters, digits, '_' and '/'")
    _check_tokens(kind, name)
    if len(name) > TOPIC_MAX_LENGTH:
        raise ValueError(f"{kind} {name!r}: {len(name)} characters, at most {TOPIC_MAX_LENGTH}")
    return name


def validate_topic_name(name: str) -> str:
    """``name`` if it is a valid topic name as a user writes it (relative, ``~`` or ``{node}`` allowed)."""
    kind = "topic name"
    if not isinstance(name, str) or not name:
        raise ValueError(f"{kind} {name!r}: must be a non-empty string")
    if name.endswith("/"):
        raise ValueError(f"{kind} {name!r}: must not end with '/'")
    if "~" in name[1:] or (name.startswith("~") and len(name) > 1 and name[1] != "/"):
        raise ValueError(f"{kind} {name!r}: '~' may only start the name, followed by '/' or nothing")
    for match in re.finditer(r"\{([^{}]*)\}?", name):
        if not match.group(0).endswith("}"):
            raise ValueError(f"{kind} {name!r}: unmatched '{{' at index {match.start()}")
        if match.group(1) not in _SUBSTITUTIONS:
            raise ValueError(
                f"{kind} {name!r}: unknown substitution {match.group(0)!r} (known: {{node}}, {{ns}}, {{namespace}})"
            )
    plain = re.sub(r"\{[^{}]*\}", "x", name.replace("~", "x", 1))
    if "}" in plain or "{" in plain:
        raise ValueError(f"{kind} {name!r}: unmatched '}}'")
    _check_characters(kind, plain, _ALLOWED, "only letters, digits, '_', '/', a leading '~' and {substitutions}")
    if re.match(r"[0-9]", name):
        raise ValueError(f"{kind} {name!r}: a token must not start with a digit (index 0)")
    _check_tokens(kind, name)
    return name


def fully_qualified_name(name: str, namespace: str = "/", node_name: str | None = None) -> str:
    """The absolute name ``name`` stands for in a node's namespace (rcl's expansion).

    ``/a`` stays; ``a`` becomes ``<namespace>/a``; ``~`` and ``~/a`` are under the node itself;
    ``{node}`` and ``{ns}``/``{namespace}`` are replaced. The result is validated.
    """
    validate_topic_name(name)
    validate_namespace(namespace)
    uses_node = name.startswith("~") or "{node}" in name
    if uses_node and node_name is None:
        raise ValueError(f"topic name {name!r}: '~' and {{node}} need a node name")
    if node_name is not None:
        validate_node_name(node_name)
    base = "" if namespace == "/" else namespace
    expanded = name.replace("{node}", node_name or "").replace("{namespace}", base).replace("{ns}", base)
    if expanded.startswith("~"):
        expanded = f"{base}/{node_name}{expanded[1:]}"
    elif not expanded.startswith("/"):
        expanded = f"{base}/{expanded}"
    return validate_full_topic_name(expanded)


def node_fqn(namespace: str, node_name: str) -> str:
    """A node's fully-qualified name: ``/talker`` in the root namespace, ``/robot1/talker`` in ``/robot1``."""
    validate_namespace(namespace)
    validate_node_name(node_name)
    return f"/{node_name}" if namespace == "/" else f"{namespace}/{node_name}"


def data_key(domain_id: int, fqn: str, dds_type: str, type_hash: str) -> str:
    """The Zenoh key of a topic's (or service's) data: ``<domain>/<fqn without slashes>/<type>/<hash>``.

    As rmw_zenoh's TopicInfo: one leading and one trailing ``/`` are stripped from the name,
    inner ones kept (``/robot1/cmd_vel`` -> ``0/robot1/cmd_vel/...``).
    """
    check_domain_id(domain_id)
    validate_full_topic_name(fqn)
    for what, value in (("DDS type name", dds_type), ("type hash", type_hash)):
        if not value or "/" in value or any(c in value for c in "*$?#"):
            raise ValueError(f"{what} {value!r} cannot be one key expression chunk")
    return f"{domain_id}/{fqn.strip('/')}/{dds_type}/{type_hash}"


def check_domain_id(domain_id: int) -> int:
    """``domain_id`` if it is a ROS domain id (an integer from 0), else a ValueError."""
    if isinstance(domain_id, bool) or not isinstance(domain_id, int) or domain_id < 0:
        raise ValueError(f"ROS domain id {domain_id!r}: must be an integer >= 0")
    return domain_id


def mangle(name: str) -> str:
    """A name as one liveliness-token chunk: every ``/`` replaced by ``%`` (``/robot1`` -> ``%robot1``)."""
    return name.replace("/", SLASH_REPLACEMENT)


def demangle(chunk: str) -> str:
    """The name a liveliness-token chunk holds: every ``%`` back to ``/``."""
    return chunk.replace(SLASH_REPLACEMENT, "/")
