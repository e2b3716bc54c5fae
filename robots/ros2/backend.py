"""The ``ros2`` backend: a mission runs on a robot that is already on a ROS 2 graph.

The robot is anything that publishes and subscribes the topics of robots/ros2/topics.py under
the names its profile's ``ros2:`` gives (ROS's defaults otherwise): a ROS 2 robot over rmw_zenoh,
or ``botstage serve robot`` in another process or on another machine. The backend joins the graph
as a node (``node_name`` in ``namespace``, ``domain_id``), connecting to ``connect`` (by default
where ROS 2 nodes find their router, ``tcp/127.0.0.1:7447``) and listening on loopback only; the
mission runs on a wall clock. The robot's devices are proxies (robots.ros2.topic_robot.py,
robots/ros2/proxies.py), loaded only when a run opens the backend: listing backends stays light.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from pydantic import Field, field_validator

from botstage.robots.backend import Backend, BackendKind, BackendOptions, OpenRequest
from botstage.robots.ros2.endpoints import DEFAULT_LISTEN, ROUTER_LISTEN, endpoints
from botstage.robots.ros2.names import check_domain_id, validate_namespace, validate_node_name
from botstage.robots.ros2.topics import check_section

if TYPE_CHECKING:
    from botstage.robots.profile import Profile


class Ros2Options(BackendOptions):
    domain_id: int = Field(default=0, description="the ROS 2 domain (ROS_DOMAIN_ID)")
    connect: list[str] = Field(
        default=[ROUTER_LISTEN],
        description="Zenoh endpoints to connect to, comma-separated (rmw_zenohd's, or a robot process's --listen)",
    )
    listen: list[str] = Field(default=[DEFAULT_LISTEN], description="Zenoh endpoints to listen on, comma-separated")
    namespace: str = Field(default="/", description="the node's namespace: relative topics are under it")
    node_name: str = Field(default="botstage", description="the mission's node name on the graph")
    ready_timeout: float = Field(default=10.0, gt=0, description="s to wait at open for each topic's first message")
    stale_after: float = Field(
        default=1.0, gt=0, description="s after which a reading is stale (or 3 periods of its rate, if longer)"
    )

    @field_validator("connect", "listen", mode="before")
    @classmethod
    def _endpoints(cls, value: Any) -> list[str]:
        return endpoints(value if isinstance(value, str | list | tuple) else str(value))

    @field_validator("domain_id")
    @classmethod
    def _domain(cls, value: int) -> int:
        return check_domain_id(value)

    @field_validator("namespace")
    @classmethod
    def _namespace(cls, value: str) -> str:
        return validate_namespace(value)

    @field_validator("node_name")
    @classmethod
    def _node_name(cls, value: str) -> str:
        return validate_node_name(value)


class Ros2Kind(BackendKind):
    name = "ros2"
    description = "a robot already on a ROS 2 graph (rmw_zenoh's format over Zenoh), its topics from the profile"
    simulated = False
    Options = Ros2Options
    profile_section = "ros2"

    def check_profile(self, profile: Profile) -> list[tuple[tuple[str, ...], str, str]]:
        section = profile.ros2
        problems = check_section(section.topics, section.rates_hz, list(profile.interfaces))
        return [(("ros2", *where), f"ros2: {message}", hint) for where, message, hint in problems]

    def open(self, request: OpenRequest, options: BackendOptions) -> Backend:
        from botstage.robots.ros2.topic_robot import Ros2Backend  # zenoh and rosbags load only when used

        assert isinstance(options, Ros2Options)
        return Ros2Backend.open(request, options)
