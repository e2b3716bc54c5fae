"""One process of a deployment, by its role: the robot, skills, the mission, or several of these.

``serve_process`` is what ``botstage serve process DEPLOYMENT NAME`` runs (and ``botstage up``
starts once per process). Every process is a ROS 2 node named after it, on one Zenoh session:

- **the robot** (``backend:``): opens the mission's robot as a one-process run would (same map,
  start, people, voices, seed) and serves its devices (``robots/remote``) and its control
  (``@backend``: the world's step at each mission tick, summary, result files);
- **skills** (``skills:``): a ``SkillHost`` for them over the robot's devices (here, or proxies of
  the robot process's) and the run services skills use (files, uploads), whose after-tick work
  runs when the mission's tick reaches it (``/<name>/lockstep``);
- **the mission** (``mission: true``): runs the mission with the skills served elsewhere replaced
  by proxies (``skills/remote``) and the robot by ``RemoteRobot``; after each tick it waits until
  every other process with after-tick work has finished that tick (lockstep; one with none rests
  until a skill reply says it has some), then merges their summary blocks.

On a simulated backend the mission's ticks drive every clock, so a distributed run leaves the
trace of the same run in one process. Loopback unless the deployment or ``--listen`` says more.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import signal
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import Future
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import zenoh

from botstage.missions.deployment import ROUTER_ENDPOINT, CheckedDeployment, check_deployment
from botstage.missions.distributed.clock import ClockPublisher
from botstage.missions.distributed.names import lockstep_service
from botstage.missions.distributed.operator import Operator
from botstage.missions.distributed.security import SecurityError, secured, session_options
from botstage.missions.runner import run
from botstage.missions.session.errors import RunError
from botstage.missions.session.plugins import service_registry
from botstage.missions.session.result import RunResult
from botstage.missions.session.session import RunSession
from botstage.missions.session.uploads import fill_counters
from botstage.robots.backend import BackendError, BackendKind, BackendOptions, OpenRequest
from botstage.robots.backend_registry import BackendRegistry, open_kind
from botstage.robots.clock import SimClock, WallClock
from botstage.robots.remote import values
from botstage.robots.remote.backend import CONTROL, BackendControl, RemoteRobot
from botstage.robots.remote.devices import DeviceHost
from botstage.robots.remote.ros2_link import open_remote_devices, serve_devices
from botstage.robots.ros2 import types
from botstage.robots.ros2.liveliness import ADMIN_SPACE, EntityKind, TokenError, parse_token
from botstage.robots.ros2.node import Ros2Node
from botstage.robots.ros2.service import ServiceUnavailable
from botstage.robots.ros2.topics import routes
from botstage.skills.outbox.store import DB_NAME
from botstage.skills.registry import Registry
from botstage.skills.remote.actions import SkillActions
from botstage.skills.remote.host import SkillHost
from botstage.skills.remote.protocol import TickRequest
from botstage.skills.remote.proxy import remote_of
from botstage.skills.remote.ros2_link import SkillTickLink, serve_skill_host
from botstage.skills.upload import UploadParams

log = logging.getLogger(__name__)

LOCKSTEP_TYPE = "botstage_msgs/srv/Lockstep"
READY_TIMEOUT_S = 60.0
RECHECK_S = 5.0  # mission time after which a resting process is stepped anyway (work from outside the mission)
STEP, FINISH = 0, 1


class DeploymentError(RuntimeError):
    """A deployment that cannot run as asked (its problems were printed by the caller)."""


@dataclass
class Role:
    """What one process does, from the checked deployment."""

    name: str
    checked: CheckedDeployment
    mission_path: Path
    robot_process: str | None  # the process that opens the robot (None: the mission's own)
    skills_here: list[str]
    skill_hosts: dict[str, str]  # skill -> process, for the skills the mission calls
    backend: str | None
    runs_mission: bool
    others: list[str] = field(default_factory=list)  # processes the mission steps in lockstep
    topics: bool = False  # also serves the robot as ROS 2 topics (missions/distributed/operator.py)

    @classmethod
    def of(cls, path: Path, name: str) -> Role:
        checked = check_deployment(path)
        if not checked.ok:
            raise DeploymentError("\n".join(str(p) for p in checked.problems))
        deployment = checked.deployment
        assert deployment is not None
        if name not in deployment.processes:
            known = ", ".join(deployment.processes)
            raise DeploymentError(f"{path}: no process {name!r} in this deployment (it has: {known})")
        process = deployment.processes[name]
        hosts = checked.skill_hosts()
        robot = next((n for n, p in deployment.processes.items() if p.backend), None)
        skills_here = sorted({s for s, h in hosts.items() if h == name} | set(process.skills or ()))
        others = [
            n
            for n, p in deployment.processes.items()
            if n != name and (p.skills or p.gallery) and not p.mission and any(h == n for h in hosts.values())
        ]
        return cls(
            name,
            checked,
            (path.parent / deployment.mission).resolve(),
            robot if robot is not None and robot != name else None,
            skills_here,
            hosts,
            process.backend,
            process.mission,
            others,
            process.topics,
        )


def endpoints(
    role: Role, connect: list[str], listen: list[str] | None, secure: bool = False
) -> tuple[list[str], list[str], str]:
    """Where the process listens, what it connects to, and its Zenoh mode (TLS ones when ``secure``)."""
    deployment = role.checked.deployment
    assert deployment is not None
    process = deployment.processes[role.name]
    router = role.checked.router == role.name
    heard = listen if listen is not None else (process.listen or ([ROUTER_ENDPOINT] if router else []))
    heard, reached = heard or ["tcp/127.0.0.1:0"], ([] if router else connect or [ROUTER_ENDPOINT])
    if secure:
        heard, reached = secured(heard, listen or []), secured(reached, connect)
    return heard, reached, "router" if router else "peer"


class Lockstep:
    """This process's side of the mission's ticks: after-tick work of its services, then the answer."""

    def __init__(self, clock: SimClock, services: list[Any], session: Any) -> None:
        self.clock, self.services, self.session = clock, services, session
        self._response = types.message_class(f"{LOCKSTEP_TYPE}_Response")

    def handle(self, request: Any) -> Any:
        try:
            if request.kind == FINISH:
                return self._response(summary_json=values.dumps(self.finish(), "the summary"), error="", resting=False)
            self.clock.ticks = int(request.ticks)
            for service in self.services:
                after = getattr(service, "after_tick", None)
                if after is not None:
                    after(self.session)
            return self._response(summary_json="", error="", resting=self.resting())
        except Exception as error:  # said to the mission, which records it; this process serves on
            log.exception("lockstep request failed")
            return self._response(summary_json="", error=f"{type(error).__name__}: {error}", resting=False)

    def resting(self) -> bool:
        """Whether no service has after-tick work left (one with ``after_tick`` and no ``resting()`` always has)."""
        return all(
            getattr(service, "after_tick", None) is None or bool(getattr(service, "resting", lambda: False)())
            for service in self.services
        )

    def finish(self) -> dict[str, Any]:
        result = RunResult("", "", self.session.folder, {"counters": {}}, {}, None)
        for service in self.services:
            finished = getattr(service, "finished", None)
            if finished is not None:
                finished(self.session, result)
        result.summary.pop("counters", None)
        return result.summary


class RemoteKind(BackendKind):
    """The mission's robot, opened by the robot process: proxies of its devices over the node."""

    name = "remote"
    description = "a robot served by another botstage process (missions/distributed)"

    def __init__(self, node: Ros2Node, robot: str, simulated: bool) -> None:
        self.node, self.robot, self.simulated = node, robot, simulated  # type: ignore[misc]

    def open(self, request: OpenRequest, options: BackendOptions) -> Any:
        _, proxies = open_remote_devices(self.node, self.robot, READY_TIMEOUT_S)
        # a robot process on a wall-clock backend (the robot's own board, an emulator): the run
        # then goes in real time, as it would with that backend in one process
        self.simulated = bool(getattr(proxies[CONTROL], "simulated", True))  # type: ignore[misc]
        return RemoteRobot(proxies, request.profile, request.grid, request.clock)


