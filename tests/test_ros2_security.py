"""Security of botstage's Zenoh sessions: certificates, mutual TLS, access control, loopback listening, no secrets out.

Everything runs real eclipse-zenoh sessions on loopback (127.0.0.1, free ports, no multicast
scouting) with certificates made in tmp_path by robots.ros2.certs. A failed connection is
``zenoh.open`` raising (``connect/timeout_ms: 0``: one attempt, no retry). That something did not
arrive is shown by order, not by waiting: a peer puts the forbidden sample, then a marker on an
open topic over the same link (Zenoh keeps a link's order within a priority); when the marker is
in, the forbidden sample would have been. Other waits are on queues and events with failsafe
timeouts.
"""

from __future__ import annotations

import datetime
import itertools
import os
import queue
import re
import socket
import stat
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import typer
import zenoh
from cryptography import x509
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID
from typer.testing import CliRunner

from botstage.missions.cli.certs import certs as certs_command
from botstage.robots.ros2 import certs, types
from botstage.robots.ros2.attachment import Attachment, encode
from botstage.robots.ros2.liveliness import graph_key, parse_token
from botstage.robots.ros2.node import DEFAULT_LISTEN, ROUTER_LISTEN, Ros2Node
from botstage.robots.ros2.security import (
    ACCESS_CONTROL,
    REDACTED,
    AccessPolicy,
    ListenError,
    access_control,
    check_listen,
    describe,
    is_loopback,
    redacted,
    security_options,
    tls_options,
)
from botstage.robots.ros2.service import ServiceUnavailable

