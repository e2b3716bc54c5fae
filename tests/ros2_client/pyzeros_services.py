"""An independent ROS 2-over-Zenoh peer (pyzeros, not botstage's code) for services and actions.

Run in its own process: ``python pyzeros_services.py ENDPOINT``. It connects to ENDPOINT
(loopback, multicast scouting off) as node ``/pz`` and reports on stdout, one JSON object a line:

- ``ready``: once it serves ``/pz/add_two_ints`` (example_interfaces/srv/AddTwoInts) with pyzeros'
  server, with that server's token and the hashes ros2_pyterfaces gives every type it uses;
- ``services``: botstage's servers as their liveliness tokens say (name, DDS type, hash), parsed
  here, once botstage's ``/bs/trigger`` and the SkillCall action's services are all there;
- ``trigger``: the response of botstage's ``/bs/trigger`` (std_srvs/srv/Trigger), called with
  pyzeros' client;
- ``skill``: a call of botstage's ``/bs/skills/echo`` action (botstage_msgs/action/SkillCall) made
  the way rcl_action makes it, out of pyzeros' service clients and subscription: send_goal,
  the feedback received, then get_result.

pyzeros has service clients and servers but no actions. It leaves the graph and exits 0 on a line
``stop`` (or the end of input) on stdin, or at its failsafe deadline.
"""

from __future__ import annotations

import asyncio
import json
import sys
import threading
import time
import uuid

import asyncio_for_robotics as afor
import pyzeros
import zenoh
from independent_interfaces import (  # beside this script: Python puts the script's folder on the path
    AddTwoInts,
    SkillCall_FeedbackMessage,
    SkillCall_GetResult,
    SkillCall_GetResult_Request,
    SkillCall_Goal,
    SkillCall_SendGoal,
    SkillCall_SendGoal_Request,
    independent_hashes,
)
from ros2_pyterfaces.cyclone.std_srvs.srv import Trigger, Trigger_Request
from ros2_pyterfaces.cyclone.unique_identifier_msgs.msg import UUID

FAILSAFE_S = 90.0
ACTION = "/bs/skills/echo"


def emit(event: str, **fields: object) -> None:
    print(json.dumps({"event": event, **fields}), flush=True)


def open_session(endpoint: str) -> zenoh.Session:
    config = zenoh.Config()
    config.insert_json5("mode", '"peer"')
    config.insert_json5("scouting/multicast/enabled", "false")
    config.insert_json5("listen/endpoints", json.dumps(["tcp/127.0.0.1:0"]))
    config.insert_json5("connect/endpoints", json.dumps([endpoint]))
    return zenoh.open(config)


def botstage_services(session: zenoh.Session) -> list[list[str]]:
    """Servers (SS tokens) of node /bs: [service, DDS type, hash], chunks as rmw_zenoh's design.md lays them out."""
    found = set()
    for reply in session.liveliness().get("@ros2_lv/0/**", timeout=2.0):
        if reply.ok is None:
            continue
        chunks = str(reply.ok.key_expr).split("/")
        if len(chunks) >= 13 and chunks[5] == "SS" and chunks[8] == "bs":
            found.add((chunks[9].replace("%", "/"), chunks[10], chunks[11]))
    return [list(entry) for entry in sorted(found)]


def wait_for_botstage(session: zenoh.Session, deadline: float) -> list[list[str]]:
    wanted = {"/bs/trigger", *(f"{ACTION}/_action/{s}" for s in ("send_goal", "cancel_goal", "get_result"))}
    while time.monotonic() < deadline:
        services = botstage_services(session)
        if wanted <= {name for name, _, _ in services}:
            return services
        threading.Event().wait(0.05)
    return botstage_services(session)


async def serve_add(server: pyzeros.Server) -> None:
    async for responder in server.listen_reliable():
        responder.response.sum = responder.request.a + responder.request.b
        responder.send()


async def call_skill(deadline: float) -> dict[str, object]:
    """One SkillCall goal, as rcl_action's client does it, from pyzeros' primitives."""
    send_goal = pyzeros.Client(SkillCall_SendGoal, f"{ACTION}/_action/send_goal")
    get_result = pyzeros.Client(SkillCall_GetResult, f"{ACTION}/_action/get_result")
    feedback = pyzeros.Sub(SkillCall_FeedbackMessage, f"{ACTION}/_action/feedback")
    goal_id = uuid.uuid4().bytes
    feedback_seen: list[dict[str, object]] = []

    async def collect() -> None:
        async for message in feedback.listen_reliable():
            if bytes(message.goal_id.uuid) == goal_id:
                feedback_seen.append({"ticks": int(message.feedback.ticks), "detail": message.feedback.detail})

    collecting = asyncio.create_task(collect())
    left = max(0.0, deadline - time.monotonic())
    await asyncio.wait_for(send_goal.wait_for_service(), left)
    await asyncio.wait_for(get_result.wait_for_service(), left)
    goal = SkillCall_Goal(skill="echo", inputs_json='{"text": "hi"}', call_id="pz-1", tick=7)
    accepted = await send_goal.call_async(SkillCall_SendGoal_Request(goal_id=UUID(uuid=goal_id), goal=goal))
    response = await get_result.call_async(SkillCall_GetResult_Request(goal_id=UUID(uuid=goal_id)))
    await asyncio.sleep(0.2)  # feedback published before the result may still be in flight
    collecting.cancel()
    return {
        "accepted": bool(accepted.accepted),
        "stamp": [int(accepted.stamp.sec), int(accepted.stamp.nanosec)],
        "status": int(response.status),
        "outcome": response.result.outcome,
        "reason": response.result.reason,
        "outputs_json": response.result.outputs_json,
        "ticks": int(response.result.ticks),
        "feedback": feedback_seen,
    }


@afor.scoped
async def exchange(session: zenoh.Session, stop: threading.Event, deadline: float) -> None:
    server = pyzeros.Server(AddTwoInts, "/pz/add_two_ints")
    serving = asyncio.create_task(serve_add(server))
    emit("ready", server_token=server.token_keyexpr, hashes=independent_hashes() | {"trigger": Trigger.hash_rihs01()})
    services = await asyncio.to_thread(wait_for_botstage, session, deadline)
    emit("services", services=services)
    trigger = pyzeros.Client(Trigger, "/bs/trigger")
    await asyncio.wait_for(trigger.wait_for_service(), max(0.0, deadline - time.monotonic()))
    answer = await asyncio.wait_for(trigger.call_async(Trigger_Request()), max(0.0, deadline - time.monotonic()))
    emit("trigger", success=bool(answer.success), message=answer.message)
    emit("skill", **await call_skill(deadline))
    while not stop.is_set() and time.monotonic() < deadline:
        await asyncio.sleep(0.05)
    serving.cancel()


def watch_stdin(stop: threading.Event) -> None:
    for line in sys.stdin:
        if line.strip() == "stop":
            break
    stop.set()


def main() -> int:
    endpoint = sys.argv[1]
    deadline = time.monotonic() + FAILSAFE_S
    stop = threading.Event()
    threading.Thread(target=watch_stdin, args=(stop,), daemon=True).start()
    session = open_session(endpoint)
    try:
        with pyzeros.auto_context(node="pz", zenoh_session=session):
            asyncio.run(exchange(session, stop, deadline))
    finally:
        session.close()
    emit("done")
    return 0


if __name__ == "__main__":
    sys.exit(main())
