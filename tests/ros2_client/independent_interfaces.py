"""Services and actions written anew in ros2_pyterfaces (pyzeros' types), from their definitions' text.

ros2_pyterfaces hashes services (request, response and event) and serialises CDR without rosbags
or botstage's code, so these classes check botstage's service and action hashes and bytes. It has
no actions: an action's messages and its SendGoal and GetResult services are written here field
by field as rosidl generates them, and the action's own hash is composed from pyterfaces' schemas
(``action_hash``). (No ``from __future__ import annotations``: pyterfaces reads the field types at
class creation.)
"""

from dataclasses import dataclass, field
from typing import Any

from ros2_pyterfaces.core import TYPENAME_KEY, hash_rihs01
from ros2_pyterfaces.cyclone import idl
from ros2_pyterfaces.cyclone.builtin_interfaces.msg import Time
from ros2_pyterfaces.cyclone.unique_identifier_msgs.msg import UUID


@dataclass
class AddTwoInts_Request(idl.IdlStruct, typename="example_interfaces/srv/AddTwoInts_Request"):
    a: idl.types.int64 = 0
    b: idl.types.int64 = 0


@dataclass
class AddTwoInts_Response(idl.IdlStruct, typename="example_interfaces/srv/AddTwoInts_Response"):
    sum: idl.types.int64 = 0


AddTwoInts = idl.make_idl_service(AddTwoInts_Request, AddTwoInts_Response)


# botstage_msgs/action/SkillCall


@dataclass
class SkillCall_Goal(idl.IdlStruct, typename="botstage_msgs/action/SkillCall_Goal"):
    skill: str = ""
    inputs_json: str = ""
    params_json: str = ""
    call_id: str = ""
    tick: idl.types.uint64 = 0


@dataclass
class SkillCall_Result(idl.IdlStruct, typename="botstage_msgs/action/SkillCall_Result"):
    outcome: str = ""
    reason: str = ""
    outputs_json: str = ""
    ticks: idl.types.uint64 = 0


@dataclass
class SkillCall_Feedback(idl.IdlStruct, typename="botstage_msgs/action/SkillCall_Feedback"):
    ticks: idl.types.uint64 = 0
    detail: str = ""


@dataclass
class SkillCall_SendGoal_Request(idl.IdlStruct, typename="botstage_msgs/action/SkillCall_SendGoal_Request"):
    goal_id: UUID = field(default_factory=UUID)
    goal: SkillCall_Goal = field(default_factory=SkillCall_Goal)


@dataclass
class SkillCall_SendGoal_Response(idl.IdlStruct, typename="botstage_msgs/action/SkillCall_SendGoal_Response"):
    accepted: bool = False
    stamp: Time = field(default_factory=Time)


@dataclass
class SkillCall_GetResult_Request(idl.IdlStruct, typename="botstage_msgs/action/SkillCall_GetResult_Request"):
    goal_id: UUID = field(default_factory=UUID)


@dataclass
class SkillCall_GetResult_Response(idl.IdlStruct, typename="botstage_msgs/action/SkillCall_GetResult_Response"):
    status: idl.types.int8 = 0
    result: SkillCall_Result = field(default_factory=SkillCall_Result)


@dataclass
class SkillCall_FeedbackMessage(idl.IdlStruct, typename="botstage_msgs/action/SkillCall_FeedbackMessage"):
    goal_id: UUID = field(default_factory=UUID)
    feedback: SkillCall_Feedback = field(default_factory=SkillCall_Feedback)


SkillCall_SendGoal = idl.make_idl_service(
    SkillCall_SendGoal_Request, SkillCall_SendGoal_Response, typename="botstage_msgs/action/SkillCall_SendGoal"
)
SkillCall_GetResult = idl.make_idl_service(
    SkillCall_GetResult_Request, SkillCall_GetResult_Response, typename="botstage_msgs/action/SkillCall_GetResult"
)


# example_interfaces/action/Fibonacci


@dataclass
class Fibonacci_Goal(idl.IdlStruct, typename="example_interfaces/action/Fibonacci_Goal"):
    order: idl.types.int32 = 0


@dataclass
class Fibonacci_Result(idl.IdlStruct, typename="example_interfaces/action/Fibonacci_Result"):
    sequence: idl.types.sequence[idl.types.int32] = field(default_factory=list)


