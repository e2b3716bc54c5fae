"""rmw_zenoh's wire format, piece by piece: type hashes, CDR, names and keys, QoS strings, tokens, attachments.

Expected values come from outside botstage wherever there is one: rmw_zenoh's docs/design.md
(keys and tokens of the demo nodes, the String and AddTwoInts hashes), ROS 2's published type
hashes, CDR bytes packed here with ``struct``, and xxHash's reference value.
"""

from __future__ import annotations

import struct

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from botstage.robots.ros2 import qos as qos_strings
from botstage.robots.ros2 import types
from botstage.robots.ros2.attachment import Attachment, AttachmentError, decode, encode, entity_gid
from botstage.robots.ros2.graph import Graph
from botstage.robots.ros2.liveliness import (
    EntityKind,
    GraphEntity,
    TokenError,
    entity_token,
    graph_key,
    node_token,
    parse_token,
)
from botstage.robots.ros2.names import (
    data_key,
    demangle,
    fully_qualified_name,
    mangle,
    node_fqn,
    validate_full_topic_name,
    validate_namespace,
    validate_node_name,
    validate_topic_name,
)
from botstage.robots.ros2.qos import INFINITE, Durability, History, Liveliness, QoS, Reliability

STRING_HASH = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"  # design.md
ADD_TWO_INTS_HASH = "RIHS01_e118de6bf5eeb66a2491b5bda11202e7b68f198d6f67922cf30364858239c81a"  # design.md

# rmw_zenoh docs/design.md, "Graph Cache": the demo nodes' tokens
LISTENER_NODE = "@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/listener"
LISTENER_SUB = (
    "@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/10/MS/%/%/listener/%chatter/std_msgs::msg::dds_::String_/"
    f"{STRING_HASH}/::,10:,:,:,,"
)
TALKER_PUB = (
    "@ros2_lv/2/8b20917502ee955ac4476e0266340d5c/0/10/MP/%/%/talker/%chatter/std_msgs::msg::dds_::String_/"
    f"{STRING_HASH}/::,7:,:,:,,"
)
SERVER = (
    "@ros2_lv/2/f9980ee0495eaafb3e38f0d19e2eae12/0/10/SS/%/%/add_two_ints_server/%add_two_ints/"
    f"example_interfaces::srv::dds_::AddTwoInts_/{ADD_TWO_INTS_HASH}/::,10:,:,:,,"
)

finite = st.floats(allow_nan=False, allow_infinity=False)
token_text = st.from_regex(r"[a-z][a-z0-9_]{0,8}", fullmatch=True)
namespaces = st.lists(token_text, max_size=3).map(lambda parts: "/" + "/".join(parts))
topics = st.lists(token_text, min_size=1, max_size=3).map(lambda parts: "/" + "/".join(parts))
durations = st.one_of(st.just(INFINITE), st.integers(min_value=1, max_value=INFINITE))
profiles = st.builds(
    QoS,
    reliability=st.sampled_from([Reliability.RELIABLE, Reliability.BEST_EFFORT]),
    durability=st.sampled_from([Durability.VOLATILE, Durability.TRANSIENT_LOCAL]),
    history=st.sampled_from([History.KEEP_LAST, History.KEEP_ALL]),
    depth=st.integers(min_value=1, max_value=10_000),
    deadline=durations,
    lifespan=durations,
    liveliness=st.sampled_from([Liveliness.AUTOMATIC, Liveliness.MANUAL_BY_TOPIC]),
    lease=durations,
)


# -- types: hashes and CDR -----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("type_name", "expected"),
    [
        ("std_msgs/msg/String", STRING_HASH),
        ("geometry_msgs/msg/Twist", "RIHS01_9c45bf16fe0983d80e3cfe750d6835843d265a9a6c46bd2e609fcddde6fb8d2a"),
        ("nav_msgs/msg/Odometry", "RIHS01_3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0"),
        ("sensor_msgs/msg/LaserScan", "RIHS01_64c191398013af96509d518dac71d5164f9382553fce5c1f8cca5be7924bd828"),
    ],
)
def test_standard_types_hash_to_their_published_rihs01(type_name: str, expected: str) -> None:
    assert types.type_hash(type_name) == expected


