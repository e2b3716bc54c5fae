"""display: the layout supervisor of the PeopleBot's tablet (the paper's Tables III and IV, Fig. 4).

The mission says which layout goes with each state or event by writing its name to a blackboard
key (``layout`` by default; a state's ``on_enter: {set: {layout: Layout_5}}`` does it); this
skill, running beside the mission for its whole length, shows that layout on the Display
interface whenever the key changes, and the default expression (Layout_0) when it is empty.
Keeping the choice on the blackboard puts the layout history in the trace, where the report
reads which layout was shown when, and lets a scenario check it without a screen.

A name that is not one of the seven layouts is not shown: the skill logs it once and keeps the
current layout, so a typo in a mission never blanks the robot's face.
"""

from __future__ import annotations

from botstage.skills.base import In, Outcome, Skill, SkillContext, SkillRun

LAYOUTS = {
    "Layout_0": "default expression",
    "Layout_1": "ready to take a photo",
    "Layout_2": "a compliment on the photo",
    "Layout_3": "information: introductory video",
    "Layout_4": "information: video",
    "Layout_5": "greeting the people",
    "Layout_6": "saying goodbye",
}
DEFAULT = "Layout_0"


class Display(Skill):
    name = "display"
    description = "Layout supervisor: show the layout named by blackboard key `key` on the Display whenever it changes."
    inputs = {
        "key": In(str, default="layout", doc="the key that names the layout to show", names_key="read"),
        "default": In(str, default=DEFAULT, doc="shown while the key is empty or unset"),
    }
    outcomes = ("cancelled",)

    def run(self, ctx: SkillContext, key: str, default: str) -> SkillRun:
        if default not in LAYOUTS:
            return Outcome.failure(f"unknown default layout {default!r} (layouts: {', '.join(LAYOUTS)})")
        display = ctx.interface("display")
        shown = ""
        refused: set[str] = set()
        while True:
            wanted = (ctx.blackboard.get(key) if ctx.blackboard.exists(key) else None) or default
            if wanted != shown and (not isinstance(wanted, str) or wanted not in LAYOUTS):
                if repr(wanted) not in refused:
                    refused.add(repr(wanted))
                    ctx.logger.warning(f"{key} names no layout: {wanted!r} (layouts: {', '.join(LAYOUTS)})")
                wanted = shown or default
            if wanted != shown:
                display.show(wanted, meaning=LAYOUTS[wanted])
                ctx.logger.debug(f"showing {wanted} ({LAYOUTS[wanted]})")
                shown = wanted
            yield
