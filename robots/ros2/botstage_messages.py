"""The readings and commands that have no standard ROS 2 message, and their messages.

People tracks and audio chunks travel as botstage's own messages (``botstage_msgs``, shipped
with their type hashes); what the speaker says and whether it is talking, and what the display
shows, as ``std_msgs``: ``String`` (the text to say), ``Bool`` (speaking), and ``String`` holding
JSON for the display (``{"layout": "Layout_1", "content": {"title": "Hello"}}``), a layout and
its text fields being nothing ROS has a message for.

People are in the tracker's frame as REP 103 has it (x forward, y left), which the interface's
Kinect convention (x right, z forward) maps onto exactly: ``position.x = z``, ``position.y = -x``.
As in readings.py, ``*_of`` functions refuse what a reading cannot hold with a ValueError naming
the field.
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

from botstage.robots.interfaces import AUDIO_RATE_HZ, TrackedPerson
from botstage.robots.ros2 import types
from botstage.robots.ros2.readings import header

# a display message is bounded: layouts are names and a handful of short fields
DISPLAY_MAX_CHARS = 64 * 1024


def _type(name: str) -> Any:
    return types.message_class(name)


# -- people ----------------------------------------------------------------------------------------


def people_message(
    people: list[TrackedPerson], stamp: float, range_min: float, range_max: float, frame_id: str = "people_sensor"
) -> Any:
    """botstage_msgs/PeopleTracks of what the tracker sees now."""
    Point, Track = _type("geometry_msgs/msg/Point"), _type("botstage_msgs/msg/PersonTrack")
    tracks = [Track(id=int(p.id), position=Point(x=float(p.z), y=-float(p.x), z=0.0)) for p in people]
    return _type("botstage_msgs/msg/PeopleTracks")(
        header=header(stamp, frame_id), range_min=float(range_min), range_max=float(range_max), people=tracks
    )


def people_of(message: Any) -> tuple[list[TrackedPerson], float, float]:
    """The people of a PeopleTracks, with the tracker's range (min, max)."""
    people = []
    for track in message.people:
        x, y = float(track.position.x), float(track.position.y)
        if not (math.isfinite(x) and math.isfinite(y)):
            raise ValueError(f"person {track.id}'s position must be finite, got ({x!r}, {y!r})")
        people.append(TrackedPerson(int(track.id), -y, x))
    low, high = float(message.range_min), float(message.range_max)
    if not (math.isfinite(low) and math.isfinite(high) and 0 <= low < high):
        raise ValueError(f"people range_min and range_max must satisfy 0 <= min < max, got {low!r}, {high!r}")
    return people, low, high


# -- audio -----------------------------------------------------------------------------------------


def audio_message(samples: np.ndarray, stamp: float, frame_id: str = "microphone") -> Any:
    """botstage_msgs/AudioChunk of 16 kHz mono int16 samples; ``stamp`` is the first sample's time."""
    samples = np.asarray(samples)
    if samples.ndim != 1 or samples.dtype != np.int16:
        raise ValueError(f"audio must be one-dimensional int16 samples, got {samples.dtype} {samples.shape}")
    return _type("botstage_msgs/msg/AudioChunk")(
        header=header(stamp, frame_id), sample_rate=AUDIO_RATE_HZ, samples=np.ascontiguousarray(samples)
    )


def audio_of(message: Any) -> np.ndarray:
    """The int16 samples of an AudioChunk; only 16 kHz, the rate the recogniser takes."""
    if int(message.sample_rate) != AUDIO_RATE_HZ:
        raise ValueError(f"audio sample_rate must be {AUDIO_RATE_HZ} Hz, got {message.sample_rate}")
    return np.asarray(message.samples, dtype=np.int16).copy()


# -- speaker and display -------------------------------------------------------------------------


def text_message(text: str) -> Any:
    """std_msgs/String: what the speaker is to say."""
    return _type("std_msgs/msg/String")(data=str(text))


def flag_message(value: bool) -> Any:
    """std_msgs/Bool: whether the speaker is talking."""
    return _type("std_msgs/msg/Bool")(data=bool(value))


def display_message(layout: str, content: dict[str, str]) -> Any:
    """std_msgs/String holding ``{"layout": ..., "content": {...}}``."""
    return text_message(json.dumps({"layout": layout, "content": content}, ensure_ascii=False, sort_keys=True))


def display_of(message: Any) -> tuple[str, dict[str, str]]:
    """The layout and content of a display message; a ValueError says what is wrong with it."""
    text = message.data
    if len(text) > DISPLAY_MAX_CHARS:
        raise ValueError(f"a display message must be at most {DISPLAY_MAX_CHARS} characters, got {len(text)}")
    try:
        data = json.loads(text)
    except json.JSONDecodeError as error:
        raise ValueError(f"a display message is JSON, {{'layout': ..., 'content': {{...}}}}: {error}") from None
    if not isinstance(data, dict) or not isinstance(data.get("layout"), str) or not data["layout"]:
        raise ValueError("a display message needs a non-empty 'layout' string")
    content = data.get("content", {})
    if not isinstance(content, dict) or not all(isinstance(k, str) and isinstance(v, str) for k, v in content.items()):
        raise ValueError("a display message's 'content' maps field names to strings")
    unknown = set(data) - {"layout", "content"}
    if unknown:
        raise ValueError(f"a display message has only 'layout' and 'content', not {sorted(unknown)}")
    return data["layout"], content
