"""botstage_msgs written anew in ros2_pyterfaces (pyzeros' types), from the .msg files' text.

ros2_pyterfaces computes RIHS01 hashes and CDR without rosbags, so these classes check that
botstage's type store gives its own messages the hashes and bytes any ROS 2 implementation would.
(No ``from __future__ import annotations``: ros2_pyterfaces reads the field types at class creation.)
"""

from dataclasses import dataclass, field

from ros2_pyterfaces.cyclone import idl
from ros2_pyterfaces.cyclone.geometry_msgs.msg import Point
from ros2_pyterfaces.cyclone.std_msgs.msg import Header


@dataclass
class PersonTrack(idl.IdlStruct, typename="botstage_msgs/msg/PersonTrack"):
    id: idl.types.uint32 = 0
    position: Point = field(default_factory=Point)


@dataclass
class PeopleTracks(idl.IdlStruct, typename="botstage_msgs/msg/PeopleTracks"):
    header: Header = field(default_factory=Header)
    range_min: idl.types.float32 = 0.0
    range_max: idl.types.float32 = 0.0
    people: idl.types.sequence[PersonTrack] = field(default_factory=list)


@dataclass
class AudioChunk(idl.IdlStruct, typename="botstage_msgs/msg/AudioChunk"):
    header: Header = field(default_factory=Header)
    sample_rate: idl.types.uint32 = 0
    samples: idl.types.sequence[idl.types.int16] = field(default_factory=list)