def test_botstage_types_are_registered_from_the_shipped_msg_files() -> None:
    shipped = types.shipped_definitions()
    assert set(shipped) >= {
        "botstage_msgs/msg/PersonTrack",
        "botstage_msgs/msg/PeopleTracks",
        "botstage_msgs/msg/AudioChunk",
    }
    for name in shipped:
        assert types.is_known(name)
        assert types.type_hash(name).startswith("RIHS01_") and len(types.type_hash(name)) == 71
    assert types.message_class("botstage_msgs/msg/AudioChunk").SAMPLE_RATE_16K == 16000


def test_a_twist_is_the_encapsulation_header_then_six_little_endian_doubles() -> None:
    Twist, Vector3 = types.message_class("geometry_msgs/msg/Twist"), types.message_class("geometry_msgs/msg/Vector3")
    message = Twist(linear=Vector3(x=0.5, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=0.25))
    data = types.serialize(message)
    assert type(data) is bytes
    assert data == b"\x00\x01\x00\x00" + struct.pack("<6d", 0.5, 0, 0, 0, 0, 0.25)
    back = types.deserialize(data, "geometry_msgs/msg/Twist")
    assert (back.linear.x, back.angular.z) == (0.5, 0.25)


def test_a_string_is_its_length_with_the_terminator_then_its_bytes() -> None:
    String = types.message_class("std_msgs/msg/String")
    assert types.serialize(String(data="hello")) == b"\x00\x01\x00\x00" + struct.pack("<I", 6) + b"hello\x00"
    big_endian = b"\x00\x00\x00\x00" + struct.pack(">I", 6) + b"hello\x00"
    assert types.deserialize(big_endian, "std_msgs/msg/String").data == "hello"
    assert types.deserialize(memoryview(big_endian), "std_msgs/msg/String").data == "hello"


@given(linear=st.tuples(finite, finite, finite), angular=st.tuples(finite, finite, finite))
def test_twists_round_trip(linear: tuple[float, float, float], angular: tuple[float, float, float]) -> None:
    Twist, Vector3 = types.message_class("geometry_msgs/msg/Twist"), types.message_class("geometry_msgs/msg/Vector3")
    message = Twist(linear=Vector3(*linear), angular=Vector3(*angular))
    back = types.deserialize(types.serialize(message), "geometry_msgs/msg/Twist")
    assert (back.linear.x, back.linear.y, back.linear.z) == linear
    assert (back.angular.x, back.angular.y, back.angular.z) == angular


@given(text=st.text(st.characters(blacklist_categories=("Cs",), blacklist_characters="\x00")))
def test_strings_round_trip(text: str) -> None:
    String = types.message_class("std_msgs/msg/String")
    assert types.deserialize(types.serialize(String(data=text)), "std_msgs/msg/String").data == text


@given(samples=st.lists(st.integers(-32768, 32767), max_size=400), sec=st.integers(0, 2**31 - 1))
def test_audio_chunks_round_trip(samples: list[int], sec: int) -> None:
    AudioChunk = types.message_class("botstage_msgs/msg/AudioChunk")
    Header, Time = types.message_class("std_msgs/msg/Header"), types.message_class("builtin_interfaces/msg/Time")
    pcm = np.array(samples, dtype=np.int16)
    message = AudioChunk(header=Header(stamp=Time(sec=sec, nanosec=1), frame_id="mic"), sample_rate=16000, samples=pcm)
    data = types.serialize(message)
    assert data[:4] == b"\x00\x01\x00\x00"
    back = types.deserialize(data, "botstage_msgs/msg/AudioChunk")
    assert back.sample_rate == 16000 and back.header.stamp.sec == sec
    assert back.samples.dtype == np.int16 and np.array_equal(back.samples, pcm)