class LockstepObserver:
    """The mission's side: after each tick, every other process finishes it; at the end, their summaries.

    A process that answers that it rests (no after-tick work left: no upload due or in flight) is
    not asked again until one of its skills' replies says it has such work (``work_given``: how
    many have so far), a new session serves it (a restart), or ``RECHECK_S`` of mission time have
    passed: stepping it would do nothing, and a round trip per tick to each process is a large
    part of what a distributed tick costs over one process's. The recheck is for work that comes
    from outside the mission (a ROS 2 tool's goal to its upload action): its time moves only when
    stepped, so it would otherwise wait for the mission's next photo. It falls on fixed ticks, so
    runs stay deterministic. Whether the process is still there is checked every tick all the
    same, from the graph.

    A process that is gone (killed, cut off: its lockstep server left the graph, or a call in
    flight ended without an answer) is skipped, said once, and stepped again from the first tick
    it serves again (a restarted process): the mission goes on without it meanwhile, as its
    skills' nodes fail with ``remote 'NAME' lost``. One still there that reports an error ends the
    run, as in one process.
    """

    name = "lockstep"

    def __init__(
        self,
        node: Ros2Node,
        processes: list[str],
        say: Callable[[str], None] = print,
        work_given: Callable[[str], int] = lambda process: 0,
    ) -> None:
        self.request = types.message_class(f"{LOCKSTEP_TYPE}_Request")
        self.clients = {p: node.client(lockstep_service(p), LOCKSTEP_TYPE) for p in processes}
        self.say = say
        self.work_given = work_given
        self.lost: set[str] = set()
        # process -> (work_given, sessions) when it rested, and the tick it is asked again at the latest
        self.resting: dict[str, tuple[tuple[int, frozenset[str]], int]] = {}
        self.steps = self.skipped = 0  # lockstep calls made, and saved by resting processes

    def wait_ready(self, timeout: float) -> None:
        for process, client in self.clients.items():
            if not client.wait_for_service(timeout):
                raise DeploymentError(f"process {process!r} did not come up within {timeout:g} s")

    def _send(self, process: str, kind: int, session: Any) -> Future | None:
        """The call to the process, in flight; None when it is gone."""
        client = self.clients[process]
        if not client.servers.zids():
            self._gone(process, session, "its node left the graph")
            return None
        return client.call_async(self.request(kind=kind, ticks=session.clock.ticks, time=session.clock.now()))

    def _answer(self, process: str, call: Future | None, session: Any) -> Any | None:
        """The process's answer to ``call``, or None when it is gone."""
        if call is None:
            return None
        try:
            response = call.result()
        except ServiceUnavailable:
            self._gone(process, session, "a call ended unanswered")
            return None
        if process in self.lost:
            self.lost.discard(process)
            self.say(f"process {process!r} is back: in step again from tick {session.clock.ticks}")
        if response.error:
            raise RuntimeError(f"process {process!r}: {response.error}")
        return response

    def _all(self, kind: int, session: Any, processes: list[str] | None = None) -> dict[str, Any | None]:
        """Every process's answer, asked of all at once (a tick waits for the slowest, not the sum)."""
        calls = {process: self._send(process, kind, session) for process in processes or self.clients}
        return {process: self._answer(process, call, session) for process, call in calls.items()}

    def _seen(self, process: str) -> tuple[int, frozenset[str]]:
        """What says whether a resting process still rests: the work given to it, the sessions serving it."""
        return self.work_given(process), self.clients[process].servers.zids()

    def _still_resting(self, process: str, ticks: int) -> bool:
        """Whether ``process`` rests on at tick ``ticks``: no work given to it since, the same sessions
        serve it, and its recheck is not due."""
        rested = self.resting.get(process)
        if rested is None:
            return False
        seen, recheck = rested
        if ticks < recheck and seen == self._seen(process):
            return True
        del self.resting[process]  # stepped again (gone: said so by the step that finds it missing)
        return False

    def _gone(self, process: str, session: Any, why: str) -> None:
        if process not in self.lost:
            self.lost.add(process)
            self.say(f"process {process!r} lost at tick {session.clock.ticks} ({why}): the mission goes on without it")

    def after_tick(self, session: Any) -> None:
        ticks = session.clock.ticks
        due = [process for process in self.clients if not self._still_resting(process, ticks)]
        self.steps += len(due)
        self.skipped += len(self.clients) - len(due)
        if not due:
            return
        for process, response in self._all(STEP, session, due).items():
            if response is not None and response.resting:
                self.resting[process] = (self._seen(process), ticks + max(1, round(RECHECK_S / session.clock.period)))

    def finished(self, session: Any, result: RunResult) -> None:
        # what lockstep cost: calls to other processes after ticks, and those saved while they rested
        result.summary["lockstep"] = {"steps": self.steps, "skipped": self.skipped}
        for process, response in self._all(FINISH, session).items():
            if response is None:
                result.summary.setdefault("processes_lost", []).append(process)  # its summary blocks are missing
                continue
            blocks = values.loads(response.summary_json or "{}", "a summary")
            for name, block in blocks.items():
                result.summary[name] = block
                if name == "upload":
                    fill_counters(result.summary["counters"], block)


