"""The built-in composites: sequences, selectors (fallbacks) and parallels, on py_trees."""

from __future__ import annotations

from typing import Any, ClassVar

import py_trees
from pydantic import Field

from botstage.behaviors.kinds.base import CompositeKind, KindOptions, NodeBuild
from botstage.robots.suggest import did_you_mean

PARALLEL_POLICIES = ("success_on_all", "success_on_one", "success_on_selected")


class MemoryOptions(KindOptions):
    memory: bool | None = Field(
        default=None,
        description="resume at the running child (true) or restart from the first each tick (false); "
        "default true, false for the reactive kinds",
    )


class Sequence(CompositeKind):
    """Children in order until one fails."""

    name = "sequence"
    description = "run the children in order; fail at the first that fails"
    shape = "sequence"
    Options = MemoryOptions
    memory_default: ClassVar[bool] = True
    behaviour: ClassVar[type[py_trees.composites.Composite]] = py_trees.composites.Sequence

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour:
        memory = self.memory_default if b.options.memory is None else b.options.memory
        return self.behaviour(name=b.name, memory=memory, children=b.children)

    def title(self, node: py_trees.behaviour.Behaviour) -> str:
        return self.shape if node.memory else f"reactive {self.shape}"


class ReactiveSequence(Sequence):
    name = "reactive_sequence"
    description = "a sequence that re-checks earlier children every tick"
    memory_default = False


class Selector(Sequence):
    """py_trees' name is the one listed; ``fallback`` (BehaviorTree.CPP's word) still reads as it,
    as an alias only, because the Python API's ``Fallback`` and missions written with it use it."""

    name = "selector"
    aliases = ("fallback",)
    description = "try the children in order until one succeeds (a fallback)"
    shape = "selector"
    behaviour = py_trees.composites.Selector


class ReactiveSelector(Selector):
    """``reactive_fallback`` is an alias only, as ``fallback`` is for ``selector``."""

    name = "reactive_selector"
    aliases = ("reactive_fallback",)
    description = "a selector that re-tries higher-priority children every tick, halting a lower one"
    memory_default = False


class ParallelOptions(KindOptions):
    policy: str = Field(
        default="success_on_all",
        description="when the parallel succeeds: all children, one, or the selected ones",
        json_schema_extra={"enum": list(PARALLEL_POLICIES)},
    )
    synchronise: bool = Field(default=True, description="a child that succeeded is not ticked again")
    selected: list[str] | None = Field(default=None, description="with success_on_selected: the children's names")


class Parallel(CompositeKind):
    name = "parallel"
    description = "tick every child each tick; the policy says when it succeeds"
    shape = "parallel"
    Options = ParallelOptions

    def build(self, b: NodeBuild) -> py_trees.behaviour.Behaviour:
        options: ParallelOptions = b.options
        policies = py_trees.common.ParallelPolicy
        policy: Any
        if options.policy == "success_on_all":
            policy = policies.SuccessOnAll(synchronise=options.synchronise)
        elif options.policy == "success_on_one":
            policy = policies.SuccessOnOne()
        elif options.policy == "success_on_selected":
            policy = policies.SuccessOnSelected(children=self._selected(b), synchronise=options.synchronise)
        else:
            b.problem(
                f"unknown parallel policy {options.policy!r}",
                "policy",
                hint=did_you_mean(options.policy, PARALLEL_POLICIES) or "one of " + ", ".join(PARALLEL_POLICIES),
            )
            policy = policies.SuccessOnAll()
        return py_trees.composites.Parallel(name=b.name, policy=policy, children=b.children)

    @staticmethod
    def _selected(b: NodeBuild) -> list[py_trees.behaviour.Behaviour]:
        wanted = b.options.selected
        if not wanted:
            b.problem("success_on_selected needs `selected`: a list of child names", "selected")
            return []
        by_name = {c.name: c for c in b.children}
        chosen = []
        for index, child_name in enumerate(wanted):
            if child_name in by_name:
                chosen.append(by_name[child_name])
            else:
                b.problem(f"no child named {child_name!r}", "selected", index, hint=did_you_mean(child_name, by_name))
        return chosen

    def title(self, node: py_trees.behaviour.Behaviour) -> str:
        policy = type(node.policy).__name__
        return {"SuccessOnAll": "parallel (all)", "SuccessOnOne": "parallel (one)"}.get(policy, "parallel (selected)")
