"""The host side of rosserial over a serial port (pyserial, 57600 8N1): what rosserial_python's
``SerialClient`` does, without ROS. The gesture controller's IMU (book ch. 5) speaks it.

Sources: ros-drivers/rosserial ``rosserial_python/src/rosserial_python/SerialClient.py``
(noetic) for the host's behaviour, ``rosserial_client/src/ros_lib/ros/node_handle.h`` for the
device's, ``rosserial_arduino/src/ros_lib/ArduinoHardware.h`` for the baud rate (57600, the
default of ``ArduinoHardware``; ``baud`` changes it). The framing and the protocol's own
messages are in ``rosserial_protocol``; messages are (de)serialised by rosbags.

What the host does, as SerialClient does it:

- **Topic negotiation**: on every (re)connection the topic request (an empty packet on topic 0)
  goes out first (it is ``SerialLink``'s safe command), and again every
  ``request_interval_s`` until the device has announced its endpoints (decision: 2 s; an Uno
  that the port's opening reset is in its bootloader for about that long, which is why
  SerialClient waits 2 s before its first request), when a publication comes on a topic id the
  host does not know ("Tried to publish before configured": the device kept its configuration
  while the host was away; at most once per interval), and when the device has not asked for
  the time in ``sync_timeout_s`` (SerialClient's 3 x 5 s: "Lost sync with device"; ros_lib asks
  every 2.5 s). What the host learned is forgotten on a reconnection and learned again.
- **TopicInfo**: a device publisher (topic 0) or subscriber (topic 1) is accepted when its type
  is known to the typestore and its md5 is the type's ROS 1 md5 as rosbags computes it;
  otherwise it is refused, counted (``unknown_type``, ``md5_mismatch``, ``bad_topic_id`` for an
  endpoint on a reserved id) and its publications are dropped and counted. Services are not
  supported (counted as ``unsupported_endpoint``).
- **Time**: a time request (topic 10) is answered at once with ``clock()`` (injectable; the
  host's wall clock by default) as ``std_msgs/Time``.
- **Publications** (topic ids from 100) are decoded by rosbags into messages and handed to the
  subscribers registered for their topic name (a leading ``/`` does not matter), in the reader
  thread: a subscriber must be quick, and one that raises is counted and does not stop the
  others. The latest message of each topic is kept (``latest``; ``orientation`` for the
  gesture controller's ``imu_data``).
- **Device logs** (topic 7, ``rosserial_msgs/Log``) go to Python logging (logger
  ``botstage.robots.drivers.rosserial.device``) at their level; **parameter requests** (topic 6) are
  answered from ``params`` (ints, floats or strings; a missing one is logged and not answered,
  as SerialClient does).
- **Sending** to a device's subscriber (``publish``) checks the type and the device's buffer
  size. On ``close()`` the tx stop request (topic 11) is the last word, as SerialClient's.

Types are looked up in ``rosserial_protocol.TYPESTORE`` (ROS 1 noetic's, rosserial's and
``tf/tfMessage``); a device with messages of its own needs
``typestore=make_typestore({"pkg/msg/Name": definition})``.

Garbage, cut packets, bad checksums, lying lengths and foreign protocol versions are the
decoder's to drop and count; unplugging and a silent port are ``SerialLink``'s (reopen with
backoff). ``stats()`` has all the counters.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from rosbags.typesys.store import Typestore

from botstage.robots.drivers import rosserial_protocol as rp
from botstage.robots.drivers.serial_link import RateLimitedLog, SerialLink

log = logging.getLogger(__name__)
device_log = logging.getLogger(__name__ + ".device")

BAUD = 57_600  # ArduinoHardware's default
IMU_TOPIC = "imu_data"  # the gesture sketch's publisher (geometry_msgs/Vector3: yaw, pitch, roll in degrees)
VECTOR3 = "geometry_msgs/msg/Vector3"
REQUEST_INTERVAL_S = 2.0
SYNC_TIMEOUT_S = 15.0
SILENCE_S = 10.0  # a configured device speaks at least every 2.5 s (its time requests)

LOG_LEVELS = {
    rp.ROSDEBUG: logging.DEBUG,
    rp.INFO: logging.INFO,
    rp.WARN: logging.WARNING,
    rp.ERROR: logging.ERROR,
    rp.FATAL: logging.CRITICAL,
}

Subscriber = Callable[[Any, float], None]


@dataclass(frozen=True, slots=True)
class Endpoint:
    """A device's publisher or subscriber, as its TopicInfo announced it."""

    topic_id: int
    topic_name: str
    typename: str  # rosbags' name, pkg/msg/Name
    md5sum: str
    buffer_size: int