class MissionLog:
    """What the mission's process says while it runs: its machine's states, and remotes lost and back.

    A state is said after the tick that entered it (its skill has started by then, here or in
    the process that runs it). A remote skill's node that fails with ``remote 'NAME' lost`` is
    said at once, the first time for each loss; the first outcome of one of that process's
    skills that is not a loss says it serves again.
    """

    name = "mission_log"

    def __init__(self, hosts: Mapping[str, str], say: Callable[[str], None] = print) -> None:
        self.hosts = hosts  # skill -> the process that runs it (the remote ones)
        self.say = say
        self.down: set[str] = set()
        self._states: list[str] = []

    def event(self, record: dict[str, Any]) -> None:
        if record["ev"] == "transition":
            reason = f" ({record['reason']})" if record["reason"] else ""
            where = f"{record['machine']}: {record['source'] or '-'} -> {record['dest'] or '-'}"
            self._states.append(f"t={record['t']:.1f} s {where}{reason}")
        elif record["ev"] == "skill_outcome":
            self._outcome(record)

    def _outcome(self, record: dict[str, Any]) -> None:
        process = self.hosts.get(record["skill"])
        if process is None:
            return
        lost = f"remote {process!r} lost"
        if record["outcome"] == "failure" and str(record["reason"]).startswith(lost):
            if process not in self.down:
                self.down.add(process)
                self.say(f"{lost}: {record['node']} ({record['skill']}) failed at t={record['t']:.1f} s")
        elif process in self.down:
            self.down.discard(process)
            ended = f"{record['skill']} ended {record['outcome']} at t={record['t']:.1f} s"
            self.say(f"remote {process!r} serves again: {ended}")

    def after_tick(self, session: Any) -> None:
        states, self._states = self._states, []
        for line in states:
            self.say(line)