@given(people=st.lists(st.tuples(st.integers(0, 2**32 - 1), finite, finite), max_size=8))
def test_people_tracks_round_trip(people: list[tuple[int, float, float]]) -> None:
    Tracks, Track = (
        types.message_class("botstage_msgs/msg/PeopleTracks"),
        types.message_class("botstage_msgs/msg/PersonTrack"),
    )
    Point, Header, Time = (
        types.message_class(n)
        for n in ("geometry_msgs/msg/Point", "std_msgs/msg/Header", "builtin_interfaces/msg/Time")
    )
    message = Tracks(
        header=Header(stamp=Time(sec=3, nanosec=0), frame_id="kinect"),
        range_min=0.5,
        range_max=4.0,
        people=[Track(id=i, position=Point(x=x, y=y, z=0.0)) for i, x, y in people],
    )
    back = types.deserialize(types.serialize(message), "botstage_msgs/msg/PeopleTracks")
    assert [(p.id, p.position.x, p.position.y) for p in back.people] == people
    assert (back.range_min, back.range_max, back.header.frame_id) == (0.5, 4.0, "kinect")


def test_unknown_types_are_refused_with_a_suggestion() -> None:
    with pytest.raises(types.UnknownTypeError, match=r"unknown message type 'geometry_msgs/msg/Twst'.*did you mean"):
        types.type_hash("geometry_msgs/msg/Twst")
    with pytest.raises(types.UnknownTypeError, match="botstage_msgs/msg/Nope"):
        types.deserialize(b"\x00\x01\x00\x00", "botstage_msgs/msg/Nope")
    with pytest.raises(ValueError, match="expected 'package/msg/Type'"):
        types.dds_type_name("geometry_msgs/Twist")


def test_bad_bytes_are_cdr_errors_naming_the_type() -> None:
    with pytest.raises(types.CdrError, match="4-byte header"):
        types.deserialize(b"\x00\x01", "std_msgs/msg/String")
    with pytest.raises(types.CdrError, match="unsupported CDR encapsulation 00 07"):
        types.deserialize(b"\x00\x07\x00\x00" + bytes(8), "std_msgs/msg/String")
    with pytest.raises(types.CdrError, match="not a geometry_msgs/msg/Twist message"):
        types.deserialize(b"\x00\x01\x00\x00" + bytes(47), "geometry_msgs/msg/Twist")


def test_a_message_is_serialised_only_as_its_own_type() -> None:
    String = types.message_class("std_msgs/msg/String")
    with pytest.raises(TypeError, match="std_msgs/msg/String message cannot be serialised as std_msgs/msg/Int32"):
        types.serialize(String(data="x"), "std_msgs/msg/Int32")


@pytest.mark.parametrize(
    ("ros", "dds"),
    [
        ("geometry_msgs/msg/Twist", "geometry_msgs::msg::dds_::Twist_"),
        ("example_interfaces/srv/AddTwoInts", "example_interfaces::srv::dds_::AddTwoInts_"),
        ("botstage_msgs/msg/PeopleTracks", "botstage_msgs::msg::dds_::PeopleTracks_"),
    ],
)
def test_dds_type_names(ros: str, dds: str) -> None:
    assert types.dds_type_name(ros) == dds
    assert types.ros_type_name(dds) == ros


# -- names and keys ------------------------------------------------------------------------------


def test_data_keys_are_those_of_design_md() -> None:
    assert data_key(0, "/chatter", "std_msgs::msg::dds_::String_", STRING_HASH) == (
        f"0/chatter/std_msgs::msg::dds_::String_/{STRING_HASH}"
    )
    assert data_key(0, "/robot1/chatter", "std_msgs::msg::dds_::String_", STRING_HASH) == (
        f"0/robot1/chatter/std_msgs::msg::dds_::String_/{STRING_HASH}"
    )
    assert data_key(2, "/add_two_ints", "example_interfaces::srv::dds_::AddTwoInts_", ADD_TWO_INTS_HASH) == (
        f"2/add_two_ints/example_interfaces::srv::dds_::AddTwoInts_/{ADD_TWO_INTS_HASH}"
    )
    twist = types.type_hash("geometry_msgs/msg/Twist")
    assert data_key(0, "/cmd_vel", types.dds_type_name("geometry_msgs/msg/Twist"), twist) == (
        f"0/cmd_vel/geometry_msgs::msg::dds_::Twist_/{twist}"
    )


