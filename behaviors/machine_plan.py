"""Plans hierarchical state machines from their specs: states and what each runs, nested
levels, transitions with guards, timeouts, entry and exit actions and preemptions, every
problem reported where it was written. The plan becomes a ``MachineBehaviour``."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from botstage.behaviors.machine import (
    Action,
    Level,
    MachineBehaviour,
    MachinePlan,
    StateInfo,
    Target,
    Unresolved,
    plan_access,
    resolve_outcome,
    resolve_target,
)
from botstage.robots.limits import PositiveSeconds, number_problem
from botstage.robots.suggest import did_you_mean
from botstage.skills.expression import Expression

if TYPE_CHECKING:
    from botstage.behaviors.builder import Builder, Scope, SpecPath

STATE_KEYS = {
    "skill",
    "inputs",
    "outputs",
    "params",
    "tree",
    "machine",
    "transitions",
    "timeout",
    "on_enter",
    "on_exit",
    "success_on",
}
MACHINE_KEYS = {"initial", "states", "outcomes", "preemptions", "success_on", "name"}
SKILL_STATE_KEYS = ("inputs", "outputs", "params", "success_on")
Preemptions = list[tuple[Expression, list[Target]]]


class MachinePlanner:
    """Plans machines for one builder (whose trees, skills and problem list it shares)."""

    def __init__(self, builder: Builder) -> None:
        self.b = builder

    def machine(self, spec: Any, scope: Scope, name: str) -> MachineBehaviour | None:
        states: dict[str, StateInfo] = {}
        preemptions: Preemptions = []
        level = self.level(spec, scope, "", states, preemptions)
        if level is None:
            return None
        outcomes = level.outcomes
        top = [level.full(n) for n in [*outcomes, *level.names]]
        self._resolve_outcomes(states, preemptions)
        # By default a machine succeeds on `success`, or else on the first outcome it declares.
        default = "success" if "success" in outcomes else outcomes[0]
        success_on = self.b.success_on(spec.get("success_on", default), outcomes, scope.spec_path + ("success_on",))
        if success_on is None:
            success_on = frozenset({default})
        reads, writes = plan_access(states, preemptions)
        plan = MachinePlan(
            initial=level.initial,
            states=states,
            top=top,
            outcomes=outcomes,
            preemptions=preemptions,
            level=level,
            success_on=success_on,
            reads=reads,
            writes=writes,
        )
        self.b.plans.append(plan)
        if self.b.problems:
            return None
        return MachineBehaviour(name, scope.path, plan, self.b.runtime)

    def _resolve_outcomes(self, states: dict[str, StateInfo], preemptions: Preemptions) -> None:
        """Turn targets that are outcomes of nested machines into direct transitions."""
        local = {path: dict(info.transitions) for path, info in states.items()}
        for path, info in states.items():
            for outcome in list(info.transitions):
                try:
                    info.transitions[outcome] = resolve_outcome(states, local, path, outcome)
                except Unresolved as exc:
                    self.b.problem(states[exc.state].spec_path, str(exc))
                    info.transitions[outcome] = []
        levels = [preemptions] + [i.preemptions for i in states.values() if i.preemptions]
        for items in levels:
            for index, (condition, targets) in enumerate(items):
                try:
                    step = (f"preempt {condition.source!r}",)
                    direct = [d for t in targets for d in resolve_target(states, local, t, step)]
                except Unresolved as exc:
                    self.b.problem(states[exc.state].spec_path, str(exc))
                    direct = []
                items[index] = (condition, direct)

    # -- levels -----------------------------------------------------------------------------

    def level(
        self, spec: Any, scope: Scope, prefix: str, states: dict[str, StateInfo], preemptions: Preemptions
    ) -> Level | None:
        """Add one level's states (and their nested levels) under ``prefix``."""
        if not isinstance(spec, Mapping):
            self.b.problem(scope.spec_path, f"a machine is a mapping with `states`, got {type(spec).__name__}")
            return None
        for key in spec:
            if key not in MACHINE_KEYS:
                self.b.problem(
                    scope.spec_path + (key,), f"unknown machine option {key!r}", did_you_mean(key, MACHINE_KEYS)
                )
        state_specs = spec.get("states")
        if not isinstance(state_specs, Mapping) or not state_specs:
            self.b.problem(scope.spec_path + ("states",), "a machine needs `states`: a mapping of name: state")
            return None
        outcomes = self._outcomes(spec, scope)
        names = list(state_specs)
        if not self._state_names(names, outcomes, scope):
            return None
        initial = spec.get("initial", names[0])
        if not isinstance(initial, str) or initial not in state_specs:
            self.b.problem(
                scope.spec_path + ("initial",),
                f"initial state {initial!r} is not a state",
                did_you_mean(initial, names),
            )
            initial = names[0]
        level = Level(prefix, scope.spec_path, "", outcomes, names)
        level.initial = level.full(initial)
        parent = prefix or None
        for outcome in outcomes:
            states[level.full(outcome)] = StateInfo(level.full(outcome), parent, outcome=outcome, kind="outcome")
        for name, state_spec in state_specs.items():
            self.state(name, state_spec, scope.child(name, "states", name), level, states, parent)
        self._preemptions(spec.get("preemptions") or [], scope, level, preemptions)
        return level

    def _outcomes(self, spec: Mapping[str, Any], scope: Scope) -> list[str]:
        outcomes = spec.get("outcomes", ["success", "failure"])
        if not isinstance(outcomes, list) or not outcomes or not all(isinstance(o, str) for o in outcomes):
            self.b.problem(scope.spec_path + ("outcomes",), "outcomes must be a non-empty list of names")
            return ["success", "failure"]
        return outcomes

    def _state_names(self, names: list[Any], outcomes: list[str], scope: Scope) -> bool:
        for name in names:
            if not isinstance(name, str) or not name.isidentifier() or name.startswith("__"):
                self.b.problem(
                    scope.spec_path + ("states", str(name)),
                    f"state name {name!r} must be an identifier (letters, digits, _)",
                )
                return False
            if name in outcomes:
                self.b.problem(
                    scope.spec_path + ("states", name), f"state {name!r} has the name of one of the machine's outcomes"
                )
        return True

    def _preemptions(self, specs: Any, scope: Scope, level: Level, preemptions: Preemptions) -> None:
        if not isinstance(specs, list):
            self.b.problem(scope.spec_path + ("preemptions",), "preemptions is a list of {when: ..., to: ...}")
            return
        for index, item in enumerate(specs):
            item_path = scope.spec_path + ("preemptions", index)
            if not isinstance(item, Mapping) or set(item) != {"when", "to"}:
                self.b.problem(item_path, "a preemption is {when: <condition>, to: <state or outcome>}")
                continue
            condition = self.b.expression(item["when"], item_path + ("when",), scope)
            target = item["to"]
            if not isinstance(target, str) or (target not in level.names and target not in level.outcomes):
                self.b.problem(
                    item_path + ("to",),
                    f"unknown state or outcome {target!r}",
                    did_you_mean(target, [*level.names, *level.outcomes]),
                )
                continue
            level.preemptions.append((str(item["when"]), str(target)))
            if condition is not None:
                preemptions.append((condition, [Target(level.full(target))]))

    # -- states -----------------------------------------------------------------------------

    def state(
        self,
        name: str,
        spec: Any,
        scope: Scope,
        level: Level,
        states: dict[str, StateInfo],
        parent: str | None,
    ) -> None:
        info = StateInfo(level.full(name), parent, spec_path=scope.spec_path)
        states[info.path] = info
        if not isinstance(spec, Mapping):
            self.b.problem(scope.spec_path, f"state {name!r} must be a mapping with a skill, tree or machine")
            return
        for key in spec:
            if key not in STATE_KEYS:
                self.b.problem(scope.spec_path + (key,), f"unknown state option {key!r}", did_you_mean(key, STATE_KEYS))
        contents = [k for k in ("skill", "tree", "machine") if k in spec]
        if len(contents) != 1:
            self.b.problem(scope.spec_path, f"state {name!r} needs exactly one of skill, tree or machine")
            return
        possible = self._content(contents[0], spec, scope, info, states)
        if possible is None:
            return
        possible |= self._timeout(spec.get("timeout"), scope, info)
        info.possible = frozenset(possible)
        info.on_enter = self._actions(spec.get("on_enter"), scope.spec_path + ("on_enter",), scope)
        info.on_exit = self._actions(spec.get("on_exit"), scope.spec_path + ("on_exit",), scope)
        self._transitions(name, spec.get("transitions") or {}, scope, level, info)

    def _content(
        self, kind: str, spec: Mapping[str, Any], scope: Scope, info: StateInfo, states: dict[str, StateInfo]
    ) -> set[str] | None:
        """Plan what the state runs; the outcomes it can end with, None if it cannot be planned."""
        if kind != "skill":
            for key in SKILL_STATE_KEYS:
                if key in spec:
                    self.b.problem(
                        scope.spec_path + (key,),
                        f"only a skill state takes {key!r}",
                        "give it to the skill inside the tree or machine",
                    )
        if kind == "skill":
            return self._skill_state(spec, scope, info)
        if kind == "tree":
            self._tree_state(spec["tree"], scope, info)
            return {"success", "failure"}
        return self._machine_state(spec["machine"], scope, info, states)

    def _skill_state(self, spec: Mapping[str, Any], scope: Scope, info: StateInfo) -> set[str]:
        node = self.b.skill_node(
            spec["skill"],
            spec.get("inputs") or {},
            spec.get("outputs") or {},
            spec.get("success_on"),
            spec.get("params"),
            scope,
            scope.spec_path + ("inputs",),
        )
        info.kind, info.label = "skill", str(spec["skill"])
        if node is None:
            return {"success", "failure"}
        info.content = node
        return set(type(node.skill).all_outcomes)

    def _tree_state(self, tree: Any, scope: Scope, info: StateInfo) -> None:
        info.kind, info.label = "tree", tree if isinstance(tree, str) else ""
        if isinstance(tree, str):
            found = self.b.reference("tree", tree, self.b.trees, scope, scope.spec_path + ("tree",))
            if found is None:
                return
            tree_spec, inner = found
            info.content = self.b.node(tree_spec, inner.at(f"{scope.path}/{tree}"))
        else:
            info.content = self.b.node(tree, scope.child("tree", "tree"))
        if info.content is not None:
            info.content.name = info.content.path.rsplit("/", 1)[-1]

    def _machine_state(
        self, nested: Any, scope: Scope, info: StateInfo, states: dict[str, StateInfo]
    ) -> set[str] | None:
        info.kind, info.label = "machine", nested if isinstance(nested, str) else ""
        nested_scope = scope.under(scope.spec_path + ("machine",))
        if isinstance(nested, str):
            found = self.b.reference("machine", nested, self.b.machines, scope, scope.spec_path + ("machine",))
            if found is None:
                return None
            nested, nested_scope = found
            nested_scope = nested_scope.at(scope.path)
        level = self.level(nested, nested_scope, info.path, states, info.preemptions)
        if level is None:
            return None
        info.level, info.initial = level, level.initial
        return set(level.outcomes)

    def _timeout(self, timeout: Any, scope: Scope, info: StateInfo) -> set[str]:
        if timeout is None:
            return set()
        problem = number_problem(PositiveSeconds, timeout)
        if problem:
            self.b.problem(scope.spec_path + ("timeout",), f"timeout: {problem}", "a positive number of seconds")
            return set()
        info.timeout = float(timeout)
        return {"timeout"}

    def _transitions(self, name: str, transitions: Any, scope: Scope, level: Level, info: StateInfo) -> None:
        if not isinstance(transitions, Mapping):
            self.b.problem(scope.spec_path + ("transitions",), "transitions map outcomes to states")
            return
        for outcome, targets in transitions.items():
            where = scope.spec_path + ("transitions", outcome)
            if outcome not in info.possible:
                self.b.problem(
                    where,
                    f"state {name!r} never ends with outcome {outcome!r}",
                    did_you_mean(outcome, info.possible) or "possible: " + ", ".join(sorted(info.possible)),
                )
                continue
            entries = targets if isinstance(targets, list) else [targets]
            written = info.written.setdefault(outcome, [])
            resolved = []
            for index, entry in enumerate(entries):
                e_path = where + ((index,) if isinstance(targets, list) else ())
                target = self._target(entry, e_path, scope, level)
                if target is not None:
                    resolved.append(target)
                    written.append((target.state.rsplit("/", 1)[-1], target.guards[0].source if target.guards else ""))
            info.transitions[outcome] = resolved

    def _target(self, entry: Any, where: SpecPath, scope: Scope, level: Level) -> Target | None:
        """One transition's target, with its guard: ``state`` or ``{to: state, if: condition}``."""
        guard = None
        if isinstance(entry, Mapping):
            if "to" not in entry or set(entry) - {"to", "if"}:
                self.b.problem(where, "a guarded transition is {to: <state>, if: <condition>}")
                return None
            if "if" in entry:
                guard = self.b.expression(entry["if"], where + ("if",), scope)
            entry = entry["to"]
        if not isinstance(entry, str) or (entry not in level.names and entry not in level.outcomes):
            self.b.problem(
                where, f"transition to unknown state {entry!r}", did_you_mean(entry, [*level.names, *level.outcomes])
            )
            return None
        return Target(level.full(entry), (guard,) if guard is not None else ())

    def _actions(self, value: Any, spec_path: SpecPath, scope: Scope) -> list[Action]:
        if value is None:
            return []
        items = value if isinstance(value, list) else [value]
        actions = []
        for index, item in enumerate(items):
            item_path = spec_path + ((index,) if isinstance(value, list) else ())
            if isinstance(item, Mapping) and set(item) == {"set"} and isinstance(item["set"], Mapping):
                for key, val in item["set"].items():
                    checked = self.b.key(key, item_path + ("set", key), scope)
                    if checked is not None:
                        actions.append(Action("set", checked, val))
                        self.b.use(checked, "write", item_path + ("set", key), scope)
            elif isinstance(item, Mapping) and set(item) == {"log"}:
                actions.append(Action("log", value=str(item["log"])))
            else:
                self.b.problem(item_path, "an action is {set: {key: value, ...}} or {log: message}")
        return actions