def _open_robot(
    role: Role, seed: int | None, clock: SimClock | WallClock, given: BackendGiven | None = None
) -> tuple[Any, RunSession, OpenRequest]:
    given = given or BackendGiven()
    session = RunSession(
        role.mission_path,
        seed=seed,
        backend=given.name or role.backend or "sim",
        backend_options=given.options,
        port=given.port,
    )
    try:
        session.check()
    except RunError as error:
        raise DeploymentError("\n".join(error.lines())) from None
    request = session.robot_request(clock)
    if request is None:
        raise DeploymentError(f"the mission {role.mission_path.name} names no robot for {role.name!r} to serve")
    try:
        return open_kind(session.kind, request, session.options), session, request
    except BackendError as error:
        raise DeploymentError("\n".join(error.lines())) from None


@dataclass(frozen=True)
class BackendGiven:
    """The robot process's backend as its machine's command line gives it (``serve process --backend``):
    the deployment file's otherwise. The Pi opens the real NyBoard where one machine simulates it."""

    name: str | None = None
    options: Mapping[str, Any] = field(default_factory=dict)
    port: str | None = None

    @property
    def given(self) -> bool:
        return self.name is not None or bool(self.options) or self.port is not None


# The robot's estimates (localisation, navigation) stay with the mission: updating them reads the
# laser after every tick, and a second reader in another process would draw the sensor's noise
# twice. A process that serves navigation skills is the mission's.
MISSION_ONLY_SERVICES = frozenset({"robot"})


