"""The simulator's scenery as a mission describes it: how many people walk the map, the groups
they form on cue, the paths some of them walk, and how they speak to the robot. The simulator
owns these (robots/sim/people.py, voices.py); a mission file only says what it wants of them,
and what is wrong with that is said here, against the map it will happen on."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field, field_validator

from botstage.robots.gridmap import GridMap
from botstage.robots.limits import MAX_SECONDS
from botstage.robots.sim.people import first_blocked, standable
from botstage.robots.suggest import did_you_mean

# every model refuses NaN and infinities, as the mission's own
_CONFIG = ConfigDict(extra="forbid", allow_inf_nan=False)
_DAYS = f"at most {MAX_SECONDS:,.0f} s (about {MAX_SECONDS / 86400:.0f} days)"
Where = tuple[str | int, ...]


class Gathering(BaseModel):
    """A group the simulator's people form on cue: the nearest free people walk to ``at``."""

    model_config = _CONFIG
    at: str | list[float] = Field(description="a named place of the map, or [x, y]")
    size: int = Field(ge=2, le=6, description="people in the group (the paper's 2-6)")
    time: float = Field(default=0.0, ge=0, le=MAX_SECONDS, description=f"mission seconds when they set off; {_DAYS}")
    stay: float = Field(default=120.0, gt=0, le=MAX_SECONDS, description=f"seconds they stay once there; {_DAYS}")


class Walk(BaseModel):
    """A simulated person who walks a given path and nothing else (a face tracker's test subject):
    standing at the first point until ``at``, then point to point at ``speed``, ``repeat`` times
    round (back from the last point to the first between rounds), ``pause`` s at each point, and
    standing at the last point once done. Never sent elsewhere by the crowd's wandering or groups."""

    model_config = _CONFIG
    path: list[str | list[float]] = Field(
        min_length=2, max_length=1000, description="the points walked through: named places of the map, or [x, y]"
    )
    speed: float = Field(default=1.0, gt=0, le=3.0, description="m/s (1.0: an unhurried walk; 3 m/s is running)")
    at: float = Field(default=0.0, ge=0, le=MAX_SECONDS, description=f"mission seconds when they set off; {_DAYS}")
    repeat: int = Field(default=1, ge=1, le=10_000, description="rounds of the path")
    pause: float = Field(default=0.0, ge=0, le=MAX_SECONDS, description=f"seconds they stand at each point; {_DAYS}")


VOICE_COMMANDS = ("PHOTO", "YES", "WHATSUP", "CANCEL", "CIAO")  # what the simulator's voice clips say


class VoiceSettings(BaseModel):
    """How the simulator's people speak to the robot (robots/sim/voices.py)."""

    model_config = _CONFIG
    near: float = Field(default=2.5, gt=0, description="m: people within this of the robot speak to it")
    every: float = Field(default=12.0, gt=0, le=MAX_SECONDS, description=f"s: mean wait between utterances; {_DAYS}")
    command_share: float = Field(default=0.6, ge=0, le=1, description="share of utterances that are commands")
    pause: float = Field(default=1.0, ge=0, le=MAX_SECONDS, description=f"s of quiet at least between two; {_DAYS}")
    command_weights: dict[str, Annotated[float, Field(ge=0)]] = Field(
        default_factory=dict, description="how often each command is said, relatively (default: all alike)"
    )

    @field_validator("command_weights")
    @classmethod
    def _commands(cls, value: dict[str, float]) -> dict[str, float]:
        unknown = sorted(set(value) - set(VOICE_COMMANDS))
        if unknown:
            raise ValueError(f"no such command {', '.join(unknown)} (commands: {', '.join(VOICE_COMMANDS)})")
        return value


def check_scenery(
    people: int, gatherings: Sequence[Gathering], walks: Sequence[Walk], grid: GridMap
) -> list[tuple[Where, str, str]]:
    """What is wrong with the scenery on ``grid``: (where in the mission, message, hint) each."""
    problems: list[tuple[Where, str, str]] = []
    for index, gathering in enumerate(gatherings):
        where: Where = ("gatherings", index, "at")
        if isinstance(gathering.at, str):
            if gathering.at not in grid.places:
                problems.append(
                    (where, f"the map has no place {gathering.at!r}", did_you_mean(gathering.at, grid.places))
                )
        elif len(gathering.at) != 2:
            problems.append((where, "a gathering's place is a name or [x, y]", ""))
        elif not grid.is_free(gathering.at[0], gathering.at[1]):
            problems.append((where, f"({gathering.at[0]:g}, {gathering.at[1]:g}) is not free floor on the map", ""))
    problems += _check_walks(walks, grid)
    needed = sum(g.size for g in gatherings)
    if needed > people:
        problems.append((("gatherings",), f"the gatherings need {needed} people; `people:` is {people}", ""))
    return problems


def _check_walks(walks: Sequence[Walk], grid: GridMap) -> list[tuple[Where, str, str]]:
    """Each walk's points are places of the map or [x, y], and a person fits all along its path
    (free floor, a person's radius from walls), so a walker is never stuck where it was sent."""
    problems: list[tuple[Where, str, str]] = []
    room = standable(grid) if walks else None
    for index, walk in enumerate(walks):
        points: list[tuple[float, float]] = []
        for number, point in enumerate(walk.path):
            where: Where = ("walks", index, "path", number)
            if isinstance(point, str):
                if point not in grid.places:
                    problems.append((where, f"the map has no place {point!r}", did_you_mean(point, grid.places)))
                    break
                points.append((float(grid.places[point][0]), float(grid.places[point][1])))
            elif len(point) != 2:
                problems.append((where, "a walk's point is a place's name or [x, y]", ""))
                break
            else:
                points.append((float(point[0]), float(point[1])))
        else:
            if walk.repeat > 1:
                points.append(points[0])  # the way back to the start between rounds
            blocked = first_blocked(grid, points, room)
            if blocked is not None:
                towards, x, y = blocked
                where = ("walks", index, "path", towards % len(walk.path))  # the way back leads to the first
                message = (
                    f"a person cannot walk through ({x:.2f}, {y:.2f}): a wall, or less than a person's width from one"
                )
                problems.append((where, message, ""))
    return problems
