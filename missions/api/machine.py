"""State machines built in Python, as YASMIN's ``StateMachine.add_state`` builds them.

A machine lowers to exactly the mapping its YAML spelling loads as: ``states``, each with what it
runs (a skill, a tree or a nested machine) and the transitions its outcomes take, ``outcomes``,
``initial`` and ``preemptions``. Each state and preemption remembers the line that added it, so
a transition to an unknown state is reported there.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from botstage.missions.api.lowering import Lowering, Part, SpecPath, in_order
from botstage.missions.api.nodes import MachineRef, Node, NodeLike, Skill, as_node
from botstage.missions.api.where import caller
from botstage.missions.loader import Location

STATE_OPTIONS = ("inputs", "outputs", "params", "success_on")  # a skill state's, besides the skill


class State(Part):
    """One state: its spec mapping (skill, tree or machine, transitions, timeout, actions)."""

    def __init__(self, options: dict[str, Any], where: Location | None) -> None:
        self.options = options
        self.where = where

    def lower(self, low: Lowering, path: SpecPath) -> dict[str, Any]:
        return {name: low.value(option, path + (name,)) for name, option in self.options.items()}

    def __repr__(self) -> str:
        runs = next((f"{k}={v!r}" for k, v in self.options.items() if k in ("skill", "tree", "machine")), "")
        return f"<State {runs}>"


class Preemption(Part):
    """``when`` this condition holds, whatever runs is cancelled and the machine goes ``to``."""

    def __init__(self, when: str, to: str, where: Location | None) -> None:
        self.when, self.to, self.where = when, to, where

    def lower(self, low: Lowering, path: SpecPath) -> dict[str, Any]:
        return {"when": low.value(self.when, path + ("when",)), "to": low.value(self.to, path + ("to",))}


class StateMachine(Part):
    """A (hierarchical) state machine; its outcomes default to success and failure.

    ``initial`` defaults to the first state added. A machine is a tree node too: put it among a
    sequence's children, or give it to ``add_state(machine=...)`` to nest it.
    """

    def __init__(
        self,
        outcomes: Iterable[str] | None = None,
        initial: str | None = None,
        *,
        name: str | None = None,
        success_on: str | Iterable[str] | None = None,
    ) -> None:
        self.outcomes = list(outcomes) if outcomes is not None else None
        self.initial = initial
        self.name = name
        self.success_on = success_on if success_on is None or isinstance(success_on, str) else list(success_on)
        self.states: dict[str, Any] = {}
        self.preemptions: list[Any] = []
        self.extra: dict[str, Any] = {}  # what a file said that a machine does not take (reported by check)
        self.where: Location | None = caller()
        self.order: tuple[str, ...] | None = None  # a file's key order

    @classmethod
    def of(cls, spec: Mapping[str, Any], states: dict[str, Any], preemptions: list[Any]) -> StateMachine:
        """A machine from a file's parts, without recording a caller."""
        machine = cls.__new__(cls)
        machine.outcomes = spec.get("outcomes")
        machine.initial = spec.get("initial")
        machine.name = spec.get("name")
        machine.success_on = spec.get("success_on")
        machine.states, machine.preemptions, machine.where = states, preemptions, None
        machine.extra = {k: v for k, v in spec.items() if k not in MACHINE_FIELDS}
        machine.order = tuple(spec)
        return machine

    def add_state(
        self,
        name: str,
        *,
        skill: str | Skill | None = None,
        tree: NodeLike | None = None,
        machine: StateMachine | Mapping[str, Any] | str | None = None,
        transitions: Mapping[str, Any] | None = None,
        inputs: Mapping[str, Any] | None = None,
        outputs: Mapping[str, str] | None = None,
        params: Mapping[str, Any] | None = None,
        success_on: str | Iterable[str] | None = None,
        timeout: float | None = None,
        on_enter: Any = None,
        on_exit: Any = None,
    ) -> StateMachine:
        """Add a state running a skill (a name, or ``Skill(...)`` with its inputs), a tree (a named
        tree or a node) or a machine (a named one or a StateMachine); ``transitions`` map each
        outcome to a state, an outcome of this machine, or guarded targets ``[{to:, if:}, ...]``."""
        if name in self.states:
            raise ValueError(f"this machine already has a state {name!r}")
        options: dict[str, Any] = {}
        given = {"inputs": inputs, "outputs": outputs, "params": params, "success_on": success_on}
        if isinstance(skill, Skill):  # the node's bindings; keywords given here win (inputs merge)
            options["skill"] = skill.value
            for option in STATE_OPTIONS:
                value = skill.options.get(option)
                if given[option] is not None:
                    value = {**value, **given[option]} if option == "inputs" and value else given[option]
                options[option] = value
        else:
            if isinstance(skill, Node):
                raise TypeError(f"skill= takes a skill's name or Skill(...); for {skill!r} use tree=")
            options["skill"] = skill
            options.update(given)
        if tree is not None:
            if isinstance(tree, StateMachine):
                raise TypeError("tree= takes a tree; give a StateMachine to machine=")
            options["tree"] = as_node(tree)
        options.update(machine=machine, timeout=timeout, on_enter=on_enter, on_exit=on_exit, transitions=transitions)
        if isinstance(options.get("success_on"), list | tuple):
            options["success_on"] = list(options["success_on"])
        self.states[name] = State({k: v for k, v in options.items() if v is not None}, caller())
        return self

    def add_preemption(self, when: str, to: str) -> StateMachine:
        """Whenever ``when`` holds (a condition on the blackboard), cancel what runs and go ``to``
        a state or outcome (an e-stop, a low battery)."""
        self.preemptions.append(Preemption(when, to, caller()))
        return self

    def lower(self, low: Lowering, path: SpecPath) -> dict[str, Any]:
        data: dict[str, Any] = {}
        for field in ("name", "initial", "outcomes", "success_on"):
            value = getattr(self, field)
            if value is not None:
                data[field] = low.value(value, path + (field,))
        if self.preemptions:
            data["preemptions"] = low.value(self.preemptions, path + ("preemptions",))
        data["states"] = low.value(self.states, path + ("states",))
        for name, value in self.extra.items():
            data[name] = low.value(value, path + (name,))
        return in_order(data, self.order)

    def as_node(self) -> MachineRef:
        return MachineRef.of(MachineRef.KIND, self, {}, self.where)  # type: ignore[return-value]

    def __repr__(self) -> str:
        where = f" at {self.where}" if self.where is not None else ""
        return f"<StateMachine {', '.join(self.states) or 'no states'}{where}>"


MACHINE_FIELDS = ("name", "initial", "outcomes", "success_on", "states", "preemptions")