def _session_services(folder: Path, clock: Any, seed: int, backend: Any) -> tuple[list[Any], dict[str, Any], Any]:
    """The run services a skills process offers (files, uploads, orders, plug-ins'), opened."""
    services = service_registry()
    interfaces: dict[str, Any] = dict(backend.devices) if backend is not None else {}
    # what a service reads of its session; `interfaces` filled as the services open, as a run's
    session = SimpleNamespace(folder=folder, clock=clock, seed=seed, backend=backend, interfaces=interfaces)
    opened = []
    for name in services:
        if name in MISSION_ONLY_SERVICES:
            continue
        service = services.create(name)
        interfaces.update(service.open(session))
        opened.append(service)
    return opened, interfaces, session


def serve_process(
    path: Path,
    name: str,
    *,
    out: Path,
    seed: int | None = None,
    until: float | None = None,
    connect: list[str] | None = None,
    listen: list[str] | None = None,
    ready: Callable[[str], None] = print,
    stop: threading.Event | None = None,
    certs: Path | None = None,
    backend: BackendGiven | None = None,
    observers: Sequence[object] = (),
) -> int:
    """Run process ``name`` of the deployment at ``path`` until it is stopped (or its mission ends).

    ``observers`` watch the mission's run (the live monitor): for the process that runs it only.

    With ``certs`` (missions/distributed/security.py) it speaks only mutual TLS under the
    deployment's access policy, and may listen beyond loopback. ``backend`` is this machine's
    backend for the process that opens the robot, instead of the file's (the robot's own board
    on the robot's computer).
    """
    role = Role.of(path, name)
    if observers and not role.runs_mission:
        raise DeploymentError(f"process {name!r} runs no mission: there is no run to watch here")
    backend = backend or BackendGiven()
    if backend.given and not role.backend:
        opener = next((n for n, p in role.checked.deployment.processes.items() if p.backend), None)  # type: ignore[union-attr]
        where = f": {opener!r} does" if opener else ""
        raise DeploymentError(f"process {name!r} opens no robot: a backend is for the process that opens it{where}")
    try:
        listen_on, connect_to, mode = endpoints(role, connect or [], listen, secure=certs is not None)
        options = session_options(role.checked, name, certs) if certs is not None else None
    except SecurityError as error:
        raise DeploymentError(str(error)) from None
    out.mkdir(parents=True, exist_ok=True)
    stop = stop or threading.Event()
    node = Ros2Node(
        name,
        domain_id=role.checked.deployment.domain_id if role.checked.deployment else 0,
        listen=listen_on,
        connect=connect_to,
        mode=mode,
        options=options,
        allow_remote=options is not None,
    )
    with node, contextlib.ExitStack() as stack:  # what the process serves ends before its node leaves the graph
        if role.runs_mission:  # Ctrl-C (SIGINT) and SIGTERM end the run as in one process: summary written
            try:
                return _run_mission(role, node, out=out, seed=seed, until=until, ready=ready, observers=observers)
            except KeyboardInterrupt:
                ready(f"{name}: interrupted before its run began")
                return 130
        for signum in (signal.SIGINT, signal.SIGTERM):
            with contextlib.suppress(ValueError):  # not the main thread (tests)
                previous = signal.signal(signum, lambda *_: stop.set())
                stack.callback(signal.signal, signum, previous)
        _serve(role, node, stack, out=out, seed=seed, say=ready, given=backend)
        ready(f"{name} ready")
        stop.wait()
    return 0


