"""What a robot can do: skills with a declared contract, and the algorithms they use.

Skills never import py_trees or transitions: the same skill runs inside a behaviour tree,
inside a state of a state machine, in a scenario test and in a remote process.
"""

from botstage.skills.base import In, Out, Outcome, Port, Skill, SkillContext

__all__ = ["In", "Out", "Outcome", "Port", "Skill", "SkillContext"]
