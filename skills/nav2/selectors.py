"""Nav2's selectors: botstage has one planner, controller, goal checker ... so each writes its default.

Nav2 lets a topic switch the plug-in at run time; ``topic_name`` is accepted and ignored, and the
output is always ``default_*`` (Nav2 does the same until something is published on the topic).
"""

from __future__ import annotations

from botstage.skills.base import In, Out, Outcome, Skill, SkillContext
from botstage.skills.nav2.common import ignored


def _selector(kind: str, what: str) -> type[Skill]:
    name = "".join(part.capitalize() for part in kind.split("_")) + "Selector"
    default, selected = f"default_{kind}", f"selected_{kind}"

    def run(self: Skill, ctx: SkillContext, topic_name: object, **inputs: str) -> Outcome:
        return Outcome.success(inputs[default], **{selected: inputs[default]})

    return type(
        name,
        (Skill,),
        {
            "__module__": __name__,
            "name": name,
            "description": f"Nav2's {name}: writes `{default}` to `{selected}` (botstage has one {what})",
            "inputs": {
                "topic_name": ignored("no topic switches the plug-in at run time", f"{kind}_selector"),
                default: In(str, default="", doc=f"the {what} to use"),
            },
            "outputs": {selected: Out(str, doc=f"the {what} chosen: the default")},
            "run": run,
        },
    )


PlannerSelector = _selector("planner", "planner")
ControllerSelector = _selector("controller", "controller")
SmootherSelector = _selector("smoother", "smoother")
GoalCheckerSelector = _selector("goal_checker", "goal checker")
ProgressCheckerSelector = _selector("progress_checker", "progress checker")
PathHandlerSelector = _selector("path_handler", "path handler")
