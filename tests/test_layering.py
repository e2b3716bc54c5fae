"""The structure the design promises, read from the import graph (tests/import_graph.py):

- imports point one way: missions -> behaviors -> skills -> robots; skills and robots never see
  py_trees or transitions;
- the core never imports a plug-in set: each set is registered through entry points only, and a
  module of one set imports no other set but those it is built on;
- no two modules import each other at run time, however indirectly (type-only imports aside).
"""

from __future__ import annotations

import pytest

from tests.import_graph import chain, cycles, graph, modules, reach

ORDER = ["robots", "skills", "behaviors", "missions"]
FORBIDDEN_BELOW_BEHAVIORS = {"py_trees", "transitions"}

# Each plug-in set by the module prefixes it owns (its pip extra, where it has one, has the same name).
SETS: dict[str, tuple[str, ...]] = {
    "btcpp": ("botstage.behaviors.btcpp", "botstage.missions.groot2", "botstage.missions.cli.btcpp"),
    "nav2": ("botstage.behaviors.nav2", "botstage.skills.nav2"),
    "ros2": (
        "botstage.robots.ros2",
        "botstage.robots.remote",
        "botstage.skills.remote",
        "botstage.missions.distributed",
        "botstage.missions.deployment",
    ),
    "hardware": ("botstage.robots.drivers", "botstage.robots.emulators"),
    "speech": ("botstage.skills.speech", "botstage.skills.listen"),
    "chat": ("botstage.skills.chat", "botstage.skills.converse"),
    "web": ("botstage.missions.monitor", "botstage.missions.gallery", "botstage.missions.serving"),
}
# What a set is built on, besides the core (a deployment runs remote devices on real drivers too;
# Nav2's trees are BT.CPP XML; the remote devices carry hardware devices' readings).
BUILT_ON: dict[str, set[str]] = {
    "nav2": {"btcpp"},
    "ros2": {"hardware", "speech", "chat", "web"},
    "hardware": set(),
    "web": {"btcpp"},
}
# Packages only a plug-in set may import: `pip install botstage` does not install them.
SET_PACKAGES: dict[str, set[str]] = {
    "zenoh": {"ros2"},
    "xxhash": {"ros2"},
    "cryptography": {"ros2"},
    "rosbags": {"ros2", "hardware"},  # rosserial's message definitions too
    "serial": {"hardware"},
    "dynamixel_sdk": {"hardware"},
    "pocketsphinx": {"speech"},
    "onnxruntime": {"speech"},
    "aiml": {"chat"},
    "fastapi": {"web"},
    "starlette": {"web"},
    "uvicorn": {"web"},
    "multipart": {"web"},
    "zmq": {"btcpp"},
}
CLI = "botstage.missions.cli"  # the verbs: each set's verbs are its own; the app loads them by entry point


def set_of(module: str) -> str:
    for name, prefixes in SETS.items():
        if any(module == prefix or module.startswith(prefix + ".") for prefix in prefixes):
            return name
    return ""


EDGES = graph()


@pytest.mark.parametrize("layer", ORDER)
def test_layers_import_only_downwards(layer: str) -> None:
    higher = {f"botstage.{name}" for name in ORDER[ORDER.index(layer) + 1 :]}
    offenders = []
    for module, targets in sorted(EDGES.items()):
        if module.split(".")[1] != layer:
            continue
        bad = {t for t in targets if any(t == h or t.startswith(h + ".") for h in higher)}
        if layer in ("robots", "skills"):
            bad |= targets & FORBIDDEN_BELOW_BEHAVIORS
        if bad:
            offenders.append(f"{module} imports {sorted(bad)}")
    assert offenders == []


def test_the_core_imports_no_plugin_set() -> None:
    offenders = []
    for module, targets in sorted(EDGES.items()):
        if set_of(module) or module.startswith(CLI + "."):
            continue
        for target in sorted(targets):
            needed = {set_of(target)} - {""} or SET_PACKAGES.get(target, set())
            if needed:
                offenders.append(f"{module} imports {target} (the {'/'.join(sorted(needed))} set)")
    assert offenders == []


def test_a_plugin_set_imports_only_the_sets_it_is_built_on() -> None:
    offenders = []
    for module, targets in sorted(EDGES.items()):
        own = set_of(module)
        if not own:
            continue
        allowed = {own, *BUILT_ON.get(own, set())}
        for target in sorted(targets):
            needed = {set_of(target)} - {""} or SET_PACKAGES.get(target, set())
            if needed and not needed & allowed:
                offenders.append(f"{module} ({own}) imports {target} (the {'/'.join(sorted(needed))} set)")
    assert offenders == []


def test_no_runtime_import_cycle() -> None:
    assert cycles(EDGES) == []


def test_checking_and_running_reach_no_plugin_set() -> None:
    """What `botstage validate` and `botstage run` import, followed through every module they reach."""
    for start in ("botstage.missions.check", "botstage.missions.runner", "botstage.missions.scenario"):
        seen = reach(EDGES, start)
        bad = [" <- ".join(reversed(chain(seen, m))) for m in seen if set_of(m) or m in SET_PACKAGES]
        assert bad == [], start


def test_the_graph_sees_every_module() -> None:
    """The structural tests above mean something only if the graph holds the whole code base."""
    assert set(EDGES) == set(modules())
    assert len(EDGES) > 300
    assert "botstage.robots.ros2.node" in EDGES["botstage.robots.ros2.service"] or any(
        t.startswith("botstage.robots.ros2.") for t in EDGES["botstage.robots.ros2.service"]
    )
