"""Missions, trees and machines built in Python, checked, drawn and run exactly as YAML ones.

The YAML file format is one front end of this API: ``Mission.from_yaml(path)`` gives the same
objects Python builds, and ``Mission.to_yaml()`` the file a user could save. The engine sees only
the plain data both produce, so a mission and its YAML twin run to the same trace::

    from botstage.missions.api import Condition, Mission, Sequence, Skill, StateMachine, Timeout, key

    mission = Mission("patrol", seed=7, until=60, blackboard={"battery_pct": 100, "estop": False})
    mission.add_tree("patrol", Sequence(
        Condition("battery_pct > 20"),
        Timeout(10, Skill("wait", duration=4)),
        Skill("log", message=key("greeting")),   # "{greeting}": read from the blackboard
    ))
    machine = StateMachine(outcomes=["done", "stopped"])
    machine.add_state("patrolling", tree="patrol", transitions={"success": "done", "failure": "stopped"})
    machine.add_preemption("estop", to="stopped")
    mission.machine = machine
    mission.check().problems   # located at the Python lines: file.py:5:5: error: unknown skill 'wiat' ...
    mission.draw(machine=True) # as `botstage machine` draws it
    mission.run(out=Path("runs/patrol")).outcome

Plug-in node kinds and skills take the general form ``Node(kind, value, **options)``, e.g.
``Node("approach", {"target": key("crowd_centre")}, outputs={"distance": "d"})``; a plain spec
mapping is accepted wherever a node is. ``python -m botstage.missions.examples.hello_api`` runs an example.
"""

from botstage.missions.api.machine import Preemption, State, StateMachine
from botstage.missions.api.mission import Mission
from botstage.missions.api.nodes import (
    Condition,
    Fallback,
    ForceFailure,
    ForceSuccess,
    If,
    Inverter,
    MachineRef,
    Node,
    OneShot,
    Parallel,
    ReactiveFallback,
    ReactiveSelector,
    ReactiveSequence,
    Repeat,
    Retry,
    Selector,
    Sequence,
    Skill,
    Subtree,
    Timeout,
    While,
    key,
)

__all__ = [
    "Condition",
    "Fallback",
    "ForceFailure",
    "ForceSuccess",
    "If",
    "Inverter",
    "MachineRef",
    "Mission",
    "Node",
    "OneShot",
    "Parallel",
    "Preemption",
    "ReactiveFallback",
    "ReactiveSelector",
    "ReactiveSequence",
    "Repeat",
    "Retry",
    "Selector",
    "Sequence",
    "Skill",
    "State",
    "StateMachine",
    "Subtree",
    "Timeout",
    "While",
    "key",
]
