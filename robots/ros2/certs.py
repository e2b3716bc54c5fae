"""Certificates for Zenoh's TLS with mutual authentication: a certificate authority and one certificate per process.

Every process of a deployment proves who it is with a certificate signed by the deployment's own
authority; its common name is the process name, which Zenoh's access control matches
(``cert_common_names``). The files are what Zenoh's TLS link (rustls and webpki) accepts, as
checked by running eclipse-zenoh 1.10: PEM certificates (X.509 v3), PEM PKCS#8 private keys on
the NIST P-256 curve (ECDSA with SHA-256; rustls takes Ed25519 too, P-256 is what every TLS stack
and SROS2 use). The authority has ``basicConstraints CA`` and may only sign certificates; a process
certificate is an end entity for both TLS roles (``serverAuth`` and ``clientAuth``: every process
listens and connects) with its hosts as subject alternative names, which webpki checks when a peer
connects (it ignores the common name).

Layout of a certificate folder (``botstage certs``)::

    ca.pem, ca.key           the authority (keep ca.key off the robots: it makes new identities)
    <process>/ca.pem         a copy of the authority's certificate
    <process>/cert.pem       the process's certificate
    <process>/key.pem        its private key

so a process's folder is all a machine needs. Private keys are written 0600 and never printed.
"""

from __future__ import annotations

import datetime
import ipaddress
import os
import re
import tempfile
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

from botstage.robots.ros2.names import validate_node_name

CA_CERT = "ca.pem"
CA_KEY = "ca.key"
PROCESS_CA = "ca.pem"
PROCESS_CERT = "cert.pem"
PROCESS_KEY = "key.pem"
DEFAULT_HOSTS = ("localhost", "127.0.0.1", "::1")  # loopback: every process's default listen address
CA_NAME = "botstage deployment CA"
CA_DAYS = 3650
DEFAULT_DAYS = 365
_DNS_NAME = re.compile(r"(?!-)[a-z0-9-]{1,63}(?<!-)(\.(?!-)[a-z0-9-]{1,63}(?<!-))*")
_CLOCK_SKEW = datetime.timedelta(minutes=5)  # valid a little before now: peers' clocks differ

PrivateKey = ec.EllipticCurvePrivateKey


class CertificateError(Exception):
    """A certificate folder that cannot be used or written as asked."""


@dataclass(frozen=True, slots=True)
class Authority:
    """The deployment's certificate authority: its key signs the processes' certificates."""

    key: PrivateKey
    cert: x509.Certificate

    @property
    def expires(self) -> datetime.datetime:
        return self.cert.not_valid_after_utc


@dataclass(frozen=True, slots=True)
class Credentials:
    """The three files a process's TLS needs, by path (key material never travels in a config)."""

    ca: Path
    cert: Path
    key: Path

    @classmethod
    def in_folder(cls, folder: str | Path) -> Credentials:
        """A process's folder as ``botstage certs`` writes it."""
        folder = Path(folder)
        return cls(folder / PROCESS_CA, folder / PROCESS_CERT, folder / PROCESS_KEY)

    def missing(self) -> list[Path]:
        return [path for path in (self.ca, self.cert, self.key) if not path.is_file()]


def _new_key() -> PrivateKey:
    return ec.generate_private_key(ec.SECP256R1())


def _validity(days: int, now: datetime.datetime) -> tuple[datetime.datetime, datetime.datetime]:
    if days < 1:
        raise CertificateError(f"a certificate must be valid for at least 1 day, not {days}")
    return now - _CLOCK_SKEW, now + datetime.timedelta(days=days)


def new_authority(name: str = CA_NAME, days: int = CA_DAYS, now: datetime.datetime | None = None) -> Authority:
    """A new self-signed authority that may sign end-entity certificates and nothing else."""
    key = _new_key()
    subject = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, name)])
    start, end = _validity(days, now or datetime.datetime.now(datetime.UTC))
    public = key.public_key()
    cert = (
        x509.CertificateBuilder()
        .subject_name(subject)
        .issuer_name(subject)
        .public_key(public)
        .serial_number(x509.random_serial_number())
        .not_valid_before(start)
        .not_valid_after(end)
        .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .add_extension(_key_usage(cert_sign=True), critical=True)
        .add_extension(x509.SubjectKeyIdentifier.from_public_key(public), critical=False)
        .sign(key, hashes.SHA256())
    )
    return Authority(key, cert)


def _key_usage(*, cert_sign: bool) -> x509.KeyUsage:
    return x509.KeyUsage(
        digital_signature=not cert_sign,
        content_commitment=False,
        key_encipherment=False,
        data_encipherment=False,
        key_agreement=False,
        key_cert_sign=cert_sign,
        crl_sign=cert_sign,
        encipher_only=False,
        decipher_only=False,
    )


def _san(host: str) -> x509.GeneralName:
    try:
        return x509.IPAddress(ipaddress.ip_address(host.strip("[]")))
    except ValueError:
        pass
    name = host.rstrip(".").lower()
    if not _DNS_NAME.fullmatch(name):
        raise CertificateError(f"host {host!r} is neither an IP address nor a DNS name")
    return x509.DNSName(name)


