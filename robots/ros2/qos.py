"""ROS 2 quality of service, and rmw_zenoh's compact QoS string in liveliness tokens.

The string is ``rel:dur:hist,depth:dl_s,dl_ns:life_s,life_ns:liv,lease_s,lease_ns`` with rmw's
enum numbers, every field left empty when it equals rmw_zenoh's default (reliable, volatile,
keep last, depth 42, infinite deadline, lifespan and lease, automatic liveliness): ROS's default
profile is ``::,10:,:,:,,`` and the sensor-data profile ``2::,5:,:,:,,``. Decoding accepts what
rmw_zenoh's ``keyexpr_to_qos`` accepts, so the tokens of other implementations parse too.

Before encoding, a profile is resolved as rmw_zenoh resolves it: system defaults and unknowns
become its defaults, an unspecified (zero) duration becomes infinite, depth 0 becomes 42.
"best available" becomes the default as well: rmw_zenoh's parser refuses the number 4 for
reliability and durability, so a token carrying it would be invisible to ROS 2 nodes.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from enum import IntEnum

NS_PER_S = 1_000_000_000
# RMW_DURATION_INFINITE is {9223372036 s, 854775807 ns}: exactly 2**63 - 1 nanoseconds.
INFINITE = 2**63 - 1
UNSPECIFIED = 0  # RMW_DURATION_UNSPECIFIED, ROS's default for deadline, lifespan and lease
ZENOH_DEFAULT_DEPTH = 42


class Reliability(IntEnum):
    """rmw_qos_reliability_policy_e."""

    SYSTEM_DEFAULT = 0
    RELIABLE = 1
    BEST_EFFORT = 2
    UNKNOWN = 3
    BEST_AVAILABLE = 4


class Durability(IntEnum):
    """rmw_qos_durability_policy_e."""

    SYSTEM_DEFAULT = 0
    TRANSIENT_LOCAL = 1
    VOLATILE = 2
    UNKNOWN = 3
    BEST_AVAILABLE = 4


class History(IntEnum):
    """rmw_qos_history_policy_e."""

    SYSTEM_DEFAULT = 0
    KEEP_LAST = 1
    KEEP_ALL = 2
    UNKNOWN = 3


class Liveliness(IntEnum):
    """rmw_qos_liveliness_policy_e (2, manual by node, is deprecated and absent)."""

    SYSTEM_DEFAULT = 0
    AUTOMATIC = 1
    MANUAL_BY_TOPIC = 3
    UNKNOWN = 4
    BEST_AVAILABLE = 5


@dataclass(frozen=True, slots=True)
class QoS:
    """A topic's quality of service; durations in nanoseconds, ``INFINITE`` for none.

    The defaults are ROS 2's default profile (``rmw_qos_profile_default``) as rmw_zenoh resolves it.
    """

    reliability: Reliability = Reliability.RELIABLE
    durability: Durability = Durability.VOLATILE
    history: History = History.KEEP_LAST
    depth: int = 10
    deadline: int = INFINITE
    lifespan: int = INFINITE
    liveliness: Liveliness = Liveliness.AUTOMATIC
    lease: int = INFINITE

    def __post_init__(self) -> None:
        for name, enum in (
            ("reliability", Reliability),
            ("durability", Durability),
            ("history", History),
            ("liveliness", Liveliness),
        ):
            value = getattr(self, name)
            try:
                object.__setattr__(self, name, enum(value))
            except ValueError:
                raise ValueError(f"QoS {name} {value!r}: not one of {[m.name.lower() for m in enum]}") from None
        if isinstance(self.depth, bool) or not isinstance(self.depth, int) or self.depth < 0:
            raise ValueError(f"QoS depth {self.depth!r}: must be an integer >= 0")
        for name in ("deadline", "lifespan", "lease"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= INFINITE:
                raise ValueError(f"QoS {name} {value!r}: must be nanoseconds from 0 to INFINITE (2**63 - 1)")

    @classmethod
    def default(cls) -> QoS:
        """ROS 2's default profile: reliable, volatile, keep last 10."""
        return cls()

    @classmethod
    def sensor_data(cls) -> QoS:
        """ROS 2's sensor-data profile: best effort, volatile, keep last 5."""
        return cls(reliability=Reliability.BEST_EFFORT, depth=5)

    def resolved(self) -> QoS:
        """This profile as rmw_zenoh resolves it before advertising it (see the module's notes)."""

        def pick(value: IntEnum, keep: tuple[IntEnum, ...], default: IntEnum) -> IntEnum:
            return value if value in keep else default

        def duration(value: int) -> int:
            return INFINITE if value == UNSPECIFIED else value

        return replace(
            self,
            reliability=pick(self.reliability, (Reliability.RELIABLE, Reliability.BEST_EFFORT), Reliability.RELIABLE),
            durability=pick(self.durability, (Durability.TRANSIENT_LOCAL, Durability.VOLATILE), Durability.VOLATILE),
            history=pick(self.history, (History.KEEP_LAST, History.KEEP_ALL), History.KEEP_LAST),
            depth=self.depth or ZENOH_DEFAULT_DEPTH,
            deadline=duration(self.deadline),
            lifespan=duration(self.lifespan),
            liveliness=pick(self.liveliness, (Liveliness.AUTOMATIC, Liveliness.MANUAL_BY_TOPIC), Liveliness.AUTOMATIC),
            lease=duration(self.lease),
        )


