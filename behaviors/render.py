"""Pictures of trees and machines: ascii, unicode, Graphviz dot (and svg/png through `dot`),
mermaid and json.

A machine renders as one picture: each state is a cluster holding what it runs (a skill, a
tree, or a nested machine), transitions are edges labelled with the outcome (and guard).
Labels show the skill, its port bindings and the decorators. Given the statuses of a recorded
run (``statuses_at``), nodes are coloured by their status at that tick.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

import py_trees

from botstage.behaviors.kinds import Described
from botstage.behaviors.kinds.leaves import describe_skill
from botstage.behaviors.machine import MachineBehaviour, MachinePlan
from botstage.behaviors.skill_behaviour import SkillBehaviour

FORMATS = ("ascii", "unicode", "dot", "svg", "png", "mermaid", "json")
TREE_FORMATS = MACHINE_FORMATS = FORMATS  # trees and machines are drawn in every format alike
COLOURS = {
    "UNTESTED": "#eeeeee,stroke-dasharray:4 3,color:#999999",
    "RUNNING": "#f0ad4e",
    "SUCCESS": "#5cb85c",
    "FAILURE": "#d9534f",
    "INVALID": "#dddddd",
    "ACTIVE": "#f0ad4e",
}


class GraphvizMissing(RuntimeError):
    def __init__(self) -> None:
        super().__init__(
            "Graphviz's `dot` is not installed (Debian: apt-get install graphviz); "
            "try --format mermaid, which needs nothing installed"
        )


@dataclass
class Statuses:
    """What a recorded run looked like at one tick."""

    nodes: dict[str, str] = field(default_factory=dict)  # node path -> RUNNING/SUCCESS/FAILURE/INVALID
    states: dict[str, str] = field(default_factory=dict)  # machine path -> active state path
    # from a coverage.json: nodes and states no test reached, transitions ("state:outcome") none took
    untested: set[str] = field(default_factory=set)
    untested_transitions: set[str] = field(default_factory=set)


def statuses_at(events: Iterable[Mapping[str, Any]], tick: int) -> Statuses:
    found = Statuses()
    for event in events:
        if event["tick"] > tick:
            break
        kind = event["ev"]
        if kind == "status":
            found.nodes[event["node"]] = event["new"]
        elif kind == "skill_cancel":
            found.nodes[event["node"]] = "INVALID"
        elif kind == "transition":
            found.states[event["machine"]] = event["dest"]
    return found


# -- describing nodes ---------------------------------------------------------------------


@dataclass
class Item:
    """One thing in a picture: a tree node, a machine, a state, or an outcome."""

    path: str
    # skill, condition, sequence, selector, parallel, decorator, machine, state, outcome; or group:
    # several pictures side by side (the machines of a mission), drawn with no node of its own
    kind: str
    title: str
    details: list[str] = field(default_factory=list)
    children: list[Item] = field(default_factory=list)
    # machines and states
    transitions: list[tuple[str, str, str]] = field(default_factory=list)  # (outcome, target path, guard)
    initial: str = ""
    preemptions: list[tuple[str, str]] = field(default_factory=list)  # (condition, target path)
    machine: str = ""  # for machine levels: the path of the machine they belong to


def describe(node: py_trees.behaviour.Behaviour) -> Item:
    """What a built node looks like in pictures, as its kind describes it (machines as clusters)."""
    path = getattr(node, "path", node.name)
    if isinstance(node, MachineBehaviour):
        return describe_machine(node.plan, path, node.name)
    kind = getattr(node, "node_kind", None)
    if kind is not None:
        described = kind.describe(node)
    elif isinstance(node, SkillBehaviour):  # a machine state's skill
        described = describe_skill(node)
    else:  # a behaviour made by hand, outside any kind
        described = Described(type(node).__name__, "decorator" if node.children else "skill")
    if described.shape in ("skill", "condition"):
        return Item(path, described.shape, described.title, list(described.details))
    title = described.title
    if node.name and node.name not in title.replace(" ", "_") and not title.startswith(node.name):
        title = f"{node.name}: {title}"
    return Item(path, described.shape, title, list(described.details), [describe(child) for child in node.children])


def describe_machine(plan: MachinePlan, path: str, name: str) -> Item:
    item = Item(path, "machine", f"machine {name}")
    item.details.append("outcomes: " + ", ".join(plan.outcomes))
    _fill_level(item, plan, plan.level, path)
    return item


def _fill_level(item: Item, plan: MachinePlan, level: Any, machine_path: str) -> None:
    item.machine = machine_path
    item.initial = f"{machine_path}/{level.initial}"
    item.preemptions = [(cond, f"{machine_path}/{level.full(t)}") for cond, t in level.preemptions]
    for name in level.names:
        info = plan.states[level.full(name)]
        state = Item(f"{machine_path}/{info.path}", "state", name)
        if info.timeout is not None:
            state.details.append(f"timeout {info.timeout:g} s")
        state.transitions = [
            (outcome, f"{machine_path}/{level.full(target)}", guard)
            for outcome, targets in info.written.items()
            for target, guard in targets
        ]
        if info.content is not None:
            content = describe(info.content)
            if info.kind == "tree" and info.label:
                named = content.title.startswith(info.label + ": ")
                content.title = f"tree {content.title}" if named else f"tree {info.label}: {content.title}"
            state.children.append(content)
        elif info.level is not None:
            outcomes = ["outcomes: " + ", ".join(info.level.outcomes)]
            nested = Item(f"{state.path}#machine", "machine", "machine", outcomes)
            _fill_level(nested, plan, info.level, machine_path)
            state.children.append(nested)
        item.children.append(state)
    for outcome in level.outcomes:
        item.children.append(Item(f"{machine_path}/{level.full(outcome)}", "outcome", outcome))


def machines_in(item: Item) -> list[Item]:
    """The outermost machines in a picture, wherever they sit (a tree's node, a parallel's
    child); a machine inside another's state is part of that one's picture."""
    if item.kind == "machine":
        return [item]
    return [machine for child in item.children for machine in machines_in(child)]


def group(title: str, items: list[Item]) -> Item:
    """Several pictures as one: a heading in text, side by side in dot and mermaid."""
    return Item("", "group", title, children=items)


# -- text -------------------------------------------------------------------------------------


def _status_mark(item: Item, statuses: Statuses | None) -> str:
    if statuses is None:
        return ""
    if item.path in statuses.untested:
        return "  [untested]"
    if item.kind == "state":
        _machine, _, _state = item.path.rpartition("/")
        active = any(
            item.path == f"{m}/{s}" or f"{m}/{s}".startswith(item.path + "/") for m, s in statuses.states.items()
        )
        return "  [ACTIVE]" if active else ""
    status = statuses.nodes.get(item.path)
    return f"  [{status}]" if status and status != "INVALID" else ""


def _lines(item: Item, unicode: bool, statuses: Statuses | None) -> Iterator[str]:
    tee, last, bar, space = ("├── ", "└── ", "│   ", "    ") if unicode else ("|-- ", "`-- ", "|   ", "    ")
    arrow = "→" if unicode else "->"

    def head(it: Item) -> str:
        text = (
            it.title
            if it.kind not in ("state", "outcome")
            else f"({it.title})"
            if it.kind == "outcome"
            else f"state {it.title}"
        )
        if it.details:
            text += "  " + "  ".join(it.details)
        untested = statuses.untested_transitions if statuses else set()
        if it.transitions:
            text += "  " + ", ".join(
                f"{o}{' if ' + g if g else ''} {arrow} {t.rsplit('/', 1)[-1]}"
                + (" (untested)" if f"{it.path}:{o}" in untested else "")
                for o, t, g in it.transitions
            )
        if it.kind == "machine" and it.initial:
            text += f"  initial {it.initial.rsplit('/', 1)[-1]}"
            text += "".join(
                f"  preempt: {c} {arrow} {t.rsplit('/', 1)[-1]}"
                + (" (untested)" if f"{it.machine}/preempt:{c}" in untested else "")
                for c, t in it.preemptions
            )
        return text.replace("→", arrow) + _status_mark(it, statuses)

    def walk(it: Item, prefix: str) -> Iterator[str]:
        for index, child in enumerate(it.children):
            end = index == len(it.children) - 1
            yield prefix + (last if end else tee) + head(child)
            yield from walk(child, prefix + (space if end else bar))

    yield head(item)
    yield from walk(item, "")


def to_text(item: Item, unicode: bool = True, statuses: Statuses | None = None) -> str:
    return "\n".join(_lines(item, unicode, statuses)) + "\n"


# -- dot --------------------------------------------------------------------------------------

_UNTESTED_NODE = ', style="rounded,filled,dashed", color="#999999", fontcolor="#999999"'
_UNTESTED_EDGE = ', style=dashed, color="#999999", fontcolor="#999999"'
_SHAPES = {
    "skill": "box",
    "condition": "ellipse",
    "sequence": "cds",
    "selector": "octagon",
    "parallel": "parallelogram",
    "decorator": "hexagon",
    "outcome": "doublecircle",
}


def _quote(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'


class _Ids:
    def __init__(self) -> None:
        self.ids: dict[str, str] = {}

    def __call__(self, path: str, suffix: str = "") -> str:
        key = path + suffix
        if key not in self.ids:
            self.ids[key] = f"n{len(self.ids)}"
        return self.ids[key]


def to_dot(item: Item, statuses: Statuses | None = None) -> str:
    ids = _Ids()
    lines = [
        "digraph botstage {",
        "  compound=true; rankdir=TB; newrank=true; ordering=out;",
        '  node [fontname="Helvetica", fontsize=10, style="rounded,filled", fillcolor="#ffffff"];',
        '  edge [fontname="Helvetica", fontsize=9];',
    ]
    edges: list[str] = []

    def fill(it: Item) -> str:
        status = statuses.nodes.get(it.path) if statuses else None
        return COLOURS.get(status, "#ffffff") if status else "#ffffff"

    def node(it: Item, indent: str) -> str:
        """Emit ``it``; returns the id of a node edges can attach to."""
        if it.kind in ("machine", "state"):
            return cluster(it, indent)
        if it.kind == "group":
            for child in it.children:
                node(child, indent)
            return ""
        label = "\n".join([it.title, *it.details])
        shape = _SHAPES.get(it.kind, "box")
        lines.append(
            f'{indent}{ids(it.path)} [label={_quote(label)}, shape={shape}, fillcolor="{fill(it)}"'
            + (_UNTESTED_NODE if it.path in untested else "")
            + "];"
        )
        for child in it.children:
            child_id = node(child, indent)
            edges.append(
                f"  {ids(it.path)} -> {child_id}"
                + (f" [lhead=cluster_{child_id}]" if child.kind in ("machine", "state") else "")
                + ";"
            )
        return ids(it.path)

    def cluster(it: Item, indent: str) -> str:
        anchor = ids(it.path, "#anchor")
        active = (
            statuses is not None
            and it.kind == "state"
            and any(f"{m}/{s}" == it.path or f"{m}/{s}".startswith(it.path + "/") for m, s in statuses.states.items())
        )
        colour = COLOURS["ACTIVE"] if active else "#f5f5f5" if it.kind == "state" else "#ffffff"
        label = it.title if it.kind == "state" else "\n".join([it.title, *it.details])
        if it.kind == "state" and it.details:
            label += "\n" + "\n".join(it.details)
        lines.append(f"{indent}subgraph cluster_{anchor} {{")
        style = "rounded,filled,dashed" if it.path in untested else "rounded,filled"
        lines.append(
            f'{indent}  label={_quote(label)}; style="{style}"; fillcolor="{colour}";'
            + (' fontcolor="#999999"; color="#999999";' if it.path in untested else "")
        )
        lines.append(f'{indent}  {anchor} [shape=point, width=0.05, label=""];')
        for child in it.children:
            node(child, indent + "  ")
        lines.append(f"{indent}}}")
        if it.kind == "machine" and it.initial:
            start = ids(it.path, "#start")
            lines.append(f'{indent}{start} [shape=circle, width=0.15, label="", fillcolor="#000000"];')
            edges.append(f"  {start} -> {ids(it.initial, '#anchor')} [lhead=cluster_{ids(it.initial, '#anchor')}];")
            for condition, target in it.preemptions:
                cold = f"{it.machine}/preempt:{condition}" in untested_transitions
                edges.append(
                    f'  {anchor} -> {_target(target)} [style=dashed, color="{"#999999" if cold else "#d9534f"}", '
                    f"label={_quote('preempt: ' + condition + (' (untested)' if cold else ''))}, "
                    f"ltail=cluster_{anchor}];"
                )
        for outcome, target, guard in it.transitions:
            cold = f"{it.path}:{outcome}" in untested_transitions
            label = outcome + (f" [{guard}]" if guard else "") + (" (untested)" if cold else "")
            edges.append(
                f"  {anchor} -> {_target(target)} [label={_quote(label)}, ltail=cluster_{anchor}"
                + (f", lhead=cluster_{ids(target, '#anchor')}" if target in states else "")
                + (_UNTESTED_EDGE if cold else "")
                + "];"
            )
        return anchor

    states = {s.path for s in _walk(item) if s.kind == "state"}
    untested = statuses.untested if statuses else set()
    untested_transitions = statuses.untested_transitions if statuses else set()

    def _target(path: str) -> str:
        return ids(path, "#anchor") if path in states else ids(path)

    node(item, "  ")
    lines.extend(edges)
    lines.append("}")
    return "\n".join(lines) + "\n"


def _walk(item: Item) -> Iterator[Item]:
    yield item
    for child in item.children:
        yield from _walk(child)


def graphviz(dot_text: str, fmt: str) -> bytes:
    exe = shutil.which("dot")
    if exe is None:
        raise GraphvizMissing()
    result = subprocess.run([exe, f"-T{fmt}"], input=dot_text.encode(), capture_output=True, timeout=60)
    if result.returncode != 0:
        raise RuntimeError(f"dot failed: {result.stderr.decode(errors='replace').strip()}")
    return result.stdout


# -- mermaid ----------------------------------------------------------------------------------

_MERMAID_SHAPES = {
    "skill": ('["', '"]'),
    "condition": ('(["', '"])'),
    "decorator": ('{{"', '"}}'),
    "outcome": ('(("', '"))'),
    "sequence": ('[/"', '"/]'),
    "selector": ('{"', '"}'),
    "parallel": ('[\\"', '"\\]'),
}


def to_mermaid(item: Item, statuses: Statuses | None = None) -> str:
    ids = _Ids()
    lines = ["flowchart TD"]
    edges: list[str] = []
    classes: dict[str, list[str]] = {}
    states = {s.path for s in _walk(item) if s.kind == "state"}

    def text(value: str) -> str:
        return value.replace('"', "#quot;").replace("\n", "<br/>")

    def target(path: str) -> str:
        return ids(path, "#anchor") if path in states else ids(path)

    def node(it: Item, indent: str) -> str:
        if it.kind == "group":
            for child in it.children:
                node(child, indent)
            return ""
        if it.kind in ("machine", "state"):
            anchor = ids(it.path, "#anchor")
            label = text("<br/>".join([it.title, *it.details]))
            lines.append(f'{indent}subgraph {anchor}s["{label}"]')
            lines.append(f"{indent}  {anchor}(( ))")
            for child in it.children:
                node(child, indent + "  ")
            lines.append(f"{indent}end")
            if (
                statuses is not None
                and it.kind == "state"
                and any(
                    f"{m}/{s}" == it.path or f"{m}/{s}".startswith(it.path + "/") for m, s in statuses.states.items()
                )
            ):
                classes.setdefault("ACTIVE", []).append(anchor)
            if it.kind == "machine" and it.initial:
                edges.append(f"  {anchor} -->|initial| {target(it.initial)}")
                for condition, to in it.preemptions:
                    edges.append(f'  {anchor} -.->|"{text("preempt: " + condition)}"| {target(to)}')
            for outcome, to, guard in it.transitions:
                cold = statuses is not None and f"{it.path}:{outcome}" in statuses.untested_transitions
                label = outcome + (f" [{guard}]" if guard else "") + (" (untested)" if cold else "")
                edges.append(f'  {anchor} {"-.->" if cold else "-->"}|"{text(label)}"| {target(to)}')
            return anchor
        open_, close = _MERMAID_SHAPES.get(it.kind, ('["', '"]'))
        lines.append(f"{indent}{ids(it.path)}{open_}{text(chr(10).join([it.title, *it.details]))}{close}")
        status = statuses.nodes.get(it.path) if statuses else None
        if status and status != "INVALID":
            classes.setdefault(status, []).append(ids(it.path))
        if statuses is not None and it.path in statuses.untested:
            classes.setdefault("UNTESTED", []).append(ids(it.path))
        for child in it.children:
            edges.append(f"  {ids(it.path)} --> {node(child, indent)}")
        return ids(it.path)

    node(item, "  ")
    lines.extend(edges)
    for status, members in classes.items():
        lines.append(f"  classDef {status.lower()} fill:{COLOURS[status]}")
        lines.append(f"  class {','.join(members)} {status.lower()}")
    return "\n".join(lines) + "\n"


# -- json -------------------------------------------------------------------------------------


def to_plain(item: Item, statuses: Statuses | None = None) -> dict[str, Any]:
    """The picture as plain data (what ``--format json`` prints and the live monitor draws)."""

    def plain(it: Item) -> dict[str, Any]:
        out: dict[str, Any] = {"path": it.path, "kind": it.kind, "title": it.title}
        if it.details:
            out["details"] = it.details
        if statuses is not None and it.path in statuses.nodes:
            out["status"] = statuses.nodes[it.path]
        if it.transitions:
            out["transitions"] = [{"outcome": o, "to": t, **({"if": g} if g else {})} for o, t, g in it.transitions]
        if it.initial:
            out["initial"] = it.initial
        if it.preemptions:
            out["preemptions"] = [{"when": c, "to": t} for c, t in it.preemptions]
        if it.children:
            out["children"] = [plain(c) for c in it.children]
        return out

    return plain(item)


def to_json(item: Item, statuses: Statuses | None = None) -> str:
    return json.dumps(to_plain(item, statuses), indent=2) + "\n"


def render(item: Item, fmt: str, statuses: Statuses | None = None) -> bytes:
    """One picture in one format; svg and png need Graphviz's `dot`."""
    if fmt in ("ascii", "unicode"):
        return to_text(item, fmt == "unicode", statuses).encode()
    if fmt == "dot":
        return to_dot(item, statuses).encode()
    if fmt in ("svg", "png"):
        return graphviz(to_dot(item, statuses), fmt)
    if fmt == "mermaid":
        return to_mermaid(item, statuses).encode()
    if fmt == "json":
        return to_json(item, statuses).encode()
    raise ValueError(f"unknown format {fmt!r}")
