"""A secured deployment: every process on mutual TLS with its certificate, and one access policy from the file.

``botstage certs DIR --deployment FILE`` makes the authority, one folder per process and one for
the operator (``DIR/operator``, see below); ``botstage serve process FILE NAME --certs DIR`` (and
``botstage up FILE --secure``) then opens the process's session with ``botstage.robots.ros2.security``:
TLS links only, a peer without a certificate of that authority never connects, and Zenoh's access
control (default deny) filters what the identities it does know may do. The policy is derived
from the deployment, the same in every process, so nobody writes ACL rules by hand:

- only the mission's process calls a process's skills (``/<p>/skill_tick`` and the skills'
  actions under ``/<p>/skills``) and steps it in lockstep (``/<p>/lockstep``), and only it
  publishes ``/clock``;
- a process's devices (``/<p>/device_call``, ``/<p>/describe_devices``: the robot's drive among
  them, which is what moves the robot) are called only by the processes that run the mission or
  skills, never by one that serves neither (a gallery, say);
- the robot's command topics, which a robot process subscribes to (``topics: true``,
  missions/distributed/operator.py), are published only by the mission's process and the
  operator: ``cmd_vel``, and ``say``, ``display`` and the pan's ``pan_controller/command`` too,
  each named as the robot's profile renames it (``ros2: topics:``) and as the robot process's node
  resolves it (root namespace, ``~`` under its name), in the deployment's domain. Decided: every
  command topic, not the drive's alone: each acts on the robot (the pan moves, ``say`` speaks
  aloud in the museum, ``display`` is the tablet guests read), and the processes that
  legitimately use those devices reach them by device calls, not topics. They are protected for
  every process that opens a backend, ``topics: true`` or not: closed costs nothing;
- the router forwards what the others send, so it is trusted with every resource.

Decided, the operator: ``botstage teleop ROBOT --connect ... --certs DIR`` is not a process of the
file, yet drives the robot while no mission does. It has an identity of its own, ``operator``
(``OPERATOR``, a name no process may take), whose certificate ``botstage certs --deployment`` makes
beside the processes' (and ``botstage up --secure`` in ``OUT/certs``). The policy names it, so it
connects and reads what every process may; it may publish the robot's command topics, and nothing
protected else (no skills, devices, lockstep or ``/clock``). A teleop with the mission's
certificate drives too (the Bittle PC's, which runs both); one with any other process's (the
gallery's) is dropped by the robot process, so the robot never moves for it.

Decided: ``--certs`` takes either a process's own folder (what is copied to its machine) or the
folder ``botstage certs`` wrote, in which the process's subfolder is used (teleop: ``operator/``).
Endpoints default to ``tls/`` on the same addresses as unsecured ones; a ``tcp/`` endpoint given
with ``--certs`` is an error rather than a silent change of protocol.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from botstage.missions.deployment import OPERATOR, CheckedDeployment
from botstage.missions.distributed.names import lockstep_service
from botstage.robots.remote.ros2_link import call_service, describe_service
from botstage.robots.ros2.certs import PROCESS_CERT, Credentials
from botstage.robots.ros2.names import fully_qualified_name
from botstage.robots.ros2.security import SECURE_PROTOCOL, AccessPolicy, security_options
from botstage.robots.ros2.topics import Direction, routes
from botstage.skills.remote.ros2_link import service_name as skill_tick_service

SKILL_ACTIONS = "skills"
CLOCK = "/clock"
PROCESS_NAMESPACE = "/"  # a deployment's processes are nodes in the root namespace (process.py)


class SecurityError(ValueError):
    """Certificates or endpoints a secured process cannot run with."""


def identities(checked: CheckedDeployment) -> list[str]:
    """Every certificate name the deployment's policy knows: its processes, then the operator."""
    assert checked.deployment is not None
    return [*checked.deployment.processes, OPERATOR]


def command_topics(checked: CheckedDeployment) -> list[str]:
    """The full names of the topics the robot processes take commands on (cmd_vel, say, display, pan)."""
    deployment = checked.deployment
    assert deployment is not None
    profile = checked.robot_profile()
    if profile is None:
        return []
    commands = [route.topic for route in routes(profile) if route.channel.direction is Direction.COMMAND]
    robots = [name for name, process in deployment.processes.items() if process.backend]
    found = (fully_qualified_name(topic, PROCESS_NAMESPACE, name) for name in robots for topic in commands)
    return list(dict.fromkeys(found))


def deployment_policy(checked: CheckedDeployment) -> AccessPolicy:
    """Who may call and publish what in this deployment (see the module's docstring)."""
    deployment = checked.deployment
    assert deployment is not None
    mission = checked.mission_process
    names = list(deployment.processes)
    callers: dict[str, list[str]] = {}
    users = [name for name, p in deployment.processes.items() if p.mission or p.skills]
    for name in names:
        callers[skill_tick_service(name)] = [mission]
        callers[f"/{name}/{SKILL_ACTIONS}"] = [mission]
        callers[lockstep_service(name)] = [mission]
        callers[call_service(name)] = users
        callers[describe_service(name)] = users
    publishers = {CLOCK: [mission]}
    for topic in command_topics(checked):
        publishers[topic] = [mission, OPERATOR]
    return AccessPolicy(
        processes=identities(checked),
        publishers=publishers,
        callers=callers,
        forwarders=[checked.router],
        domain_id=deployment.domain_id,
    )


def credentials(folder: Path, process: str) -> Credentials:
    """The process's credentials in ``folder``: its own folder, or ``botstage certs``' with its subfolder."""
    own = folder / process
    chosen = Credentials.in_folder(own if (own / PROCESS_CERT).is_file() else folder)
    missing = chosen.missing()
    if missing:
        listed = ", ".join(str(path) for path in missing)
        raise SecurityError(
            f"no TLS credentials for {process!r} in {folder} (missing {listed}); "
            f"make them with `botstage certs {folder} --deployment FILE`"
        )
    return chosen


def secured(endpoints: Sequence[str], given: Sequence[str]) -> list[str]:
    """``endpoints`` as TLS ones: those the user ``given`` must be tls already, defaults switch from tcp."""
    for endpoint in given:
        if not endpoint.startswith(f"{SECURE_PROTOCOL}/"):
            raise SecurityError(f"{endpoint}: a secured process speaks only {SECURE_PROTOCOL}/ (e.g. tls/HOST:7447)")
    return [
        f"{SECURE_PROTOCOL}/{endpoint.split('/', 1)[1]}" if endpoint.startswith("tcp/") else endpoint
        for endpoint in endpoints
    ]


def session_options(checked: CheckedDeployment, process: str, folder: Path) -> dict[str, Any]:
    """The Zenoh options of a secured process: its mutual TLS and the deployment's policy."""
    return security_options(credentials(folder, process), deployment_policy(checked))