def test_data_keys_refuse_what_is_not_a_name_or_a_chunk() -> None:
    with pytest.raises(ValueError, match="must be absolute"):
        data_key(0, "cmd_vel", "T_", "H")
    with pytest.raises(ValueError, match="domain id -1"):
        data_key(-1, "/cmd_vel", "T_", "H")
    with pytest.raises(ValueError, match="cannot be one key expression chunk"):
        data_key(0, "/cmd_vel", "a/b", "H")


@pytest.mark.parametrize(
    ("name", "mangled"), [("/", "%"), ("/robot1", "%robot1"), ("/cmd_vel", "%cmd_vel"), ("/a/b", "%a%b")]
)
def test_mangling_replaces_every_slash(name: str, mangled: str) -> None:
    assert mangle(name) == mangled and demangle(mangled) == name


@given(name=topics)
def test_mangled_names_fit_one_chunk_and_come_back(name: str) -> None:
    assert "/" not in mangle(name) and demangle(mangle(name)) == name


@pytest.mark.parametrize(
    ("name", "namespace", "node", "expected"),
    [
        ("cmd_vel", "/", None, "/cmd_vel"),
        ("cmd_vel", "/robot1", None, "/robot1/cmd_vel"),
        ("/scan", "/robot1", None, "/scan"),
        ("~/status", "/robot1", "base", "/robot1/base/status"),
        ("~", "/", "base", "/base"),
        ("{node}/status", "/", "base", "/base/status"),
        ("{ns}/status", "/robot1", None, "/robot1/status"),
        ("{namespace}/status", "/", None, "/status"),
    ],
)
def test_fully_qualified_names(name: str, namespace: str, node: str | None, expected: str) -> None:
    assert fully_qualified_name(name, namespace, node) == expected


@pytest.mark.parametrize(
    ("validate", "name", "message"),
    [
        (validate_node_name, "", "non-empty"),
        (validate_node_name, "my-node", r"'-' at index 2 is not allowed"),
        (validate_node_name, "2nd", "must not start with a digit"),
        (validate_node_name, "n" * 256, "256 characters, at most 255"),
        (validate_namespace, "robot1", "must be absolute"),
        (validate_namespace, "/robot1/", "must not end with '/'"),
        (validate_namespace, "/robot 1", r"' ' at index 6"),
        (validate_namespace, "/a//b", "repeated '/'"),
        (validate_namespace, "/1robot", "must not start with a digit"),
        (validate_full_topic_name, "cmd_vel", "must be absolute"),
        (validate_full_topic_name, "/", "must not end with '/'"),
        (validate_full_topic_name, "/cmd_vel/", "must not end with '/'"),
        (validate_full_topic_name, "/a/9b", r"must not start with a digit \(index 3\)"),
        (validate_full_topic_name, "/cmd-vel", r"'-' at index 4"),
        (validate_full_topic_name, "/" + "t" * 247, "248 characters, at most 247"),
        (validate_topic_name, "a/~b", "'~' may only start the name"),
        (validate_topic_name, "~b", "'~' may only start the name"),
        (validate_topic_name, "{node", "unmatched '{'"),
        (validate_topic_name, "a}b", "unmatched '}'"),
        (validate_topic_name, "{robot}/x", "unknown substitution '{robot}'"),
        (validate_topic_name, "9lives", "must not start with a digit"),
        (validate_topic_name, "scan/", "must not end with '/'"),
    ],
)
def test_invalid_names_are_refused_saying_why(validate, name: str, message: str) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ValueError, match=message):
        validate(name)


def test_private_names_need_a_node() -> None:
    with pytest.raises(ValueError, match="need a node name"):
        fully_qualified_name("~/status", "/")


def test_node_fully_qualified_names() -> None:
    assert node_fqn("/", "talker") == "/talker"
    assert node_fqn("/robot1", "talker") == "/robot1/talker"


