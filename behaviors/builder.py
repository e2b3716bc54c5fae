"""Trees and machines from plain dict specs (what the mission YAML maps onto).

A node spec is a mapping with one *kind* key and optional options beside it::

    {"sequence": [ ...children... ], "name": "patrol", "memory": False}
    {"wait": {"duration": 5}}                      # a skill, inputs as the value
    {"skill": "wait", "inputs": {"duration": 5}}   # the same, spelled out
    {"timeout": 10, "child": {...}}                # decorators with an argument take `child`
    {"inverter": {...}}                            # ... those without take the child directly
    {"while": "battery_pct > 20", "child": {...}}  # eternal guard
    {"subtree": "approach", "remap": {"target": "crowd_centre"}}
    {"machine": "docking"}                         # a named (or inline) state machine

Which kinds exist, and how each is built, is the node-kind registry's (``botstage.behaviors.kinds``);
the builder reads a spec's shape, checks it and names the nodes. Inputs are literals, or
blackboard keys written ``"{key}"`` (YAML's ``{key}`` also works). Every problem is collected
with the spec path where it was found, then raised together.
"""

from __future__ import annotations

import ast
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import py_trees
from pydantic import ValidationError

from botstage.behaviors.blackboard import BlackboardError, normalise_key
from botstage.behaviors.kinds import CompositeKind, DecoratorKind, NodeBuild, NodeKind, NodeKinds
from botstage.behaviors.kinds.base import argument_adapter
from botstage.behaviors.machine import MachineBehaviour, MachinePlan
from botstage.behaviors.machine_plan import MachinePlanner
from botstage.behaviors.runtime import Runtime
from botstage.behaviors.skill_binding import SkillBinder, success_outcomes
from botstage.robots.limits import MAX_NODE_DEPTH
from botstage.robots.suggest import did_you_mean
from botstage.skills.expression import Expression, ExpressionError, compile_expression, key_of

__all__ = ["Builder", "KeyUsage", "Scope", "SpecError", "SpecPath", "SpecProblem", "remap_condition", "remap_key"]

SpecPath = tuple[str | int, ...]
COMMON_OPTIONS = frozenset({"name"})


@dataclass(frozen=True)
class KeyUsage:
    """A node reads or writes a blackboard key, at this place of the spec, through a port of this type."""

    key: str
    mode: str  # read or write
    spec_path: SpecPath
    type: Any = Any
    node: str = ""


@dataclass(frozen=True)
class SpecProblem:
    path: SpecPath
    message: str
    hint: str = ""

    def __str__(self) -> str:
        where = "/".join(str(p) for p in self.path) or "<root>"
        return f"{where}: {self.message}" + (f" ({self.hint})" if self.hint else "")


class SpecError(ValueError):
    def __init__(self, problems: Sequence[SpecProblem]) -> None:
        self.problems = list(problems)
        super().__init__("\n".join(str(p) for p in self.problems))


@dataclass(frozen=True)
class Scope:
    """Where a node is being built: its trace path, its spec's place, the key remapping of the
    subtrees around it, the trees and machines entered on the way (to refuse cycles) and how
    deep it is (children, subtrees and states each count one: building recurses)."""

    path: str
    spec_path: SpecPath
    remap: Mapping[str, str] = field(default_factory=dict)
    subtrees: tuple[str, ...] = ()
    depth: int = 0

    def key(self, key: str) -> str:
        return remap_key(key, self.remap)

    def child(self, segment: str, *spec: str | int) -> Scope:
        return replace(
            self,
            path=f"{self.path}/{segment}" if self.path else segment,
            spec_path=self.spec_path + spec,
            depth=self.depth + 1,
        )

    def at(self, path: str) -> Scope:
        return replace(self, path=path)

    def under(self, spec_path: SpecPath) -> Scope:
        return replace(self, spec_path=spec_path)