def _serve(
    role: Role,
    node: Ros2Node,
    stack: contextlib.ExitStack,
    *,
    out: Path,
    seed: int | None,
    say: Callable[[str], None],
    given: BackendGiven | None = None,
) -> None:
    checked_mission = role.checked.mission
    assert checked_mission is not None and checked_mission.mission is not None
    mission = checked_mission.mission
    run_seed = mission.seed if seed is None else seed
    clock = SimClock(mission.rate_hz)
    backend: Any = None
    if role.backend:
        backend, session, request = _open_robot(role, seed, clock, given)
        stack.callback(backend.close)
        control = RunControl(backend, clock, simulated=session.kind.simulated)
        devices = DeviceHost({**backend.devices, CONTROL: control})
        serve_devices(node, devices)
        watch = MissionWatch(node, role.checked.mission_process, devices, control, say)
        stack.callback(watch.close)
        if role.topics:
            _serve_topics(backend, node, clock, request, watch, devices, session.kind.simulated, say, stack)
    elif role.skills_here and role.robot_process:
        _, proxies = open_remote_devices(node, role.robot_process, READY_TIMEOUT_S)
        session = RunSession(role.mission_path, seed=seed)
        session.check()
        request = session.robot_request(clock)
        assert request is not None
        backend = RemoteRobot(proxies, request.profile, request.grid, clock)
    if not role.skills_here:
        return
    services, interfaces, session_like = _session_services(out, clock, run_seed, backend)
    for service in reversed(services):
        stack.callback(service.close)
    interfaces.pop(CONTROL, None)
    if "upload" in role.skills_here:
        _resume_outbox(interfaces.get("uploads"), mission.skill_params.get("upload", {}), out, say)
    reachable = MissionInterfaces(interfaces, node, role.checked.mission_process)
    host = SkillHost(Registry.default(), reachable, role.skills_here)
    stack.callback(host.close)
    lockstep = Lockstep(clock, services, session_like)
    serve_skill_host(node, _following(host, clock, lockstep.resting))
    stack.callback(SkillActions(node, host, role.skills_here).close)  # for ROS 2 tools; closed before the host
    node.service(lockstep_service(role.name), LOCKSTEP_TYPE, lockstep.handle)


def _resume_outbox(uploads: Any, params: Mapping[str, Any], out: Path, say: Callable[[str], None]) -> None:
    """Open the run's outbox now if an earlier process left one (a restarted upload process).

    Its photos go on uploading from the next tick, whether or not the mission uploads another;
    the gallery the run started (``gallery/`` in the run folder) starts again with it. Outboxes
    of nodes with parameters of their own open at their first call, as in one process.
    """
    if uploads is None:
        return
    settings = UploadParams.model_validate(dict(params))
    folder = Path(settings.outbox) if settings.outbox else out / "outbox"
    if not (folder / DB_NAME).is_file():
        return
    outbox = uploads.outbox(settings)
    say(f"resumed the outbox {folder}: {outbox.resumed} photo(s) still to upload")