ROOT = Path(__file__).resolve().parent.parent
FIVE = ROOT / "missions" / "deployments" / "peoplebot_five_computers.yaml"
FAILSAFE_S = 30.0
TWIST = "geometry_msgs/msg/Twist"
STRING = "std_msgs/msg/String"
TRIGGER = "std_srvs/srv/Trigger"
ONE_ATTEMPT = {"connect/timeout_ms": 0, "connect/exit_on_failure": True}  # a refused peer: open raises at once
PROCESSES = ["robot", "mission", "intruder"]  # "stranger" has a certificate of the authority, unknown to the policy
POLICY = AccessPolicy(PROCESSES, publishers={"cmd_vel": ["mission"]}, callers={"/robot/skill_tick": ["mission"]})


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@pytest.fixture(scope="module")
def pki(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One authority with the three processes and a stranger, and another authority with its own 'mission'."""
    folder = tmp_path_factory.mktemp("pki")
    certs.make_certificates(folder / "ours", [*PROCESSES, "stranger"])
    certs.make_certificates(folder / "theirs", ["mission"])
    return folder


def creds(pki: Path, who: str) -> certs.Credentials:
    return certs.Credentials.in_folder(pki / "ours" / who)


def secured(pki: Path, who: str, policy: AccessPolicy | None = None, **extra: Any) -> dict[str, Any]:
    return {**security_options(creds(pki, who), policy), **ONE_ATTEMPT, **extra}


def listening(name: str, options: dict[str, Any], host: str = "127.0.0.1", **kwargs: Any) -> tuple[Ros2Node, str]:
    """A node listening with TLS on a free loopback port, and its endpoint."""
    for _ in range(5):
        endpoint = f"tls/{host}:{free_port()}"
        try:
            return Ros2Node(name, listen=[endpoint], options=options, **kwargs), endpoint
        except zenoh.ZError as error:
            if "in use" not in str(error):
                raise
    raise RuntimeError("no free loopback port after 5 tries")


@pytest.fixture
def closing() -> Iterator[list[Ros2Node]]:
    """Nodes to close at the end of a test, whatever happened."""
    nodes: list[Ros2Node] = []
    yield nodes
    for node in reversed(nodes):
        node.close()


_EXCHANGES = itertools.count()


def exchanges(listener: Ros2Node, talker: Ros2Node) -> bool:
    """Whether a String published by ``talker`` reaches ``listener`` (failsafe-bounded).

    Each exchange has a topic of its own: a subscriber left by an earlier one in the talker's own
    process would match the publisher before the listener's subscriber is known there.
    """
    got: queue.Queue[str] = queue.Queue()
    topic = f"/hello_{next(_EXCHANGES)}"
    listener.subscription(topic, STRING, lambda message, _: got.put(message.data))
    publisher = talker.publisher(topic, STRING)
    wait_matching(talker.session, publisher.key)
    publisher.publish(types.message_class(STRING)(data="hi"))
    return got.get(timeout=FAILSAFE_S) == "hi"


def wait_matching(session: zenoh.Session, key: str) -> None:
    """Until ``session`` knows a subscriber of ``key`` (its puts have a route), failsafe-bounded."""
    matched = threading.Event()
    probe = session.declare_publisher(key)
    listener = probe.declare_matching_listener(lambda status: status.matching and matched.set())
    try:
        if not probe.matching_status.matching:
            assert matched.wait(FAILSAFE_S), f"no subscriber of {key} became known"
    finally:
        listener.undeclare()
        probe.undeclare()


# -- certificates -------------------------------------------------------------------------------


def test_certificates_are_what_rustls_needs(tmp_path: Path) -> None:
    written = certs.make_certificates(tmp_path, ["robot_computer"], {"robot_computer": ["robot.local", "10.0.0.7"]})
    ca = x509.load_pem_x509_certificate((tmp_path / certs.CA_CERT).read_bytes())
    files = written.processes["robot_computer"]
    cert = x509.load_pem_x509_certificate(files.cert.read_bytes())
    cert.verify_directly_issued_by(ca)
    assert certs.common_name(cert) == "robot_computer"
    assert cert.version is x509.Version.v3 and isinstance(cert.public_key(), ec.EllipticCurvePublicKey)
    assert ca.extensions.get_extension_for_class(x509.BasicConstraints).value.ca is True
    assert cert.extensions.get_extension_for_class(x509.BasicConstraints).value.ca is False
    usages = cert.extensions.get_extension_for_class(x509.ExtendedKeyUsage).value
    assert set(usages) == {ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH}
    names = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    assert names.get_values_for_type(x509.DNSName) == ["localhost", "robot.local"]
    assert [str(ip) for ip in names.get_values_for_type(x509.IPAddress)] == ["127.0.0.1", "::1", "10.0.0.7"]
    assert cert.not_valid_after_utc <= ca.not_valid_after_utc
    assert files.ca.read_bytes() == (tmp_path / certs.CA_CERT).read_bytes()
    for key in (tmp_path / certs.CA_KEY, files.key):
        assert stat.S_IMODE(key.stat().st_mode) == 0o600, key
        assert key.read_bytes().startswith(b"-----BEGIN PRIVATE KEY-----")  # PKCS#8
    assert stat.S_IMODE(files.cert.stat().st_mode) == 0o644


def test_an_existing_authority_is_kept_unless_a_new_one_is_asked_for(tmp_path: Path) -> None:
    first = certs.make_certificates(tmp_path, ["robot"])
    ca = (tmp_path / certs.CA_CERT).read_bytes()
    second = certs.make_certificates(tmp_path, ["mission"])
    assert first.authority_created and not second.authority_created
    assert (tmp_path / certs.CA_CERT).read_bytes() == ca
    robot = x509.load_pem_x509_certificate((tmp_path / "robot" / certs.PROCESS_CERT).read_bytes())
    mission = x509.load_pem_x509_certificate((tmp_path / "mission" / certs.PROCESS_CERT).read_bytes())
    mission.verify_directly_issued_by(x509.load_pem_x509_certificate(ca))
    assert robot.issuer == mission.issuer
    assert certs.make_certificates(tmp_path, ["mission"], new_ca=True).authority_created
    assert (tmp_path / certs.CA_CERT).read_bytes() != ca


def test_an_authority_whose_key_is_not_its_own_is_refused(tmp_path: Path) -> None:
    certs.make_certificates(tmp_path / "a", ["robot"])
    certs.make_certificates(tmp_path / "b", ["robot"])
    (tmp_path / "a" / certs.CA_KEY).write_bytes((tmp_path / "b" / certs.CA_KEY).read_bytes())
    with pytest.raises(certs.CertificateError, match="is not the key of"):
        certs.make_certificates(tmp_path / "a", ["mission"])


@pytest.mark.parametrize("host", ["bad host", "-x.local", "a..b", ""])
def test_a_host_that_is_no_name_nor_address_is_refused(host: str) -> None:
    with pytest.raises(certs.CertificateError, match="neither an IP address nor a DNS name"):
        certs.subject_alternative_names([host])


def test_a_certificate_outlives_neither_its_days_nor_its_authority() -> None:
    now = datetime.datetime(2030, 1, 1, tzinfo=datetime.UTC)
    authority = certs.new_authority(days=10, now=now)
    _, cert = certs.issue(authority, "robot", days=365, now=now)
    assert cert.not_valid_after_utc == authority.expires
    _, short = certs.issue(authority, "robot", days=2, now=now)
    assert short.not_valid_after_utc == now + datetime.timedelta(days=2)
    with pytest.raises(ValueError, match="node name"):
        certs.issue(authority, "../robot")


# -- the command --------------------------------------------------------------------------------


@pytest.fixture
def run_certs() -> Any:
    app = typer.Typer()
    app.command()(certs_command)
    runner = CliRunner()
    return lambda *args: runner.invoke(app, [str(arg) for arg in args])


def secrets_of(folder: Path) -> list[str]:
    """The body lines of every private key under ``folder``: none may ever be printed."""
    return [
        line
        for key in folder.rglob("*")
        if key.name in (certs.CA_KEY, certs.PROCESS_KEY)
        for line in key.read_text().splitlines()
        if not line.startswith("-----")
    ]


def test_botstage_certs_writes_the_files_and_prints_no_secret(tmp_path: Path, run_certs: Any) -> None:
    out = tmp_path / "certs"
    result = run_certs(out, "--process", "robot", "--process", "mission", "--host", "robot.local", "--days", "30")
    assert result.exit_code == 0, result.output
    assert "certificate authority" in result.output and "(made;" in result.output
    for who in ("robot", "mission"):
        files = certs.Credentials.in_folder(out / who)
        assert not files.missing()
        assert stat.S_IMODE(files.key.stat().st_mode) == 0o600
        assert f"{who}: {out / who}/" in result.output
        cert = x509.load_pem_x509_certificate(files.cert.read_bytes())
        names = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
        assert "robot.local" in names.get_values_for_type(x509.DNSName)
        assert cert.not_valid_after_utc - cert.not_valid_before_utc < datetime.timedelta(days=31)
    assert stat.S_IMODE((out / certs.CA_KEY).stat().st_mode) == 0o600
    assert "PRIVATE KEY" not in result.output
    assert not [line for line in secrets_of(out) if line in result.output]

    ca = (out / certs.CA_CERT).read_bytes()
    again = run_certs(out, "--process", "display")
    assert again.exit_code == 0 and "(kept;" in again.output
    assert (out / certs.CA_CERT).read_bytes() == ca
    renewed = run_certs(out, "--process", "display", "--new-ca")
    assert renewed.exit_code == 0 and "(made;" in renewed.output
    assert (out / certs.CA_CERT).read_bytes() != ca


def test_botstage_certs_takes_a_deployments_processes(tmp_path: Path, run_certs: Any) -> None:
    result = run_certs(tmp_path, "--deployment", FIVE)
    assert result.exit_code == 0, result.output
    expected = {
        "robot_computer",
        "navigation_computer",
        "kinect_speech_computer",
        "upload_computer",
        "display_computer",
        "operator",  # teleop's identity, which the deployment's policy lets drive the robot
    }
    assert {path.name for path in tmp_path.iterdir() if path.is_dir()} == expected
    assert "operator: " in result.output and "(teleop's" in result.output


@pytest.mark.parametrize(
    ("args", "says"),
    [
        ((), "name at least one process"),
        (("--process", "1robot"), "must not start with a digit"),
        (("--process", "robot", "--host", "bad host"), "neither an IP address nor a DNS name"),
        (("--process", "robot", "--days", "0"), "greater than or equal to 1"),
    ],
)
def test_botstage_certs_usage_errors(tmp_path: Path, run_certs: Any, args: tuple[str, ...], says: str) -> None:
    result = run_certs(tmp_path / "out", *args)
    assert result.exit_code == 2
    assert says in " ".join(re.sub("[│╭╮╰╯─]", " ", result.output).split())  # typer's box wraps the message
    assert not (tmp_path / "out" / certs.CA_KEY).exists()


def test_botstage_certs_refuses_a_broken_authority_without_quoting_it(tmp_path: Path, run_certs: Any) -> None:
    assert run_certs(tmp_path, "--process", "robot").exit_code == 0
    (tmp_path / certs.CA_KEY).write_text(
        "-----BEGIN PRIVATE KEY-----\nc2VjcmV0IGJ1dCBicm9rZW4=\n-----END PRIVATE KEY-----\n"
    )
    result = run_certs(tmp_path, "--process", "mission")
    assert result.exit_code == 1
    assert "not a PEM certificate and unencrypted key" in result.output
    assert "c2VjcmV0" not in result.output


# -- mutual TLS ---------------------------------------------------------------------------------


def test_a_peer_with_a_certificate_of_the_authority_connects_and_exchanges(pki: Path, closing: list) -> None:
    robot, endpoint = listening("robot", secured(pki, "robot"))
    closing.append(robot)
    mission = Ros2Node("mission", listen=[], connect=[endpoint], options=secured(pki, "mission"))
    closing.append(mission)
    assert exchanges(robot, mission)
    assert exchanges(mission, robot)


def _impostor(pki: Path, tmp_path: Path, kind: str) -> dict[str, Any]:
    """TLS options of a peer that trusts our authority but has no valid certificate of its own."""
    ours = creds(pki, "mission")
    if kind == "no certificate":
        options = tls_options(ours)
        for side in ("connect", "listen"):
            del options[f"transport/link/tls/{side}_certificate"], options[f"transport/link/tls/{side}_private_key"]
        return {**options, **ONE_ATTEMPT}
    if kind == "self-signed":
        own = certs.new_authority("mission")  # a self-signed certificate named as a process
        key, cert = own.key, own.cert
    else:  # signed by another authority
        theirs = certs.Credentials.in_folder(pki / "theirs" / "mission")
        return {**tls_options(certs.Credentials(ours.ca, theirs.cert, theirs.key)), **ONE_ATTEMPT}
    certs.write_private_key(tmp_path / "key.pem", key)
    certs.write_certificate(tmp_path / "cert.pem", cert)
    return {**tls_options(certs.Credentials(ours.ca, tmp_path / "cert.pem", tmp_path / "key.pem")), **ONE_ATTEMPT}


@pytest.mark.parametrize("kind", ["no certificate", "self-signed", "another authority"])
def test_a_peer_without_a_valid_certificate_cannot_connect(pki: Path, tmp_path: Path, closing: list, kind: str) -> None:
    robot, endpoint = listening("robot", secured(pki, "robot"))
    closing.append(robot)
    with pytest.raises(zenoh.ZError):
        Ros2Node("impostor", listen=[], connect=[endpoint], options=_impostor(pki, tmp_path, kind))
    assert list(robot.session.info.peers_zid()) == []
    mission = Ros2Node("mission", listen=[], connect=[endpoint], options=secured(pki, "mission"))
    closing.append(mission)  # the listener still takes a valid peer after refusing one
    assert [str(zid) for zid in robot.session.info.peers_zid()] == [mission.zid]


def test_a_plain_tcp_peer_cannot_connect_to_a_secured_process(pki: Path, closing: list) -> None:
    robot, endpoint = listening("robot", secured(pki, "robot"))
    closing.append(robot)
    with pytest.raises(zenoh.ZError):
        Ros2Node("plain", listen=[], connect=[endpoint.replace("tls/", "tcp/")], options=ONE_ATTEMPT)
    with pytest.raises(zenoh.ZError, match="Unsupported protocol: tcp"):  # nor listen on a plain side door
        Ros2Node("robot2", listen=[DEFAULT_LISTEN], options=secured(pki, "robot"))


def test_a_process_does_not_connect_to_an_impostor_listener(pki: Path, tmp_path: Path, closing: list) -> None:
    impostor, endpoint = listening("impostor", _impostor(pki, tmp_path, "another authority"))
    closing.append(impostor)
    with pytest.raises(zenoh.ZError):
        Ros2Node("mission", listen=[], connect=[endpoint], options=secured(pki, "mission"))


def test_the_listener_must_be_named_in_its_certificate_unless_asked(pki: Path, closing: list) -> None:
    """verify_name_on_connect: 127.0.0.2 (loopback, but not in the certificate's names) is refused."""
    try:
        robot, endpoint = listening("robot", secured(pki, "robot"), host="127.0.0.2")
    except zenoh.ZError as error:
        pytest.skip(f"127.0.0.2 cannot be listened on here: {error}")
    closing.append(robot)
    with pytest.raises(zenoh.ZError):
        Ros2Node("mission", listen=[], connect=[endpoint], options=secured(pki, "mission"))
    options = {**security_options(creds(pki, "mission"), None, verify_name=False), **ONE_ATTEMPT}
    mission = Ros2Node("mission", listen=[], connect=[endpoint], options=options)
    closing.append(mission)
    assert exchanges(robot, mission)


# -- access control -----------------------------------------------------------------------------


def test_the_policy_protects_what_it_lists_and_nothing_else() -> None:
    acl = access_control(POLICY)
    assert acl["enabled"] is True and acl["default_permission"] == "deny"
    keys = {rule["id"]: rule["key_exprs"] for rule in acl["rules"]}
    assert keys["only listed processes publish /cmd_vel"] == ["0/cmd_vel/**"]
    assert keys["only listed processes call /robot/skill_tick"] == ["0/robot/skill_tick/**"]
    assert set(keys["processes may do everything"]) == {"**", "@ros2_lv/**", "**/@adv/**"}
    subjects = {subject["id"]: subject["cert_common_names"] for subject in acl["subjects"]}
    assert subjects == {
        "processes": PROCESSES,
        "may not publish /cmd_vel": ["robot", "intruder"],
        "may not call /robot/skill_tick": ["robot", "intruder"],
    }
    # the keys cover rmw_zenoh's data keys of the topic and of nothing else
    twist = "0/cmd_vel/geometry_msgs::msg::dds_::Twist_/" + types.type_hash(TWIST)
    assert zenoh.KeyExpr("0/cmd_vel/**").includes(zenoh.KeyExpr(twist))
    assert not zenoh.KeyExpr("0/cmd_vel/**").includes(zenoh.KeyExpr(twist.replace("cmd_vel", "odom")))
    # a router forwards what others publish: it is closed to nothing; a domain moves the keys
    routed = access_control(AccessPolicy(PROCESSES, {"cmd_vel": ["mission"]}, forwarders=["robot"], domain_id=7))
    assert {s["id"]: s["cert_common_names"] for s in routed["subjects"]}["may not publish /cmd_vel"] == ["intruder"]
    assert "7/cmd_vel/**" in str(routed["rules"])


@pytest.mark.parametrize(
    ("policy", "says"),
    [
        (lambda: AccessPolicy([]), "at least one process"),
        (lambda: AccessPolicy(["robot"], publishers={"cmd_vel": ["misssion"]}), "'misssion' may publish"),
        (lambda: AccessPolicy(["robot"], callers={"bad name!": ["robot"]}), "not allowed"),
        (lambda: AccessPolicy(["robot"], forwarders=["router"]), "forwarder 'router'"),
        (lambda: AccessPolicy(["robot"], domain_id=-1), "domain id"),
    ],
)
def test_a_policy_naming_what_is_not_there_is_refused(policy: Any, says: str) -> None:
    with pytest.raises(ValueError, match=says):
        policy()


def _ingress_only(options: dict[str, Any]) -> dict[str, Any]:
    """The policy without its hidden declarations: the robot's ingress filter alone must hold."""
    acl = options[ACCESS_CONTROL]
    hidden = {rule["id"] for rule in acl["rules"] if rule["flows"] == ["egress"] and rule["permission"] == "deny"}
    assert hidden
    rules = [rule for rule in acl["rules"] if rule["id"] not in hidden]
    policies = [{**p, "rules": [r for r in p["rules"] if r not in hidden]} for p in acl["policies"]]
    return {**options, ACCESS_CONTROL: {**acl, "rules": rules, "policies": policies}}


class Robot:
    """A robot process: cmd_vel and an open topic received into queues, a protected service counting calls."""

    def __init__(self, pki: Path, closing: list, shape: Any = lambda options: options) -> None:
        self.node, self.endpoint = listening("robot", shape(secured(pki, "robot", POLICY)))
        closing.append(self.node)
        self.cmd_vel: queue.Queue[Any] = queue.Queue()
        self.chatter: queue.Queue[str] = queue.Queue()
        self.calls = 0
        self.node.subscription("/cmd_vel", TWIST, lambda message, _: self.cmd_vel.put(message))
        self.node.subscription("/chatter", STRING, lambda message, _: self.chatter.put(message.data))
        self.node.service("/robot/skill_tick", TRIGGER, self._serve)
        self.shape = shape

    def _serve(self, _: Any) -> Any:
        self.calls += 1
        return types.message_class(f"{TRIGGER}_Response")(success=True, message="ticked")

    def join(self, pki: Path, closing: list, who: str) -> Ros2Node:
        """A process connecting to the robot; its session has the robot's declarations once open."""
        node = Ros2Node(who, listen=[], connect=[self.endpoint], options=self.shape(secured(pki, who, POLICY)))
        closing.append(node)
        return node

    def marker(self, node: Ros2Node, text: str) -> None:
        """Put ``text`` on the open topic and wait for it: whatever ``node`` put before has arrived by then."""
        publisher = node.publisher("/chatter", STRING)
        wait_matching(node.session, publisher.key)
        publisher.publish(types.message_class(STRING)(data=text))
        assert self.chatter.get(timeout=FAILSAFE_S) == text


def twist(x: float) -> Any:
    Twist, Vector3 = types.message_class(TWIST), types.message_class("geometry_msgs/msg/Vector3")
    return Twist(linear=Vector3(x=x, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=0.0))


@pytest.mark.parametrize("shape", [lambda options: options, _ingress_only], ids=["policy", "ingress filter alone"])
def test_a_process_not_listed_for_cmd_vel_cannot_move_the_robot(pki: Path, closing: list, shape: Any) -> None:
    robot = Robot(pki, closing, shape)
    intruder = robot.join(pki, closing, "intruder")
    intruder.publisher("/cmd_vel", TWIST).publish(twist(9.0))
    robot.marker(intruder, "after the intruder's cmd_vel")
    assert robot.cmd_vel.empty()

    mission = robot.join(pki, closing, "mission")
    drive = mission.publisher("/cmd_vel", TWIST)
    wait_matching(mission.session, drive.key)
    drive.publish(twist(0.5))
    assert robot.cmd_vel.get(timeout=FAILSAFE_S).linear.x == 0.5


@pytest.mark.parametrize("shape", [lambda options: options, _ingress_only], ids=["policy", "ingress filter alone"])
def test_a_wildcard_put_of_an_unlisted_process_does_not_move_the_robot(pki: Path, closing: list, shape: Any) -> None:
    robot = Robot(pki, closing, shape)
    intruder = robot.join(pki, closing, "intruder")
    wait_matching(intruder.session, intruder.publisher("/chatter", STRING).key)  # a route to the robot for 0/**
    _wildcard_put(intruder)
    robot.marker(intruder, "after the intruder's wildcard put")
    assert robot.cmd_vel.empty()


def _wildcard_put(node: Ros2Node) -> None:
    """A well-formed Twist with a valid attachment, put on a wildcard key that covers every topic."""
    publisher = node.session.declare_publisher("0/**", reliability=zenoh.Reliability.RELIABLE)  # as the marker's
    publisher.put(types.serialize(twist(9.0), TWIST), attachment=encode(Attachment(1, 1, bytes(16))))
    publisher.undeclare()


@pytest.mark.parametrize("shape", [lambda options: options, _ingress_only], ids=["policy", "ingress filter alone"])
def test_only_a_listed_process_calls_a_protected_service(pki: Path, closing: list, shape: Any) -> None:
    robot = Robot(pki, closing, shape)
    intruder = robot.join(pki, closing, "intruder")
    Request = types.message_class(f"{TRIGGER}_Request")
    with pytest.raises(ServiceUnavailable):
        intruder.client("/robot/skill_tick", TRIGGER).call(Request(), timeout=FAILSAFE_S)
    assert robot.calls == 0
    mission = robot.join(pki, closing, "mission")
    assert mission.client("/robot/skill_tick", TRIGGER).call(Request(), timeout=FAILSAFE_S).message == "ticked"
    assert robot.calls == 1


def test_a_wildcard_query_of_an_unlisted_process_does_not_call_a_protected_service(pki: Path, closing: list) -> None:
    robot = Robot(pki, closing)
    Response = types.message_class(f"{TRIGGER}_Response")
    robot.node.service("/robot/describe", TRIGGER, lambda _: Response(success=True, message="open"))
    intruder = robot.join(pki, closing, "intruder")
    request = types.serialize(types.message_class(f"{TRIGGER}_Request")(), f"{TRIGGER}_Request")
    replies = intruder.session.get(
        "0/**", payload=request, attachment=encode(Attachment(1, 1, bytes(16))), timeout=FAILSAFE_S
    )
    list(replies)  # to the query's end: every queryable it reached has answered or dropped it
    assert robot.calls == 0


def test_the_ros_graph_still_sees_every_listed_process(pki: Path, closing: list) -> None:
    """Liveliness tokens (``@ros2_lv``, which ``**`` does not cover) pass: ros2 node list works under the policy."""
    robot = Robot(pki, closing)
    seen: queue.Queue[str] = queue.Queue()
    robot.node.session.liveliness().declare_subscriber(
        graph_key(0), lambda sample: seen.put(str(sample.key_expr)), history=True
    )
    intruder = robot.join(pki, closing, "intruder")
    intruder.publisher("/cmd_vel", TWIST)
    kinds = set()
    while ("intruder", "MP") not in kinds:
        token = parse_token(seen.get(timeout=FAILSAFE_S))
        kinds.add((token.node_name, token.kind.value))
    assert ("intruder", "NN") in kinds


def test_an_identity_the_policy_does_not_name_gets_nothing(pki: Path, closing: list) -> None:
    """A certificate of the authority for a process the deployment does not have: default deny."""
    robot = Robot(pki, closing)
    stranger = robot.join(pki, closing, "stranger")
    Request = types.message_class(f"{TRIGGER}_Request")
    assert not stranger.session.declare_publisher(stranger.publisher("/chatter", STRING).key).matching_status.matching
    with pytest.raises(ServiceUnavailable):
        stranger.client("/robot/skill_tick", TRIGGER).call(Request(), timeout=FAILSAFE_S)
    assert robot.calls == 0


# -- listening ----------------------------------------------------------------------------------


def _own_sockets() -> set[tuple[str, str, int]]:
    """(protocol, local address, port) of this process's listening TCP and bound UDP sockets, from /proc."""
    inodes = set()
    for fd in os.listdir("/proc/self/fd"):
        try:
            target = os.readlink(f"/proc/self/fd/{fd}")
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    found = set()
    for table, listening_state in (("tcp", "0A"), ("tcp6", "0A"), ("udp", None), ("udp6", None)):
        path = Path(f"/proc/self/net/{table}")
        if not path.exists():
            continue
        for line in path.read_text().splitlines()[1:]:
            fields = line.split()
            if fields[9] not in inodes or (listening_state and fields[3] != listening_state):
                continue
            address, port = fields[1].split(":")
            found.add((table, _proc_address(address), int(port, 16)))
    return found


def _proc_address(hexed: str) -> str:
    raw = bytes.fromhex(hexed)
    # /proc/net stores addresses as host-order 32-bit words
    words = b"".join(raw[i : i + 4][::-1] for i in range(0, len(raw), 4))
    return socket.inet_ntop(socket.AF_INET if len(raw) == 4 else socket.AF_INET6, words)


def _loopback(address: str) -> bool:
    return address in ("::1",) or address.startswith("127.") or address.startswith("::ffff:127.")


@pytest.mark.skipif(not Path("/proc/self/net/tcp").exists(), reason="needs Linux's /proc")
@pytest.mark.parametrize("mode", ["peer", "router"])
@pytest.mark.parametrize("secure", [False, True], ids=["tcp", "tls"])
def test_default_sessions_listen_on_loopback_only(pki: Path, mode: str, secure: bool) -> None:
    before = _own_sockets()
    if secure:
        node, _ = listening("robot", secured(pki, "robot", POLICY), mode=mode)
    else:
        node = Ros2Node("robot", mode=mode)  # node.py's default listen endpoint
    try:
        opened = _own_sockets() - before
    finally:
        node.close()
    assert opened, "the session opened no listening socket"
    assert all(_loopback(address) for _, address, _ in opened), opened


def test_node_defaults_pass_the_listen_policy() -> None:
    assert check_listen([DEFAULT_LISTEN, ROUTER_LISTEN, "tls/localhost:7447", "tcp/[::1]:0", "unixsock-stream/x"])


@pytest.mark.parametrize(
    "endpoint",
    ["tcp/0.0.0.0:7447", "tcp/[::]:0", "tls/192.168.1.10:7447", "tcp/robot.local:7447", "udp/10.0.0.1:7447#iface=eth0"],
)
def test_anything_wider_than_loopback_must_be_asked_for_and_authenticated(pki: Path, endpoint: str) -> None:
    assert not is_loopback(endpoint)
    with pytest.raises(ListenError, match=r"beyond this machine .*is not loopback"):
        check_listen([DEFAULT_LISTEN, endpoint])
    with pytest.raises(ListenError, match="must be tls/"):  # asked for, but not authenticated
        check_listen([endpoint], allow_remote=True)
    secure = endpoint.replace(endpoint.split("/", 1)[0], "tls", 1)
    with pytest.raises(ListenError, match="must be tls/"):
        check_listen(
            [secure], tls_options(creds(pki, "robot")) | {"transport/link/tls/enable_mtls": False}, allow_remote=True
        )
    assert check_listen([secure], tls_options(creds(pki, "robot")), allow_remote=True) == [secure]


@pytest.mark.parametrize("endpoint", ["tcp", "tcp/", "/127.0.0.1:1", "tcp/:7447"])
def test_an_endpoint_that_is_none_is_refused(endpoint: str) -> None:
    with pytest.raises(ListenError):
        check_listen([endpoint])


# -- nothing secret out -------------------------------------------------------------------------


def test_key_material_travels_by_path_and_logs_redact_even_that(pki: Path) -> None:
    options = security_options(creds(pki, "robot"), POLICY)
    for path, value in options.items():
        assert "BEGIN" not in str(value), path
    assert Path(options["transport/link/tls/listen_private_key"]).resolve() == creds(pki, "robot").key.resolve()
    shown = redacted({**options, "transport": {"auth": {"usrpwd": {"user": "u", "password": "p4ss"}}}})
    assert shown["transport/link/tls/listen_private_key"] == shown["transport/link/tls/connect_private_key"] == REDACTED
    assert shown["transport"]["auth"]["usrpwd"] == {"user": "u", "password": REDACTED}
    assert shown["transport/link/tls/listen_certificate"] == options["transport/link/tls/listen_certificate"]
    assert "key.pem" not in describe(options) and "p4ss" not in describe(shown)


LOGGING_CHILD = """
import json, logging, sys
import zenoh
from botstage.robots.ros2 import certs
from botstage.robots.ros2.node import Ros2Node, session_config
from botstage.robots.ros2.security import AccessPolicy, describe, security_options
zenoh.init_log_from_env_or("debug")
logging.basicConfig(level=logging.DEBUG)
folder, endpoint, theirs = sys.argv[1], sys.argv[2], sys.argv[3]
policy = AccessPolicy(["robot", "mission"], publishers={"cmd_vel": ["mission"]})
one = {"connect/timeout_ms": 0, "connect/exit_on_failure": True}
robot_options = security_options(certs.Credentials.in_folder(f"{folder}/robot"), policy)
logging.getLogger("botstage").info("robot options %s", describe(robot_options))
robot = Ros2Node("robot", listen=[endpoint], options=robot_options)
mission = Ros2Node("mission", listen=[], connect=[endpoint], options={**robot_options, **one})
try:
    impostor = security_options(certs.Credentials.in_folder(theirs))
    Ros2Node("impostor", listen=[], connect=[endpoint], options={**impostor, **one})
except Exception as error:
    print("refused:", error)
print("config:", session_config([endpoint], options=robot_options))
mission.close()
robot.close()
"""


def test_no_key_material_in_zenoh_debug_logs_or_config_dumps(pki: Path) -> None:
    """A secured pair and a refused impostor with Zenoh's and Python's logs at debug: no key line anywhere."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("ZENOH_", "RUST_LOG"))}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    endpoint = f"tls/127.0.0.1:{free_port()}"
    args = [str(pki / "ours"), endpoint, str(pki / "theirs" / "mission")]
    done = subprocess.run(
        [sys.executable, "-c", LOGGING_CHILD, *args], capture_output=True, text=True, env=env, timeout=120, cwd=ROOT
    )
    out = done.stdout + done.stderr
    assert done.returncode == 0, out[-3000:]
    assert "refused:" in done.stdout and "config:" in done.stdout and "robot options" in done.stderr
    assert re.search(r"DEBUG.*zenoh", out)  # the logs really were at debug (Zenoh writes them to stdout)
    assert "PRIVATE KEY" not in out
    leaked = [line for line in secrets_of(pki) if line in out]
    assert not leaked
