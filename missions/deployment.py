"""Deployments: which process runs what, and where (`missions/deployments/*.yaml`).

The PeopleBot of the paper ran on five computers (robot, navigation, Kinect and speech, upload,
display); a deployment file says which process serves which of the robot's interfaces, which
skills, the gallery and the mission, on which host and with which Zenoh endpoints. It is checked
whole before anything starts, every problem at its `file:line:col`: an unknown process named as
the router or in `connect`, a skill the mission calls that no process serves, a skill or an
interface served twice, an interface the robot does not have, the simulator split over processes
(it is one world), and the mission's own problems.

Rules (decided here, documented in docs/guides/deployments.md): exactly one process runs the
mission; it runs every skill no other process serves, unless its own `skills:` lists them, which
is then the whole list. Interfaces come from the processes that open a backend (`backend:`);
when none lists `interfaces:`, the mission's process opens the robot as a one-process run does.
A process that opens the robot may also serve it as ROS 2 topics (`topics: true`) for teleop and
ROS 2 tools: they drive it whenever the mission does not (missions/distributed/operator.py).
Processes reach each other through the router process (default: the mission's), or the processes
they name in `connect:`. Process names are their ROS node names.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from botstage.missions.check import Checked, check
from botstage.robots.interfaces import INTERFACES
from botstage.robots.located_yaml import Loaded, Location, Problem, load_document
from botstage.robots.profile import Profile, load_profile, profile_path
from botstage.skills.registry import Registry, suggest

NODE_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")  # a ROS 2 node name (rcl's rule)
ENDPOINT = re.compile(r"(tcp|udp|tls|quic)/(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9.-]+):\d{1,5}\Z")
ROUTER_ENDPOINT = "tcp/127.0.0.1:7447"  # rmw_zenohd's port, on loopback unless the file says otherwise
SIMULATED = frozenset({"sim"})  # backends that are a whole world: one process holds it
OPERATOR = "operator"  # not a process: the identity (certificate) teleop drives a secured deployment's robot with


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class Process(_Strict):
    description: str = ""
    host: str = Field(default="localhost", min_length=1, description="the machine it runs on")
    mission: bool = Field(default=False, description="runs the mission (exactly one process does)")
    backend: str | None = Field(default=None, description="opens the robot's devices with this backend")
    interfaces: list[str] | None = Field(default=None, description="the robot's interfaces it serves")
    skills: list[str] | None = Field(default=None, description="the skills it serves")
    gallery: bool = Field(default=False, description="runs the photo gallery")
    topics: bool = Field(
        default=False,
        description="also serves the robot's interfaces as ROS 2 topics (cmd_vel in; odom, ... out) for teleop "
        "and ROS 2 tools, while no mission drives it (needs `backend:`)",
    )
    listen: list[str] = Field(default_factory=list, description="Zenoh endpoints it listens on")
    connect: list[str] = Field(default_factory=list, description="processes it connects to (default: the router)")


class Deployment(_Strict):
    name: str
    description: str = ""
    mission: str = Field(description="the mission file, relative to this file")
    domain_id: int = Field(default=0, ge=0, le=232, description="the ROS domain (0-232, as ROS 2 allows)")
    router: str | None = Field(default=None, description="the process others connect to (default: the mission's)")
    processes: dict[str, Process] = Field(min_length=1)


@dataclass
class CheckedDeployment:
    path: Path
    loaded: Loaded
    deployment: Deployment | None
    mission: Checked | None
    problems: list[Problem] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.problems

    @property
    def mission_process(self) -> str:
        assert self.deployment is not None
        return next(name for name, p in self.deployment.processes.items() if p.mission)

    @property
    def router(self) -> str:
        assert self.deployment is not None
        return self.deployment.router or self.mission_process

    def skill_hosts(self) -> dict[str, str]:
        """Skill name -> the process that runs it, for every skill the mission calls."""
        assert self.deployment is not None and self.mission is not None
        served = {s: name for name, p in self.deployment.processes.items() for s in p.skills or ()}
        return {skill: served.get(skill, self.mission_process) for skill in self.mission.skills_used}

    def robot_profile(self) -> Profile | None:
        """The mission's robot profile, as the robot process opens it (None: the mission names no robot)."""
        assert self.mission is not None
        robot = self.mission.mission.robot if self.mission.mission is not None else None
        found = profile_path(robot, self.mission.path.parent) if robot is not None else None
        return load_profile(found)[0] if found is not None else None

    def interface_hosts(self) -> dict[str, str]:
        """Interface name -> the process that serves it."""
        assert self.deployment is not None
        return {i: name for name, p in self.deployment.processes.items() for i in p.interfaces or ()}


class _Out:
    def __init__(self, loaded: Loaded) -> None:
        self.loaded = loaded
        self.problems: list[Problem] = list(loaded.problems)

    def at(self, where: tuple[str | int, ...], message: str, hint: str = "") -> None:
        self.problems.append(Problem(self.loaded.locations.find(where), message, hint))

    def where(self, path: tuple[str | int, ...]) -> Location:
        return self.loaded.locations.find(path)


def is_deployment(path: str | Path) -> bool:
    """Whether a YAML file is a deployment (its top level has `processes:`, which no mission has)."""
    loaded = load_document(path)
    return loaded.data is not None and "processes" in loaded.data