def _serve_topics(
    backend: Any,
    node: Ros2Node,
    clock: SimClock,
    request: OpenRequest,
    watch: MissionWatch,
    devices: DeviceHost,
    simulated: bool,
    say: Callable[[str], None],
    stack: contextlib.ExitStack,
) -> None:
    """The robot's interfaces as ROS 2 topics too, driven in real time whenever no mission drives it."""
    profile = request.profile
    operator = Operator(
        backend,
        node,
        clock,
        routes(profile),
        held=watch.holder,
        lock=devices.lock,
        say=say,
        stamp_offset=0.0 if simulated else time.time() - clock.now(),  # ROS time for a real robot
        watchdog_s=profile.control.watchdog_s,
    )
    stack.callback(operator.close)
    for direction, topic, type_name in operator.topics():
        say(f"  {direction:>3} {topic} [{type_name}]")
    operator.start()


class RunControl(BackendControl):
    """The robot's control, noting when the mission's run stopped the robot itself (its normal end).

    ``simulated`` tells the mission's process which clock to run on: its ticks move a simulated
    world (lockstep), or the robot moves in real time (its own board, an emulator)."""

    def __init__(self, backend: Any, clock: SimClock, *, simulated: bool = True) -> None:
        super().__init__(backend, clock)
        self.simulated = simulated
        self._run_ended = False

    def stop(self) -> None:
        self._run_ended = True
        super().stop()


def node_token_pattern(domain_id: int, node: str) -> str:
    """The key expression of every liveliness token of a node named ``node`` (any namespace)."""
    return f"{ADMIN_SPACE}/{domain_id}/*/*/*/{EntityKind.NODE.value}/*/*/{node}"


class MissionWatch:
    """The robot process's watch on the mission's node: when it leaves the graph, the drive stops.

    In lockstep the robot's world moves only with the mission's ticks, and on hardware the
    mission's commands would stop: either way nobody sends the zero. The mission's node token
    (rmw_zenoh's ``NN``) goes when its process dies or is cut off; the drive gets zero velocity
    then, through the device host (one call at a time with the device calls), and the stop is
    said once per loss with the delay on this process's monotonic clock. A run that ended and
    stopped the robot itself is not a loss.
    """

    def __init__(
        self, node: Ros2Node, mission: str, devices: DeviceHost, control: RunControl, say: Callable[[str], None]
    ) -> None:
        self.mission, self.devices, self.control, self.say = mission, devices, control, say
        self._zids: set[str] = set()
        self._lock = threading.Lock()
        pattern = node_token_pattern(node.domain_id, mission)
        self._subscriber = node.session.liveliness().declare_subscriber(pattern, self._on_token, history=True)

    def _on_token(self, sample: Any) -> None:
        """Zenoh's thread: note the change; a loss is handled on a thread of its own."""
        left = time.monotonic()
        try:
            token = parse_token(str(sample.key_expr))
        except TokenError:
            return
        if token.kind is not EntityKind.NODE or token.node_name != self.mission:
            return
        alive = sample.kind == zenoh.SampleKind.PUT
        with self._lock:
            before = bool(self._zids)
            (self._zids.add if alive else self._zids.discard)(token.zid)
            now = bool(self._zids)
        if now and not before:
            self.control._run_ended = False  # a (new) mission: its run is on
            self.say(f"mission {self.mission!r} is on the graph: it drives the robot")
        elif before and not now:
            threading.Thread(target=self._lost, args=(left,), name="mission-watch", daemon=True).start()

    def _lost(self, left: float) -> None:
        if self.control._run_ended:
            self.say(f"mission {self.mission!r} left after its run ended")
            return
        _, error_type, error = self.devices.answer(CONTROL, "stop", "")
        stopped = time.monotonic()
        if error_type:
            self.say(f"mission {self.mission!r} lost: the drive could not be stopped: {error_type}: {error}")
            return
        self.say(
            f"mission {self.mission!r} lost: drive stopped {(stopped - left) * 1000:.1f} ms after its node left "
            f"the graph (monotonic {stopped:.6f})"
        )

    def holder(self) -> str | None:
        """The mission's name while its node is on the graph (it drives the robot), else None."""
        with self._lock:
            return self.mission if self._zids else None

    def close(self) -> None:
        self._subscriber.undeclare()