def subject_alternative_names(hosts: Iterable[str]) -> list[x509.GeneralName]:
    """The SANs for ``hosts`` (IP addresses as such, names as DNS names), loopback first, no repeats."""
    names: list[x509.GeneralName] = []
    for host in (*DEFAULT_HOSTS, *hosts):
        san = _san(host)
        if san not in names:
            names.append(san)
    return names


def issue(
    authority: Authority,
    process: str,
    hosts: Iterable[str] = (),
    days: int = DEFAULT_DAYS,
    now: datetime.datetime | None = None,
) -> tuple[PrivateKey, x509.Certificate]:
    """A new key and a certificate for ``process`` (its common name) on ``hosts``, signed by ``authority``.

    The certificate never outlives the authority: a chain is only as valid as its shortest link.
    """
    validate_node_name(process)
    key = _new_key()
    start, end = _validity(days, now or datetime.datetime.now(datetime.UTC))
    end = min(end, authority.expires)
    public = key.public_key()
    cert = (
        x509.CertificateBuilder()
        .subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, process)]))
        .issuer_name(authority.cert.subject)
        .public_key(public)
        .serial_number(x509.random_serial_number())
        .not_valid_before(start)
        .not_valid_after(end)
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(_key_usage(cert_sign=False), critical=True)
        .add_extension(
            x509.ExtendedKeyUsage([ExtendedKeyUsageOID.SERVER_AUTH, ExtendedKeyUsageOID.CLIENT_AUTH]), critical=False
        )
        .add_extension(x509.SubjectAlternativeName(subject_alternative_names(hosts)), critical=False)
        .add_extension(x509.SubjectKeyIdentifier.from_public_key(public), critical=False)
        .add_extension(x509.AuthorityKeyIdentifier.from_issuer_public_key(authority.key.public_key()), critical=False)
        .sign(authority.key, hashes.SHA256())
    )
    return key, cert


def common_name(cert: x509.Certificate) -> str:
    """The certificate's common name: a process's identity in Zenoh's access control."""
    names = cert.subject.get_attributes_for_oid(NameOID.COMMON_NAME)
    return str(names[0].value) if names else ""


# -- files --------------------------------------------------------------------------------------


def _write_atomically(path: Path, data: bytes, mode: int) -> None:
    """Write ``data`` to ``path`` with ``mode`` from the first byte: a key is never readable by others."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    try:
        os.fchmod(fd, mode)
        with os.fdopen(fd, "wb") as out:
            out.write(data)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def write_private_key(path: Path, key: PrivateKey) -> None:
    """PEM PKCS#8, unencrypted (Zenoh takes no passphrase), mode 0600."""
    pem = key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption())
    _write_atomically(path, pem, 0o600)


def write_certificate(path: Path, cert: x509.Certificate) -> None:
    _write_atomically(path, cert.public_bytes(serialization.Encoding.PEM), 0o644)


def load_authority(folder: Path) -> Authority:
    """The authority in ``folder`` (``ca.pem`` and ``ca.key``), checked to be one and to belong together."""
    try:
        cert = x509.load_pem_x509_certificate((folder / CA_CERT).read_bytes())
        key = serialization.load_pem_private_key((folder / CA_KEY).read_bytes(), password=None)
    except OSError as error:
        raise CertificateError(f"cannot read the authority in {folder}: {error.strerror or error}") from None
    except (ValueError, TypeError):  # the message could quote the file: say only which
        raise CertificateError(f"the authority in {folder} is not a PEM certificate and unencrypted key") from None
    if not isinstance(key, ec.EllipticCurvePrivateKey) or key.public_key() != cert.public_key():
        raise CertificateError(f"{folder / CA_KEY} is not the key of {folder / CA_CERT}")
    try:
        is_ca = cert.extensions.get_extension_for_class(x509.BasicConstraints).value.ca
    except x509.ExtensionNotFound:
        is_ca = False
    if not is_ca:
        raise CertificateError(f"{folder / CA_CERT} is not a certificate authority")
    return Authority(key, cert)


@dataclass(frozen=True, slots=True)
class Written:
    """What ``make_certificates`` did: whether it made the authority, and each process's files."""

    authority_created: bool
    authority: Path
    processes: dict[str, Credentials]


def make_certificates(
    folder: Path,
    processes: Sequence[str],
    hosts: dict[str, Sequence[str]] | None = None,
    days: int = DEFAULT_DAYS,
    new_ca: bool = False,
) -> Written:
    """Certificates for ``processes`` in ``folder``, signed by its authority (made if there is none).

    An existing authority is kept and used (its processes' certificates stay valid) unless
    ``new_ca``: replacing it silently would lock every other process out.
    """
    for process in processes:
        validate_node_name(process)
    has_ca = (folder / CA_CERT).exists() or (folder / CA_KEY).exists()
    if has_ca and not new_ca:
        authority = load_authority(folder)
    else:
        authority = new_authority(days=max(CA_DAYS, days))
        write_private_key(folder / CA_KEY, authority.key)
        write_certificate(folder / CA_CERT, authority.cert)
    written: dict[str, Credentials] = {}
    for process in dict.fromkeys(processes):
        key, cert = issue(authority, process, (hosts or {}).get(process, ()), days)
        files = Credentials.in_folder(folder / process)
        write_private_key(files.key, key)
        write_certificate(files.cert, cert)
        write_certificate(files.ca, authority.cert)
        written[process] = files
    return Written(not has_ca or new_ca, folder / CA_CERT, written)