ZENOH_DEFAULT = QoS(depth=ZENOH_DEFAULT_DEPTH)  # what an empty field stands for


def _field(value: int, default: int) -> str:
    return "" if value == default else str(int(value))


def _duration_fields(value: int, default: int) -> str:
    seconds, nanoseconds = divmod(value, NS_PER_S)
    default_s, default_ns = divmod(default, NS_PER_S)
    return f"{_field(seconds, default_s)},{_field(nanoseconds, default_ns)}"


def encode(qos: QoS) -> str:
    """rmw_zenoh's QoS string of ``qos`` (resolved first), defaults left empty."""
    q, d = qos.resolved(), ZENOH_DEFAULT
    return ":".join(
        (
            _field(q.reliability, d.reliability),
            _field(q.durability, d.durability),
            f"{_field(q.history, d.history)},{_field(q.depth, d.depth)}",
            _duration_fields(q.deadline, d.deadline),
            _duration_fields(q.lifespan, d.lifespan),
            f"{_field(q.liveliness, d.liveliness)},{_duration_fields(q.lease, d.lease)}",
        )
    )


# The enum numbers rmw_zenoh's parser accepts in a token (its str_to_qos_* maps).
_ACCEPTED = {
    "reliability": (Reliability, (0, 1, 2, 3)),
    "durability": (Durability, (0, 1, 2, 3)),
    "history": (History, (0, 1, 2, 3)),
    "liveliness": (Liveliness, (0, 1, 3, 4, 5)),
}


def _number(text: str, default: int, what: str, source: str) -> int:
    if text == "":
        return default
    if not (text.isascii() and text.isdigit()):
        raise ValueError(f"QoS string {source!r}: {what} {text!r} is not a whole number")
    return int(text)


def _policy(text: str, name: str, default: IntEnum, source: str) -> IntEnum:
    enum, accepted = _ACCEPTED[name]
    value = _number(text, int(default), name, source)
    if value not in accepted:
        raise ValueError(f"QoS string {source!r}: {name} {value} is not one of {list(accepted)}")
    return enum(value)


def _duration(seconds: str, nanoseconds: str, default: int, what: str, source: str) -> int:
    default_s, default_ns = divmod(default, NS_PER_S)
    total = _number(seconds, default_s, f"{what} seconds", source) * NS_PER_S
    total += _number(nanoseconds, default_ns, f"{what} nanoseconds", source)
    if total > INFINITE:
        raise ValueError(f"QoS string {source!r}: {what} is longer than infinite")
    return total


def _split(text: str, sep: str, count: int, what: str, source: str) -> list[str]:
    parts = text.split(sep)
    if len(parts) < count:
        raise ValueError(f"QoS string {source!r}: {what} needs {count} '{sep}'-separated fields, got {len(parts)}")
    return parts


def decode(text: str) -> QoS:
    """The QoS an rmw_zenoh QoS string stands for; a ValueError saying what is wrong otherwise.

    Like rmw_zenoh, fields past the ones it knows are ignored (room for later versions).
    """
    d = ZENOH_DEFAULT
    parts = _split(text, ":", 6, "a profile", text)
    history = _split(parts[2], ",", 2, "history", text)
    deadline = _split(parts[3], ",", 2, "deadline", text)
    lifespan = _split(parts[4], ",", 2, "lifespan", text)
    liveliness = _split(parts[5], ",", 3, "liveliness", text)
    return QoS(
        reliability=_policy(parts[0], "reliability", d.reliability, text),
        durability=_policy(parts[1], "durability", d.durability, text),
        history=_policy(history[0], "history", d.history, text),
        depth=_number(history[1], d.depth, "depth", text),
        deadline=_duration(deadline[0], deadline[1], d.deadline, "deadline", text),
        lifespan=_duration(lifespan[0], lifespan[1], d.lifespan, "lifespan", text),
        liveliness=_policy(liveliness[0], "liveliness", d.liveliness, text),
        lease=_duration(liveliness[1], liveliness[2], d.lease, "lease", text),
    )