# -- QoS strings ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("profile", "text"),
    [
        (QoS.default(), "::,10:,:,:,,"),
        (QoS.sensor_data(), "2::,5:,:,:,,"),
        (QoS(durability=Durability.TRANSIENT_LOCAL, depth=1), ":1:,1:,:,:,,"),
        (QoS(depth=7), "::,7:,:,:,,"),  # design.md's talker
        (QoS(depth=42), "::,:,:,:,,"),  # everything rmw_zenoh's default
        (QoS(history=History.KEEP_ALL, depth=42), "::2,:,:,:,,"),
        (QoS(deadline=1_500_000_000), "::,10:1,500000000:,:,,"),
        (QoS(lifespan=2_000_000_000, lease=3), "::,10:,:2,0:,0,3"),
        (QoS(liveliness=Liveliness.MANUAL_BY_TOPIC), "::,10:,:,:3,,"),
    ],
)
def test_qos_strings_leave_out_rmw_zenohs_defaults(profile: QoS, text: str) -> None:
    assert qos_strings.encode(profile) == text
    assert qos_strings.decode(text) == profile


def test_unspecified_and_system_default_values_resolve_as_rmw_zenoh_does() -> None:
    ros_default_as_given = QoS(
        reliability=Reliability.SYSTEM_DEFAULT,
        durability=Durability.SYSTEM_DEFAULT,
        history=History.SYSTEM_DEFAULT,
        depth=0,
        deadline=0,
        lifespan=0,
        liveliness=Liveliness.SYSTEM_DEFAULT,
        lease=0,
    )
    assert qos_strings.encode(ros_default_as_given) == "::,:,:,:,,"
    assert qos_strings.encode(QoS(reliability=Reliability.BEST_AVAILABLE, depth=10)) == "::,10:,:,:,,"


@given(profile=profiles)
def test_qos_strings_round_trip(profile: QoS) -> None:
    text = qos_strings.encode(profile)
    assert qos_strings.decode(text) == profile
    assert qos_strings.encode(qos_strings.decode(text)) == text


