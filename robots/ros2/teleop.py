"""Teleop of a robot another process serves as ROS 2 topics (``botstage serve robot``, a
deployment's robot process with ``topics: true``): the ROS 2 set's side of robots/teleop.py."""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from typing import Any

from botstage.robots.backend import OpenRequest
from botstage.robots.clock import Clock
from botstage.robots.interfaces import Pose2D
from botstage.robots.profile import Profile
from botstage.robots.ros2.backend import Ros2Options
from botstage.robots.ros2.node import DEFAULT_LISTEN, Ros2Node
from botstage.robots.ros2.topic_robot import Ros2Backend
from botstage.robots.teleop import TELEOP_INTERFACES

SECURE_LISTEN = "tls/127.0.0.1:0"  # a secured session speaks only TLS, on loopback here too
KNOCK_S = 0.1  # zero velocity this often until the served robot's odometry comes


def open_served(
    profile: Profile,
    start: Pose2D,
    clock: Clock,
    connect: Sequence[str],
    *,
    domain_id: int = 0,
    namespace: str = "/",
    node_name: str = "teleop",
    ready_timeout: float = 10.0,
    security: Mapping[str, Any] | None = None,
) -> Ros2Backend:
    """The robot another process serves as ROS 2 topics, for teleop: ``cmd_vel`` published, ``odom`` read.

    Teleop joins the graph as node ``node_name``, connected to ``connect`` (the robot process's or
    the router's endpoint), through the ``ros2`` backend's own proxies, subscribed to nothing but
    the odometry (a camera's frames are not its business). Until the first odometry comes it
    publishes zero velocity every ``KNOCK_S``: a deployment's robot process stands still, publishing
    nothing, until someone drives it. ``ConnectionError`` if the odometry does not come within
    ``ready_timeout`` seconds (of the transport's own monotonic time: the run's clock is not started).
    ``security`` (robots/ros2/security.py's options: mutual TLS with a certificate of the
    deployment's authority) reaches a secured deployment's robot: ``tls/`` endpoints only, and
    its ``cmd_vel`` arrives only with the operator's certificate or the mission's
    (missions/distributed/security.py); with another, the robot never moves nor answers.
    """
    if "drive" not in profile.interfaces:
        raise ValueError(f"robot {profile.name!r} has no drive")
    used = {name: spec for name, spec in profile.interfaces.items() if name in TELEOP_INTERFACES}
    options = Ros2Options(
        connect=list(connect),
        domain_id=domain_id,
        namespace=namespace,
        node_name=node_name,
        ready_timeout=ready_timeout,
    )
    node = Ros2Node(
        options.node_name,
        options.namespace,
        domain_id=options.domain_id,
        listen=[SECURE_LISTEN if security else DEFAULT_LISTEN],
        connect=options.connect,
        options=security,
    )
    try:
        backend = Ros2Backend(OpenRequest(profile.model_copy(update={"interfaces": used}), start, clock), options, node)
        odometry = backend.latest.get("odometry")
        deadline = time.monotonic() + ready_timeout
        backend.devices["drive"].stop()
        while odometry is not None and not odometry.ready.wait(KNOCK_S):
            if time.monotonic() > deadline:
                raise ConnectionError(
                    f"no odometry within {ready_timeout:g} s on {odometry.topic} through "
                    f"{', '.join(options.connect)} (domain {options.domain_id}): is the robot served there "
                    "(botstage serve robot, a deployment's robot process with `topics: true`), is no mission "
                    "driving it just now, and, for a secured deployment, are the endpoints tls/ with --certs, and is "
                    "the certificate one it lets drive (the operator's, certs/operator, or the mission's)?"
                )
            backend.devices["drive"].stop()
        if odometry is not None:  # show the robot's own odometry: a start given here means nothing to it
            backend.devices["odometry"].start = odometry.get()[0].pose
    except BaseException:
        node.close()
        raise
    return backend
