"""A secured deployment: every process on mutual TLS with its certificate, and one access policy from the file.

``botstage certs DIR --deployment FILE`` makes the authority and one folder per process;
``botstage serve process FILE NAME --certs DIR`` (and ``botstage up FILE --secure``) then opens
the process's session with ``robots.ros2.security``: TLS links only, a peer without a certificate
of that authority never connects, and Zenoh's access control (default deny) filters what the
processes it does know may do. The policy is derived from the deployment, the same in every
process, so nobody writes ACL rules by hand:

- only the mission's process calls a process's skills (``/<p>/skill_tick`` and the skills'
  actions under ``/<p>/skills``) and steps it in lockstep (``/<p>/lockstep``), and only it
  publishes ``/clock``;
- a process's devices (``/<p>/device_call``, ``/<p>/describe_devices``: the robot's drive among
  them, which is what moves the robot) are called only by the processes that run the mission or
  skills, never by one that serves neither (a gallery, say);
- the router forwards what the others send, so it is trusted with every resource.

Decided: ``--certs`` takes either a process's own folder (what is copied to its machine) or the
folder ``botstage certs`` wrote, in which the process's subfolder is used. Endpoints default to
``tls/`` on the same addresses as unsecured ones; a ``tcp/`` endpoint given with ``--certs`` is
an error rather than a silent change of protocol.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from missions.deployment import CheckedDeployment
from robots.remote.ros2_link import call_service, describe_service
from robots.ros2.certs import PROCESS_CERT, Credentials
from robots.ros2.security import SECURE_PROTOCOL, AccessPolicy, security_options
from skills.remote.ros2_link import service_name as skill_tick_service

SKILL_ACTIONS = "skills"
CLOCK = "/clock"


class SecurityError(ValueError):
    """Certificates or endpoints a secured process cannot run with."""


def deployment_policy(checked: CheckedDeployment) -> AccessPolicy:
    """Who may call and publish what in this deployment (see the module's docstring)."""
    from missions.distributed.process import lockstep_service  # it imports this module

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
    return AccessPolicy(
        processes=names,
        publishers={CLOCK: [mission]},
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