class MissionInterfaces(Mapping[str, Any]):
    """A skills process's interfaces: its own first, then those the mission's process serves.

    The robot's estimates (``localization``, ``navigation``, ``people_tracking``) live with the
    mission (see ``MISSION_ONLY_SERVICES``); a skill here that uses one gets a proxy, made when it
    is first asked for (the mission serves them once its run has started).
    """

    def __init__(self, own: dict[str, Any], node: Ros2Node, mission: str) -> None:
        self.own, self.node, self.mission = own, node, mission
        self._theirs: dict[str, Any] | None = None
        self._lock = threading.Lock()

    def _mission_side(self) -> dict[str, Any]:
        with self._lock:
            if self._theirs is None:
                _, self._theirs = open_remote_devices(self.node, self.mission, READY_TIMEOUT_S)
            return self._theirs

    def __getitem__(self, name: str) -> Any:
        if name in self.own:
            return self.own[name]
        return self._mission_side()[name]

    def __iter__(self) -> Iterator[str]:
        return iter({**dict.fromkeys(self.own), **dict.fromkeys(self._mission_side())})

    def __len__(self) -> int:
        return sum(1 for _ in self)


class ServeMissionInterfaces:
    """The mission's observer that serves its run services' interfaces to the skills processes."""

    name = "serve_interfaces"

    def __init__(self, node: Ros2Node) -> None:
        self.node = node

    def started(self, session: Any) -> None:
        devices = set(session.backend.devices) if session.backend is not None else set()
        own = {name: value for name, value in session.interfaces.items() if name not in devices}
        serve_devices(self.node, DeviceHost(own))


def _following(host: SkillHost, clock: SimClock, resting: Callable[[], bool]) -> Any:
    """The host, with this process's clock set to each request's tick before it runs (services read
    it), and each reply saying whether the process now has after-tick work (lockstep steps it then)."""

    class Following:
        def handle(self, request: TickRequest, timeout: float | None = None) -> Any:
            clock.ticks = request.ticks
            reply = host.handle(request, timeout)
            return dataclasses.replace(reply, pending_after_tick=not resting())

    return Following()


def _run_mission(
    role: Role,
    node: Ros2Node,
    *,
    out: Path,
    seed: int | None,
    until: float | None,
    ready: Callable[[str], None],
    observers: Sequence[object] = (),
) -> int:
    registry = Registry.default()
    links: dict[str, SkillTickLink] = {}
    for skill, process in sorted(role.skill_hosts.items()):
        if process == role.name:
            continue
        link = links.setdefault(process, SkillTickLink(node, process))
        registry.register(remote_of(registry.get(skill), link), replace=True)
    for process, link in links.items():
        if not link.wait_for_remote(READY_TIMEOUT_S):
            raise DeploymentError(f"process {process!r} does not serve its skills (waited {READY_TIMEOUT_S:g} s)")
    backends = BackendRegistry.default()
    backend = "sim"
    if role.robot_process:
        backends.register(RemoteKind(node, role.robot_process, simulated=True), replace=True)
        backend = "remote"
    lockstep = LockstepObserver(node, role.others, ready, lambda p: links[p].work_given if p in links else 0)
    lockstep.wait_ready(READY_TIMEOUT_S)
    remote = {skill: process for skill, process in role.skill_hosts.items() if process != role.name}
    ready(f"{role.name} runs the mission")
    result = run(
        role.mission_path,
        backend=backend,
        seed=seed,
        until=until,
        out=out,
        registry=registry,
        observers=[ServeMissionInterfaces(node), ClockPublisher(node), lockstep, MissionLog(remote, ready), *observers],
        backends=backends,
    )
    ready(f"{role.name}: {result.outcome} ({result.reason})")
    return result.exit_status