def check_deployment(path: str | Path, registry: Registry | None = None) -> CheckedDeployment:
    """A deployment file and its mission, checked whole; problems collected, never raised."""
    path = Path(path)
    registry = registry or Registry.default()
    loaded = load_document(path)
    out = _Out(loaded)
    result = CheckedDeployment(path, loaded, None, None)
    if loaded.data is None:
        result.problems = out.problems
        return result
    try:
        deployment = Deployment.model_validate(loaded.data)
    except ValidationError as exc:
        for error in exc.errors():
            loc = tuple(error["loc"])
            if error["type"] == "extra_forbidden":
                out.at(loc, f"unknown key {loc[-1]!r}")
            else:
                out.at(loc, f"{'.'.join(map(str, loc))}: {error['msg'][:1].lower()}{error['msg'][1:]}")
        result.problems = out.problems
        return result
    result.deployment = deployment
    mission = check((path.parent / deployment.mission), registry)
    result.mission = mission
    if not mission.ok:
        out.at(("mission",), f"the mission {deployment.mission!r} has {len(mission.problems)} problem(s), below")
        out.problems += mission.problems
    _check_processes(deployment, out)
    if mission.ok and mission.mission is not None:
        _check_interfaces(deployment, mission, path, out)
        _check_skills(deployment, mission, registry, out)
    result.problems = out.problems
    return result


def _check_processes(deployment: Deployment, out: _Out) -> None:
    names = list(deployment.processes)
    for name, process in deployment.processes.items():
        if not NODE_NAME.match(name):
            out.at(("processes", name), f"process name {name!r} is not a ROS node name", "letters, digits and '_'")
        if name == OPERATOR:
            out.at(
                ("processes", name),
                f"process name {OPERATOR!r} is taken: it is the operator's (teleop's) identity in a secured deployment",
                "give the process another name",
            )
        for i, endpoint in enumerate(process.listen):
            if not ENDPOINT.match(endpoint):
                out.at(
                    ("processes", name, "listen", i), f"{endpoint!r} is not a Zenoh endpoint", "like tcp/127.0.0.1:7447"
                )
        for i, other in enumerate(process.connect):
            if other not in deployment.processes:
                out.at(("processes", name, "connect", i), f"unknown process {other!r}", _did_you_mean(other, names))
            elif other == name:
                out.at(("processes", name, "connect", i), f"process {name!r} cannot connect to itself")
    if deployment.router is not None and deployment.router not in deployment.processes:
        out.at(("router",), f"unknown process {deployment.router!r}", _did_you_mean(deployment.router, names))
    missions = [name for name, p in deployment.processes.items() if p.mission]
    if not missions:
        out.at(("processes",), "no process runs the mission", "give one `mission: true`")
    for extra in missions[1:]:
        out.at(("processes", extra, "mission"), f"the mission runs in one process, already {missions[0]!r}")
    galleries = [name for name, p in deployment.processes.items() if p.gallery]
    for extra in galleries[1:]:
        out.at(("processes", extra, "gallery"), f"one process runs the gallery, already {galleries[0]!r}")
    for name, process in deployment.processes.items():
        if process.topics and process.backend is None:
            out.at(
                ("processes", name, "topics"),
                f"process {name!r} serves topics but opens no backend",
                "add `backend: sim` or another",
            )
    simulators = [name for name, p in deployment.processes.items() if p.backend in SIMULATED]
    for extra in simulators[1:]:
        out.at(
            ("processes", extra, "backend"),
            f"the simulator is one world: it runs in one process, already {simulators[0]!r}",
        )


def _served(deployment: Deployment, section: str) -> Iterator[tuple[str, int, str]]:
    for name, process in deployment.processes.items():
        for i, item in enumerate(getattr(process, section) or ()):
            yield name, i, item


def _check_interfaces(deployment: Deployment, mission: Checked, path: Path, out: _Out) -> None:
    assert mission.mission is not None
    robot = mission.mission.robot
    profile = None
    if robot is not None:
        found = profile_path(robot, mission.path.parent)
        profile = load_profile(found)[0] if found is not None else None
    have = list(profile.interfaces) if profile is not None else list(INTERFACES)
    first: dict[str, tuple[str, Location]] = {}
    for name, i, interface in _served(deployment, "interfaces"):
        where = ("processes", name, "interfaces", i)
        if deployment.processes[name].backend is None:
            out.at(
                where, f"process {name!r} serves {interface!r} but opens no backend", "add `backend: sim` or another"
            )
        if interface not in have:
            robot_name = f"robot {robot!r}" if robot else "a robot"
            out.at(where, f"{robot_name} has no interface {interface!r}", _did_you_mean(interface, have))
        elif interface in first:
            other, at = first[interface]
            out.at(where, f"interface {interface!r} is served twice: by {other!r} ({at}) and {name!r}")
        else:
            first[interface] = (name, out.where(where))
    if first:
        for interface in have:
            if interface not in first:
                out.at(("processes",), f"no process serves the robot's interface {interface!r}")


def _check_skills(deployment: Deployment, mission: Checked, registry: Registry, out: _Out) -> None:
    first: dict[str, tuple[str, Location]] = {}
    for name, i, skill in _served(deployment, "skills"):
        where = ("processes", name, "skills", i)
        if skill not in registry:
            out.at(where, f"unknown skill {skill!r}", _did_you_mean(skill, registry))
        elif skill in first:
            other, at = first[skill]
            out.at(where, f"skill {skill!r} is served twice: by {other!r} ({at}) and {name!r}")
        else:
            first[skill] = (name, out.where(where))
    runner = next((name for name, p in deployment.processes.items() if p.mission), None)
    if runner is None or deployment.processes[runner].skills is None:
        return  # the mission's process runs every skill no other process serves
    for skill, used_at in mission.skills_used.items():
        if skill not in first:
            out.at(
                ("processes", runner, "skills"),
                f"skill {skill!r} is served nowhere (the mission calls it at {used_at[0]})",
                f"add it to a process's skills, or drop `skills:` from {runner!r} to run the rest there",
            )


def _did_you_mean(name: str, known: Any) -> str:
    match = suggest(name, known)
    return f"did you mean {match!r}?" if match else ""