@dataclass
class Fibonacci_Feedback(idl.IdlStruct, typename="example_interfaces/action/Fibonacci_Feedback"):
    sequence: idl.types.sequence[idl.types.int32] = field(default_factory=list)


@dataclass
class Fibonacci_SendGoal_Request(idl.IdlStruct, typename="example_interfaces/action/Fibonacci_SendGoal_Request"):
    goal_id: UUID = field(default_factory=UUID)
    goal: Fibonacci_Goal = field(default_factory=Fibonacci_Goal)


@dataclass
class Fibonacci_SendGoal_Response(idl.IdlStruct, typename="example_interfaces/action/Fibonacci_SendGoal_Response"):
    accepted: bool = False
    stamp: Time = field(default_factory=Time)


@dataclass
class Fibonacci_GetResult_Request(idl.IdlStruct, typename="example_interfaces/action/Fibonacci_GetResult_Request"):
    goal_id: UUID = field(default_factory=UUID)


@dataclass
class Fibonacci_GetResult_Response(idl.IdlStruct, typename="example_interfaces/action/Fibonacci_GetResult_Response"):
    status: idl.types.int8 = 0
    result: Fibonacci_Result = field(default_factory=Fibonacci_Result)


@dataclass
class Fibonacci_FeedbackMessage(idl.IdlStruct, typename="example_interfaces/action/Fibonacci_FeedbackMessage"):
    goal_id: UUID = field(default_factory=UUID)
    feedback: Fibonacci_Feedback = field(default_factory=Fibonacci_Feedback)


Fibonacci_SendGoal = idl.make_idl_service(
    Fibonacci_SendGoal_Request, Fibonacci_SendGoal_Response, typename="example_interfaces/action/Fibonacci_SendGoal"
)
Fibonacci_GetResult = idl.make_idl_service(
    Fibonacci_GetResult_Request,
    Fibonacci_GetResult_Response,
    typename="example_interfaces/action/Fibonacci_GetResult",
)


def action_hash(name: str, goal: Any, result: Any, feedback: Any, send_goal: Any, get_result: Any, message: Any) -> str:
    """An action's hash from pyterfaces' schemas, nested under the field names rosidl gives an action."""
    schema = {
        TYPENAME_KEY: name,
        "goal": goal.to_core_schema(),
        "result": result.to_core_schema(),
        "feedback": feedback.to_core_schema(),
        "send_goal_service": send_goal.to_core_schema(),
        "get_result_service": get_result.to_core_schema(),
        "feedback_message": message.to_core_schema(),
    }
    return hash_rihs01(schema)


ACTIONS = {
    "botstage_msgs/action/SkillCall": (
        SkillCall_Goal,
        SkillCall_Result,
        SkillCall_Feedback,
        SkillCall_SendGoal,
        SkillCall_GetResult,
        SkillCall_FeedbackMessage,
    ),
    "example_interfaces/action/Fibonacci": (
        Fibonacci_Goal,
        Fibonacci_Result,
        Fibonacci_Feedback,
        Fibonacci_SendGoal,
        Fibonacci_GetResult,
        Fibonacci_FeedbackMessage,
    ),
}


def independent_hashes() -> dict[str, str]:
    """Every type above by full name, with the hash ros2_pyterfaces gives it."""
    hashes = {"example_interfaces/srv/AddTwoInts": AddTwoInts.hash_rihs01()}
    for name, parts in ACTIONS.items():
        hashes[name] = action_hash(name, *parts)
        for part in parts:
            hashes[part.get_type_name()] = part.hash_rihs01()
    return hashes


# my_msgs/srv/Measure, a service defined in a test's own folder (tests/test_ros2_services.py)


@dataclass
class Thing(idl.IdlStruct, typename="my_msgs/msg/Thing"):
    size: idl.types.int32 = 0


@dataclass
class Measure_Request(idl.IdlStruct, typename="my_msgs/srv/Measure_Request"):
    thing: Thing = field(default_factory=Thing)
    unit: idl.types.bounded_str[8] = ""


@dataclass
class Measure_Response(idl.IdlStruct, typename="my_msgs/srv/Measure_Response"):
    sizes: idl.types.array[idl.types.float64, 3] = field(default_factory=lambda: [0.0] * 3)
    ok: bool = False


Measure = idl.make_idl_service(Measure_Request, Measure_Response)