class Builder:
    """Builds trees and machines for one run; problems are collected, then raised as SpecError."""

    def __init__(
        self,
        runtime: Runtime,
        trees: Mapping[str, Any] | None = None,
        machines: Mapping[str, Any] | None = None,
        skill_params: Mapping[str, Mapping[str, Any]] | None = None,
        spec_root: SpecPath = (),
        kinds: NodeKinds | None = None,
    ) -> None:
        self.runtime = runtime
        self.kinds = kinds or NodeKinds.default()
        self.trees = dict(trees or {})
        self.machines = dict(machines or {})
        self.skill_params = dict(skill_params or {})
        self.spec_root = spec_root
        self.problems: list[SpecProblem] = []
        self.usages: list[KeyUsage] = []
        self.plans: list[MachinePlan] = []  # every machine planned, even one with problems
        self.entered: set[tuple[str, str]] = set()  # ("trees" or "machines", name) built through a reference
        self.skills_used: dict[str, list[SpecPath]] = {}  # skill name -> where each of its nodes is written
        self._too_deep = False  # reported once: past the limit, every branch would report it again
        # a skill node, shared by tree leaves (the skill and condition kinds) and machine states
        self.skill_node = SkillBinder(self).node
        self._machines = MachinePlanner(self)

    # -- public -----------------------------------------------------------------------------

    def tree(self, spec: Any, name: str = "root", spec_path: SpecPath | None = None) -> py_trees.behaviour.Behaviour:
        node = self.node(spec, Scope(name, spec_path if spec_path is not None else self.spec_root))
        self._raise_problems()
        assert node is not None
        return node

    def named_tree(self, name: str) -> py_trees.behaviour.Behaviour:
        if name not in self.trees:
            raise SpecError([SpecProblem((), f"unknown tree {name!r}", did_you_mean(name, self.trees))])
        node = self.node(self.trees[name], Scope(name, ("trees", name), subtrees=(name,)))
        self._raise_problems()
        assert node is not None
        return node

    def machine(self, spec: Any, name: str = "machine", spec_path: SpecPath | None = None) -> MachineBehaviour:
        scope = Scope(name, spec_path if spec_path is not None else self.spec_root)
        node = self._machines.machine(spec, scope, name)
        self._raise_problems()
        assert node is not None
        return node

    # -- services for node kinds and the machine planner -------------------------------------

    def problem(self, spec_path: SpecPath, message: str, hint: str = "") -> None:
        self.problems.append(SpecProblem(spec_path, message, hint))

    def key(self, raw: Any, spec_path: SpecPath, scope: Scope) -> str | None:
        """A blackboard key as written, checked and remapped; None (and a problem) if malformed."""
        try:
            return scope.key(normalise_key(raw))
        except BlackboardError as exc:
            self.problem(spec_path, str(exc))
            return None

    def use(self, key: str, mode: str, spec_path: SpecPath, scope: Scope, tp: Any = Any) -> None:
        self.usages.append(KeyUsage(key, mode, spec_path, tp, scope.path))

    def expression(self, value: Any, spec_path: SpecPath, scope: Scope) -> Expression | None:
        """A condition compiled and remapped, its keys recorded as read; None (and a problem) if bad."""
        if not isinstance(value, str):
            self.problem(spec_path, f"expected a condition (a string), got {type(value).__name__}")
            return None
        try:
            expression = compile_expression(value)
        except ExpressionError as exc:
            self.problem(spec_path, str(exc))
            return None
        if scope.remap and any(scope.key(k) != k for k in expression.keys):
            expression = compile_expression(remap_condition(expression.source, scope.remap))
        keys = [self.key(key, spec_path, Scope("", ())) for key in sorted(expression.keys)]
        if None in keys:
            return None
        for key in keys:
            self.use(key, "read", spec_path, scope)  # type: ignore[arg-type]
        return expression

    def remapped_condition(self, source: str, scope: Scope) -> str:
        return remap_condition(source, scope.remap) if scope.remap else source

    def success_on(
        self, value: Any, outcomes: Iterable[str], spec_path: SpecPath, default: Iterable[str] = ("success",)
    ) -> frozenset[str] | None:
        found, problem, where, hint = success_outcomes(value, outcomes, default)
        if problem:
            self.problem(spec_path + where, problem, hint)
        return found

    def reference(
        self, label: str, name: Any, table: Mapping[str, Any], scope: Scope, where: SpecPath
    ) -> tuple[Any, Scope] | None:
        """A named tree or machine and the scope to build it in; None (and a problem) if it is
        unknown or would enter itself again. ``label`` is tree, subtree or machine."""
        noun = "machine" if label == "machine" else "tree"
        if not isinstance(name, str) or name not in table:
            self.problem(where, f"unknown {noun} {name!r}", did_you_mean(name, table))
            return None
        entry = f"machine {name}" if noun == "machine" else name
        if entry in scope.subtrees:
            self.problem(where, f"{label} cycle: {' -> '.join((*scope.subtrees, entry))}")
            return None
        if not self._shallow(scope, where):
            return None
        self.entered.add((f"{noun}s", name))
        inner = Scope(scope.path, (f"{noun}s", name), scope.remap, (*scope.subtrees, entry), scope.depth + 1)
        return table[name], inner

    def _shallow(self, scope: Scope, where: SpecPath) -> bool:
        """False (and a problem) where nesting goes deeper than the limit: building recurses."""
        if scope.depth < MAX_NODE_DEPTH:
            return True
        if not self._too_deep:
            self._too_deep = True
            self.problem(
                where,
                f"nested more than {MAX_NODE_DEPTH} levels deep (counting subtrees, machines and states)",
                "split it into smaller trees side by side",
            )
        return False

    def subtree(self, spec: Mapping[str, Any], scope: Scope) -> py_trees.behaviour.Behaviour | None:
        found = self.reference("subtree", spec["subtree"], self.trees, scope, scope.spec_path + ("subtree",))
        if found is None:
            return None
        tree_spec, inner = found
        remap = spec.get("remap", {})
        if not isinstance(remap, Mapping) or not all(
            isinstance(k, str) and isinstance(v, str) for k, v in remap.items()
        ):
            self.problem(scope.spec_path + ("remap",), "remap must map inner key names to outer key names")
            remap = {}
        merged = {k: scope.key(v) for k, v in remap.items()}
        for key, value in scope.remap.items():
            merged.setdefault(key, value)
        return self.node(tree_spec, replace(inner, remap=merged))

    def machine_ref(self, spec: Mapping[str, Any], scope: Scope) -> MachineBehaviour | None:
        ref = spec["machine"]
        name = scope.path.rsplit("/", 1)[-1]
        if not isinstance(ref, str):
            return self._machines.machine(ref, scope.under(scope.spec_path + ("machine",)), name)
        found = self.reference("machine", ref, self.machines, scope, scope.spec_path + ("machine",))
        if found is None:
            return None
        machine_spec, inner = found
        return self._machines.machine(machine_spec, inner, name)

    # -- nodes ------------------------------------------------------------------------------

    def node(self, spec: Any, scope: Scope) -> py_trees.behaviour.Behaviour | None:
        """Build the node ``spec`` describes at ``scope``; None (and problems) if it cannot be."""
        if isinstance(spec, str) and spec in self.runtime.registry:
            spec = {spec: None}  # a bare skill name with no inputs
        if not self._shallow(scope, scope.spec_path):
            return None
        if not isinstance(spec, Mapping):
            self.problem(scope.spec_path, f"expected a node (a mapping), got {type(spec).__name__}")
            return None
        found = self._kind_of(spec, scope)
        if found is None:
            return None
        key, kind = found
        b = NodeBuild(
            kind=kind,
            key=key,
            name=scope.path.rsplit("/", 1)[-1],
            path=scope.path,
            spec=spec,
            spec_path=scope.spec_path,
            options=self._options(spec, key, kind, scope),
            runtime=self.runtime,
            builder=self,
            scope=scope,
            value=spec[key],
        )
        if isinstance(kind, CompositeKind):
            b.children = self._children(spec[key], scope, key)
        elif isinstance(kind, DecoratorKind) and not self._decorated(b):
            return None
        node = kind.build(b)
        if node is not None:
            if not hasattr(node, "path"):
                node.path = scope.path
            if getattr(node, "node_kind", None) is None:
                node.node_kind = kind
        return node

    def _kind_of(self, spec: Mapping[str, Any], scope: Scope) -> tuple[str, NodeKind] | None:
        """The spec's one kind key, and the kind it names (a skill's name names the skill kind)."""
        keys = [k for k in spec if isinstance(k, str) and (k in self.kinds or k in self.runtime.registry)]
        if len(keys) == 1:
            key = keys[0]
            return key, self.kinds.get(key if key in self.kinds else "skill")
        if not keys:
            unknown = [k for k in spec if k not in COMMON_OPTIONS]
            if unknown:
                self.problem(
                    scope.spec_path + (unknown[0],),
                    f"unknown node or skill {unknown[0]!r}",
                    self._broken_plugin(unknown[0]) or did_you_mean(unknown[0], [*self.kinds, *self.runtime.registry]),
                )
            else:
                self.problem(scope.spec_path, "a node needs a kind (a skill, sequence, selector, ...)")
            return None
        self.problem(scope.spec_path, f"a node has exactly one kind, found {', '.join(map(repr, keys))}")
        return None

    def _broken_plugin(self, name: object) -> str:
        """Why a plug-in of this name is missing, if one failed to load."""
        for problem in [*self.kinds.problems, *self.runtime.registry.problems]:
            if problem.entry_point.split(" =")[0] == name:
                return f"the plugin {problem.entry_point!r} failed to load: {problem.reason}"
        return ""

    def _options(self, spec: Mapping[str, Any], key: str, kind: NodeKind, scope: Scope) -> Any:
        """The kind's options, validated; unknown and wrong ones are reported (with a suggestion)."""
        allowed = kind.option_names()
        given = {}
        for option, value in spec.items():
            if option == key or option in COMMON_OPTIONS:
                continue
            if option in allowed:
                given[option] = value
            else:
                self.problem(
                    scope.spec_path + (option,),
                    f"unknown option {option!r} for {key!r}",
                    did_you_mean(option, allowed | COMMON_OPTIONS),
                )
        given.pop("child", None)  # a decorator's child is built, not an option
        try:
            return kind.Options.model_validate(given)
        except ValidationError as exc:
            for error in exc.errors():
                field_name = ".".join(str(part) for part in error["loc"])
                message = error["msg"][:1].lower() + error["msg"][1:]
                self.problem(scope.spec_path + tuple(error["loc"]), f"{field_name} of {key!r}: {message}")
            # go on with the defaults, so problems below this node are reported too
            return kind.Options.model_construct()

    def _decorated(self, b: NodeBuild) -> bool:
        """Build a decorator's child and check its argument; False (and problems) if either fails."""
        kind: DecoratorKind = b.kind  # type: ignore[assignment]
        scope = b.scope
        if kind.argument is None:
            child_spec, child_key = b.value, b.key
        elif "child" not in b.spec:
            self.problem(scope.spec_path, f"{b.key!r} needs a `child` node")
            return False
        else:
            child_spec, child_key = b.spec["child"], "child"
        child_scope = scope.child(self.default_name(child_spec), child_key)
        child = self.node(child_spec, child_scope)
        if child is None:
            return False
        child.name = child_scope.path.rsplit("/", 1)[-1]
        b.children = [child]
        if kind.argument is None:
            return True
        try:
            b.value = argument_adapter(kind.argument).validate_python(b.value)
        except ValidationError as exc:
            message = exc.errors()[0]["msg"]
            hint = f"{b.key} takes {kind.argument_help}" if kind.argument_help else ""
            self.problem(scope.spec_path + (b.key,), f"{b.key}: {message[:1].lower() + message[1:]}", hint)
            return False
        return True

    def _children(self, items: Any, scope: Scope, key: str) -> list[py_trees.behaviour.Behaviour]:
        if not isinstance(items, list) or not items:
            self.problem(scope.spec_path + (key,), f"{key!r} needs a non-empty list of children")
            return []
        built = []
        names = _Names()
        explicit: dict[str, int] = {}
        for index, item in enumerate(items):
            given = item.get("name") if isinstance(item, Mapping) else None
            if isinstance(given, str):
                if given in explicit:
                    self.problem(
                        scope.spec_path + (key, index, "name"),
                        f"duplicate node name {given!r}",
                        f"sibling {explicit[given]} has it too; names identify nodes in traces",
                    )
                explicit.setdefault(given, index)
            segment = names.unique(self.default_name(item))
            node = self.node(item, scope.child(segment, key, index))
            if node is not None:
                node.name = segment
                built.append(node)
        return built

    def default_name(self, spec: Any) -> str:
        """A node's name: the spec's `name`, else what its kind calls it (a skill's name ...)."""
        if isinstance(spec, str):
            return spec
        if not isinstance(spec, Mapping):
            return "node"
        name = spec.get("name")
        if isinstance(name, str) and name and "/" not in name:
            return name
        for key in spec:
            if isinstance(key, str):
                if key in self.kinds:
                    return self.kinds.get(key).default_name(spec)
                if key in self.runtime.registry:
                    return key
        return "node"

    def _raise_problems(self) -> None:
        self._too_deep = False  # once per tree or machine built
        if self.problems:
            problems, self.problems = self.problems, []
            raise SpecError(problems)