@dataclass(frozen=True, slots=True)
class Orientation:
    """The gesture sketch's ``imu_data``: the MPU-6050 DMP's yaw, pitch and roll in degrees
    (Vector3 x, y, z), and when it arrived (the driver's monotonic clock)."""

    yaw: float
    pitch: float
    roll: float
    received: float


def topic_key(name: str) -> str:
    """A topic name as subscriptions match it: ``/imu_data`` and ``imu_data`` are one topic."""
    return name.lstrip("/")


class RosserialDriver:
    """The host side of rosserial on one port; see the module. A ``with`` block closes it."""

    def __init__(
        self,
        port: str,
        *,
        baud: int = BAUD,
        clock: Callable[[], float] = time.time,
        params: dict[str, Any] | None = None,
        typestore: Typestore | None = None,
        max_payload: int = rp.DEFAULT_MAX_PAYLOAD,
        request_interval_s: float = REQUEST_INTERVAL_S,
        sync_timeout_s: float = SYNC_TIMEOUT_S,
        backoff: tuple[float, float] = (0.05, 2.0),
        silence_s: float | None = SILENCE_S,
        read_timeout: float = 0.02,
        name: str = "rosserial",
        start: bool = True,
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        if not (request_interval_s > 0 and sync_timeout_s > 0):
            raise ValueError("request_interval_s and sync_timeout_s must be more than 0")
        self.clock = clock
        self.params = dict(params or {})
        self.store = typestore or rp.TYPESTORE
        self.request_interval_s = request_interval_s
        self.sync_timeout_s = sync_timeout_s
        self.monotonic = monotonic
        self.name = name
        self.counters: Counter[str] = Counter()
        self.warn = RateLimitedLog(log)
        self.decoder = rp.PacketDecoder(max_payload)
        self.link = SerialLink(
            port,
            self.decoder,
            rp.TOPIC_REQUEST,
            self,
            name=name,
            parting_command=rp.TX_STOP,
            baud=baud,
            backoff=backoff,
            silence_s=silence_s,
            read_timeout=read_timeout,
            start=False,
            monotonic=monotonic,
        )
        self._lock = threading.RLock()
        self._changed = threading.Condition(self._lock)
        self._publishers: dict[int, Endpoint] = {}
        self._device_subscribers: dict[str, Endpoint] = {}
        self._refused: dict[int, str] = {}
        self._subscribers: dict[str, list[Subscriber]] = {}
        self._latest: dict[str, tuple[Any, float]] = {}
        self._md5: dict[str, str] = {}
        self._announced = False
        self._last_request = monotonic()
        self._last_sync = monotonic()
        self._version_errors = 0
        self.keeps = 0  # passes of the keeper thread (tests wait on it, never on the clock)
        self._stop = threading.Event()
        self._keeper: threading.Thread | None = None
        if start:
            self.start()

    # -- lifecycle ----------------------------------------------------------------------------

    def start(self) -> None:
        if self._keeper is not None:
            return
        self._keeper = threading.Thread(target=self._keep, name=f"{self.name}-keeper {self.link.port}", daemon=True)
        self._keeper.start()
        self.link.start()

    def close(self) -> None:
        """The tx stop request, then the port closes. Safe to call twice."""
        self._stop.set()
        if self._keeper is not None and self._keeper is not threading.current_thread():
            self._keeper.join(timeout=2.0)
        self.link.close()
        with self._changed:
            self._changed.notify_all()

    def __enter__(self) -> RosserialDriver:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def port(self) -> str:
        return self.link.port

    @property
    def connected(self) -> bool:
        return self.link.connected

    # -- what the application uses -------------------------------------------------------------

    def subscribe(self, topic: str, callback: Subscriber) -> Callable[[], None]:
        """Call ``callback(message, received)`` for each message the device publishes on ``topic``
        (in the reader thread); returns what unsubscribes it."""
        key = topic_key(topic)
        with self._lock:
            self._subscribers.setdefault(key, []).append(callback)

        def unsubscribe() -> None:
            with self._lock:
                callbacks = self._subscribers.get(key, [])
                if callback in callbacks:
                    callbacks.remove(callback)

        return unsubscribe

    def latest(self, topic: str) -> tuple[Any, float] | None:
        """The last message on ``topic`` and when it arrived (monotonic), or None."""
        with self._lock:
            return self._latest.get(topic_key(topic))

    def orientation(self, topic: str = IMU_TOPIC) -> Orientation | None:
        """The gesture IMU's latest yaw, pitch, roll (degrees) with its receive time, or None."""
        latest = self.latest(topic)
        if latest is None or getattr(latest[0], "__msgtype__", None) != VECTOR3:
            return None
        message, received = latest
        return Orientation(float(message.x), float(message.y), float(message.z), received)

    @property
    def publishers(self) -> dict[int, Endpoint]:
        """The device's publishers by topic id, as learned since the last connection."""
        with self._lock:
            return dict(self._publishers)

    @property
    def device_subscribers(self) -> dict[str, Endpoint]:
        with self._lock:
            return dict(self._device_subscribers)

    @property
    def negotiated(self) -> bool:
        """Whether the device has announced its endpoints on this connection."""
        with self._lock:
            return self._announced

    def wait_until(self, predicate: Callable[[], bool], timeout: float) -> bool:
        """Wait until ``predicate()`` holds; it is checked whenever the driver's state changes
        (a packet handled, a connection made or lost)."""
        with self._changed:
            return self._changed.wait_for(predicate, timeout)

    def wait_negotiated(self, timeout: float) -> bool:
        return self.wait_until(lambda: self._announced, timeout)

    def publish(self, topic: str, message: Any) -> bool:
        """Send ``message`` to the device's subscriber on ``topic``; False when the device has
        none (yet), the message is larger than its buffer, or the port is down or closing."""
        with self._lock:
            endpoint = self._device_subscribers.get(topic_key(topic))
        if endpoint is None:
            self._count("publish_no_subscriber")
            return False
        if getattr(message, "__msgtype__", None) != endpoint.typename:
            raise TypeError(f"{topic} takes {endpoint.typename}, not {getattr(message, '__msgtype__', message)!r}")
        payload = rp.serialize(message, self.store)
        if len(payload) > endpoint.buffer_size:
            self._count("publish_oversize")
            self.warn.warning(
                "oversize", f"{self._where}: {topic}: {len(payload)} bytes do not fit the device's buffer"
            )
            return False
        if not self.link.motion_allowed:
            return False
        sent = self.link.send(rp.encode_packet(endpoint.topic_id, payload))
        if sent:
            self._count("published")
        return sent

    def request_topics(self) -> bool:
        """Ask the device for its endpoints now."""
        return self._request_topics(force=True)

    def stats(self) -> dict[str, Any]:
        """Counters for reports: packets parsed by kind, dropped by reason, link and host events."""
        with self._lock:
            publishers = {e.topic_name: rp.wire_name(e.typename) for e in self._publishers.values()}
            counters = dict(self.counters)
        return {
            "port": self.link.port,
            "connected": self.link.connected,
            "negotiated": self.negotiated,
            "publishers": dict(sorted(publishers.items())),
            "packets_ok": dict(sorted(self.decoder.ok.items())),
            "packets_bad": dict(sorted(self.decoder.bad.items())),
            **dict(sorted({**self.link.counters, **counters}.items())),
        }

    # -- the link's listener (reader thread) -----------------------------------------------------

    def on_connect(self) -> None:
        with self._changed:
            self._forget()
            now = self.monotonic()
            self._last_request = now  # the link has just sent the request (its safe command)
            self._last_sync = now
            self.counters["topic_requests"] += 1
            self._changed.notify_all()

    def on_disconnect(self) -> None:
        with self._changed:
            self._forget()
            self._changed.notify_all()

    def on_message(self, packet: rp.Packet, received: float) -> None:
        topic_id = packet.topic_id
        try:
            if topic_id >= rp.FIRST_DYNAMIC_ID:
                self._publication(packet, received)
            elif topic_id in (rp.ID_PUBLISHER, rp.ID_SUBSCRIBER):
                self._topic_info(packet.payload, publisher=topic_id == rp.ID_PUBLISHER)
            elif topic_id == rp.ID_TIME:
                self._time_request()
            elif topic_id == rp.ID_LOG:
                self._device_log(packet.payload)
            elif topic_id == rp.ID_PARAMETER_REQUEST:
                self._parameter_request(packet.payload)
            else:
                self._count("unsupported_endpoint")
                self.warn.warning("endpoint", f"{self._where}: {packet.kind} is not supported; dropped")
        finally:
            with self._changed:
                self._changed.notify_all()

    # -- handling ---------------------------------------------------------------------------------

    @property
    def _where(self) -> str:
        return f"{self.name} {self.link.port}"

    def _count(self, key: str, n: int = 1) -> None:
        with self._lock:
            self.counters[key] += n

    def _forget(self) -> None:
        self._publishers.clear()
        self._device_subscribers.clear()
        self._refused.clear()
        self._announced = False

    def _decode(self, payload: bytes, typename: str) -> Any:
        try:
            return rp.deserialize(payload, typename, self.store)
        except Exception as exc:  # rosbags raises SerdeError, struct, index and unicode errors
            self._count("undecodable")
            self.warn.warning("undecodable", f"{self._where}: a {typename} that does not decode: {exc}")
            return None

    def _expected_md5(self, typename: str) -> str:
        md5 = self._md5.get(typename)
        if md5 is None:
            md5 = self._md5[typename] = rp.md5sum(typename, self.store)
        return md5

    def _topic_info(self, payload: bytes, *, publisher: bool) -> None:
        info = self._decode(payload, rp.TOPIC_INFO)
        if info is None:
            return
        typename = rp.store_name(info.message_type)
        side = "publisher" if publisher else "subscriber"
        reason = None
        if info.topic_id < rp.FIRST_DYNAMIC_ID:
            reason = "bad_topic_id"
        elif typename is None or typename not in self.store.types:
            reason = "unknown_type"
        elif info.md5sum != self._expected_md5(typename):
            reason = "md5_mismatch"
        with self._lock:
            self._announced = True
            if reason is not None:
                self.counters[reason] += 1
                self._refused[info.topic_id] = reason
                self._publishers.pop(info.topic_id, None)
            else:
                assert typename is not None
                endpoint = Endpoint(info.topic_id, info.topic_name, typename, info.md5sum, info.buffer_size)
                self._refused.pop(info.topic_id, None)
                if publisher:
                    for stale in [i for i, e in self._publishers.items() if e.topic_name == info.topic_name]:
                        del self._publishers[stale]
                    self._publishers[info.topic_id] = endpoint
                else:
                    self._device_subscribers[topic_key(info.topic_name)] = endpoint
                self.counters[f"{side}s_learned"] += 1
        if reason is not None:
            self.warn.warning(
                f"refused {info.topic_name}",
                f"{self._where}: {side} {info.topic_name} [{info.message_type}] refused ({reason}, md5 {info.md5sum})",
            )
        else:
            log.info(
                "%s: %s %s [%s] on topic id %d", self._where, side, info.topic_name, info.message_type, info.topic_id
            )

    def _publication(self, packet: rp.Packet, received: float) -> None:
        with self._lock:
            endpoint = self._publishers.get(packet.topic_id)
            refused = packet.topic_id in self._refused
        if endpoint is None:
            if refused:
                self._count("refused_topic_messages")
            else:
                self._count("unknown_topic_messages")
                self.warn.warning(
                    "unknown", f"{self._where}: a publication on topic id {packet.topic_id} before its TopicInfo"
                )
                self._request_topics(force=False)
            return
        message = self._decode(packet.payload, endpoint.typename)
        if message is None:
            return
        key = topic_key(endpoint.topic_name)
        with self._lock:
            self.counters["messages"] += 1
            self._latest[key] = (message, received)
            callbacks = list(self._subscribers.get(key, ()))
        for callback in callbacks:
            try:
                callback(message, received)
            except Exception as exc:
                self._count("subscriber_errors")
                self.warn.warning("subscriber", f"{self._where}: a subscriber of {endpoint.topic_name} failed: {exc!r}")

    def _time_request(self) -> None:
        reply = rp.encode_packet(rp.ID_TIME, rp.serialize(rp.time_message(self.clock()), self.store))
        with self._lock:
            self.counters["time_requests"] += 1
            self._last_sync = self.monotonic()
        if self.link.send(reply):
            self._count("time_replies")

    def _device_log(self, payload: bytes) -> None:
        message = self._decode(payload, rp.LOG)
        if message is None:
            return
        device_log.log(LOG_LEVELS.get(message.level, logging.ERROR), "%s: %s", self._where, message.msg)
        self._count("device_logs")

    def _parameter_request(self, payload: bytes) -> None:
        request = self._decode(payload, rp.PARAM_REQUEST)
        if request is None:
            return
        value = self.params.get(request.name)
        values = value if isinstance(value, list | tuple) else [value]
        kinds = {float if isinstance(v, float) else str if isinstance(v, str) else int for v in values}
        usable = value is not None and len(kinds) == 1 and all(isinstance(v, bool | int | float | str) for v in values)
        if not usable:
            self._count("parameters_missing")
            self.warn.warning(
                "parameter", f"{self._where}: parameter {request.name} is not set (or not ints, floats or strings)"
            )
            return
        response = rp.param_response(list(values))
        if self.link.send(rp.encode_packet(rp.ID_PARAMETER_REQUEST, rp.serialize(response, self.store))):
            self._count("parameters_sent")

    # -- the keeper thread: re-requests topics while unanswered or out of sync ------------------

    def _request_topics(self, *, force: bool) -> bool:
        now = self.monotonic()
        with self._lock:
            if not force and now - self._last_request < self.request_interval_s:
                return False
            self._last_request = now
            self.counters["topic_requests"] += 1
        return self.link.send(rp.TOPIC_REQUEST)

    def _keep(self) -> None:
        tick = max(0.005, min(0.1, self.request_interval_s / 4, self.sync_timeout_s / 4))
        while not self._stop.wait(tick):
            self._keep_once()
            with self._changed:
                self.keeps += 1
                self._changed.notify_all()

    def _keep_once(self) -> None:
        version_errors = self.decoder.bad["protocol_version"]
        if version_errors > self._version_errors:
            self._version_errors = version_errors
            self.warn.warning(
                "version",
                f"{self._where}: packets of another rosserial protocol version (0xff: groovy, rosserial 0.4 "
                "and earlier); this host speaks hydro's 0xfe: rebuild the device with a newer ros_lib",
            )
        if not self.link.connected:
            return
        now = self.monotonic()
        with self._lock:
            unanswered = not self._announced and now - self._last_request >= self.request_interval_s
            lost = self._announced and now - self._last_sync >= self.sync_timeout_s
            if lost:
                self.counters["sync_lost"] += 1
                self._last_sync = now
        if lost:
            self.warn.warning("sync", f"{self._where}: no time request for {self.sync_timeout_s:g} s; lost sync")
        if unanswered or lost:
            self._request_topics(force=True)