def test_qos_strings_of_other_implementations_decode() -> None:
    spelled_out = "1:2:1,10:9223372036,854775807:9223372036,854775807:1,9223372036,854775807"
    assert qos_strings.decode(spelled_out) == QoS.default()
    assert qos_strings.decode("::,10:,:,:,,:future") == QoS.default()  # fields past the known ones


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("::,10:,:,", "a profile needs 6 ':'-separated fields, got 5"),
        ("::10:,:,:,,", "history needs 2 ','-separated fields"),
        ("::,10:,:,:,", "liveliness needs 3"),
        ("4::,10:,:,:,,", r"reliability 4 is not one of \[0, 1, 2, 3\]"),
        (":x:,10:,:,:,,", "durability 'x' is not a whole number"),
        ("::,-1:,:,:,,", "depth '-1' is not a whole number"),
        ("::,10:9223372037,:,:,,", "deadline is longer than infinite"),
    ],
)
def test_malformed_qos_strings_are_refused_saying_why(text: str, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        qos_strings.decode(text)


def test_qos_values_are_checked() -> None:
    with pytest.raises(ValueError, match="depth -1"):
        QoS(depth=-1)
    with pytest.raises(ValueError, match="deadline"):
        QoS(deadline=-5)
    with pytest.raises(ValueError, match="reliability 9"):
        QoS(reliability=9)  # type: ignore[arg-type]
    assert QoS(reliability=2).reliability is Reliability.BEST_EFFORT  # type: ignore[arg-type]


# -- liveliness tokens ---------------------------------------------------------------------------


def test_tokens_are_built_exactly_as_design_md_shows_them() -> None:
    assert node_token(2, "aac3178e146ba6f1fc6e6a4085e77f21", 0, "/", "listener") == LISTENER_NODE
    string = ("/chatter", "std_msgs::msg::dds_::String_", STRING_HASH)
    listener = (2, "aac3178e146ba6f1fc6e6a4085e77f21", 0, 10, EntityKind.SUBSCRIPTION, "/", "listener")
    assert entity_token(*listener, *string, QoS()) == LISTENER_SUB
    talker = (2, "8b20917502ee955ac4476e0266340d5c", 0, 10, EntityKind.PUBLISHER, "/", "talker")
    assert entity_token(*talker, *string, QoS(depth=7)) == TALKER_PUB
    server = (2, "f9980ee0495eaafb3e38f0d19e2eae12", 0, 10, EntityKind.SERVICE, "/", "add_two_ints_server")
    service = ("/add_two_ints", "example_interfaces::srv::dds_::AddTwoInts_", ADD_TWO_INTS_HASH)
    assert entity_token(*server, *service, QoS()) == SERVER


def test_design_md_tokens_parse() -> None:
    talker = parse_token(TALKER_PUB)
    assert talker == GraphEntity(
        domain_id=2,
        zid="8b20917502ee955ac4476e0266340d5c",
        node_id="0",
        entity_id="10",
        kind=EntityKind.PUBLISHER,
        enclave="/",
        namespace="/",
        node_name="talker",
        topic="/chatter",
        dds_type="std_msgs::msg::dds_::String_",
        type_hash=STRING_HASH,
        qos=QoS(depth=7),
    )
    assert talker.node_fqn == "/talker"
    listener = parse_token(LISTENER_NODE)
    assert (listener.kind, listener.node_fqn, listener.topic, listener.qos) == (
        EntityKind.NODE,
        "/listener",
        None,
        None,
    )
    assert parse_token(SERVER).kind is EntityKind.SERVICE
    assert parse_token(LISTENER_SUB).qos == QoS()


@given(
    domain=st.integers(0, 232),
    zid=st.from_regex(r"[0-9a-f]{1,32}", fullmatch=True),
    ids=st.tuples(st.integers(0, 10**6), st.integers(0, 10**6)),
    kind=st.sampled_from([k for k in EntityKind if k is not EntityKind.NODE]),
    namespace=namespaces,
    node=token_text,
    topic=topics,
    type_name=st.sampled_from(["geometry_msgs/msg/Twist", "botstage_msgs/msg/AudioChunk"]),
    profile=profiles,
)
def test_tokens_round_trip(
    domain: int,
    zid: str,
    ids: tuple[int, int],
    kind: EntityKind,
    namespace: str,
    node: str,
    topic: str,
    type_name: str,
    profile: QoS,
) -> None:
    dds, hash_ = types.dds_type_name(type_name), types.type_hash(type_name)
    token = entity_token(domain, zid, ids[0], ids[1], kind, namespace, node, topic, dds, hash_, profile)
    entity = parse_token(token)
    assert (entity.domain_id, entity.zid, entity.node_id, entity.entity_id) == (domain, zid, str(ids[0]), str(ids[1]))
    assert (entity.kind, entity.namespace, entity.node_name, entity.enclave) == (kind, namespace, node, "/")
    assert (entity.topic, entity.dds_type, entity.type_hash, entity.qos) == (topic, dds, hash_, profile)
    node_entity = parse_token(node_token(domain, zid, ids[0], namespace, node))
    assert node_entity.kind is EntityKind.NODE and node_entity.node_fqn == node_fqn(namespace, node)


def test_tokens_of_other_implementations_parse() -> None:
    # ids that are not numbers, QoS spelled out in full, chunks past the thirteenth
    token = (
        "@ros2_lv/0/e773188/node-a/pub-7/MP/%/%robot1/cam/%robot1%image/sensor_msgs::msg::dds_::Image_/RIHS01_x/"
        "1:2:1,10:9223372036,854775807:9223372036,854775807:1,9223372036,854775807/extra"
    )
    entity = parse_token(token)
    assert (entity.node_id, entity.entity_id, entity.node_fqn, entity.topic) == (
        "node-a",
        "pub-7",
        "/robot1/cam",
        "/robot1/image",
    )
    assert entity.qos == QoS.default()


@pytest.mark.parametrize(
    ("key", "reason"),
    [
        ("@ros2_lx/0/z/0/0/NN/%/%/talker", "not under @ros2_lv"),
        ("@ros2_lv/0/z/0/0/NN/%/%", "8 chunks, a token has at least 9"),
        ("@ros2_lv/0/z/0//NN/%/%/talker", "empty chunk at position 4"),
        ("@ros2_lv/zero/z/0/0/NN/%/%/talker", "domain id 'zero' is not a number"),
        ("@ros2_lv/0/z/0/0/XX/%/%/talker", "unknown entity kind 'XX'"),
        ("@ros2_lv/0/z/0/1/MP/%/%/talker/%chatter/T_/H", "a publisher token has 13 chunks, this one 12"),
        ("@ros2_lv/0/z/0/1/MS/%/%/talker/%chatter/T_/H/1:2:1,10", "a profile needs 6"),
    ],
)
def test_malformed_tokens_are_rejected_with_the_reason(key: str, reason: str) -> None:
    with pytest.raises(TokenError, match=reason):
        parse_token(key)


def test_tokens_refuse_invalid_names() -> None:
    with pytest.raises(ValueError, match="node name"):
        node_token(0, "z", 0, "/", "my node")
    with pytest.raises(ValueError, match="must be absolute"):
        entity_token(0, "z", 0, 1, EntityKind.PUBLISHER, "/", "n", "chatter", "T_", "H", QoS())
    with pytest.raises(ValueError, match="use node_token"):
        entity_token(0, "z", 0, 1, EntityKind.NODE, "/", "n", "/chatter", "T_", "H", QoS())
    assert graph_key(3) == "@ros2_lv/3/**"


def test_a_graph_reads_tokens_as_ros2_tools_do() -> None:
    graph = Graph.from_tokens([LISTENER_NODE, LISTENER_SUB, TALKER_PUB, TALKER_PUB, SERVER, "@ros2_lv/0/broken"])
    assert graph.node_names() == ["/listener"]  # the talker's node token is not among these
    assert graph.topic_names_and_types() == {"/chatter": ["std_msgs/msg/String"]}
    assert graph.service_names_and_types() == {"/add_two_ints": ["example_interfaces/srv/AddTwoInts"]}
    assert [e.node_name for e in graph.endpoints("/chatter", EntityKind.PUBLISHER)] == ["talker"]
    assert len(graph.entities) == 4
    assert graph.rejected == (("@ros2_lv/0/broken", "'@ros2_lv/0/broken': 3 chunks, a token has at least 9"),)


# -- attachments ---------------------------------------------------------------------------------


def test_an_attachment_is_33_bytes_in_rmw_zenohs_layout() -> None:
    gid = bytes(range(16))
    data = encode(Attachment(1, 1_700_000_000_123_456_789, gid))
    assert data == struct.pack("<qqB", 1, 1_700_000_000_123_456_789, 16) + gid
    assert len(data) == 33
    assert decode(data) == Attachment(1, 1_700_000_000_123_456_789, gid)
    assert decode(data[:16] + data[17:]) == decode(data)  # 32 bytes: no length byte


@given(
    sequence=st.integers(-(2**63), 2**63 - 1),
    stamp=st.integers(-(2**63), 2**63 - 1),
    gid=st.binary(min_size=16, max_size=16),
)
def test_attachments_round_trip(sequence: int, stamp: int, gid: bytes) -> None:
    assert decode(encode(Attachment(sequence, stamp, gid))) == Attachment(sequence, stamp, gid)


@pytest.mark.parametrize(
    ("data", "reason"),
    [
        (b"", "33 bytes .or 32., got 0"),
        (bytes(34), "got 34"),
        (bytes(16) + b"\x08" + bytes(16), "GID length byte is 8"),
    ],
)
def test_bad_attachments_are_refused(data: bytes, reason: str) -> None:
    with pytest.raises(AttachmentError, match=reason):
        decode(data)


def test_attachment_fields_are_checked() -> None:
    with pytest.raises(ValueError, match="gid"):
        Attachment(1, 2, bytes(15))
    with pytest.raises(ValueError, match="sequence"):
        Attachment(2**63, 2, bytes(16))


def test_gids_are_xxh3_128_of_the_token_low_half_first() -> None:
    # xxHash's reference: XXH3_128bits("") = 99aa06d3014798d8 6001c324468d497f (high, low)
    assert entity_gid("") == bytes.fromhex("7f498d4624c30160") + bytes.fromhex("d8984701d306aa99")
    assert entity_gid(TALKER_PUB) != entity_gid(LISTENER_SUB)
    assert len(entity_gid(TALKER_PUB)) == 16