class _Names:
    """Sibling names made unique as ``name``, ``name#2``, ``name#3`` ... in constant time each."""

    def __init__(self) -> None:
        self.taken: set[str] = set()
        self.next: dict[str, int] = {}

    def unique(self, name: str) -> str:
        if name not in self.taken:
            self.taken.add(name)
            return name
        n = self.next.get(name, 2)
        while f"{name}#{n}" in self.taken:
            n += 1
        self.next[name] = n + 1
        self.taken.add(f"{name}#{n}")
        return f"{name}#{n}"


def remap_key(key: str, remap: Mapping[str, str]) -> str:
    """A subtree's remapping renames a key, or a whole namespace: {robot: r2} maps robot/mode too."""
    best = ""
    for inner in remap:
        if (key == inner or key.startswith(inner + "/")) and len(inner) > len(best):
            best = inner
    return remap[best] + key[len(best) :] if best else key


def remap_condition(source: str, remap: Mapping[str, str]) -> str:
    """Rewrite the key names of a condition through a subtree's remapping."""

    def as_expr(key: str) -> ast.expr:
        parts = key.split("/")
        expr: ast.expr = ast.Name(parts[0], ast.Load())
        for part in parts[1:]:
            expr = ast.Attribute(expr, part, ast.Load())
        return expr

    class _Rename(ast.NodeTransformer):
        def _swap(self, node: ast.expr) -> ast.AST:
            key = key_of(node)
            if key is None:
                return self.generic_visit(node)
            mapped = remap_key(key, remap)
            return ast.copy_location(as_expr(mapped), node) if mapped != key else node

        visit_Name = _swap
        visit_Attribute = _swap

    return ast.unparse(_Rename().visit(ast.parse(source.strip(), mode="eval")))
