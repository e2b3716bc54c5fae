"""`botstage certs OUT_DIR`: a deployment's certificate authority and one certificate per process.

The processes come from ``--process`` or a deployment file's ``processes:`` (checked whole first);
each gets ``OUT_DIR/<process>/{cert.pem,key.pem,ca.pem}`` for Zenoh's mutual TLS
(robots.ros2.security), with its hosts as subject alternative names: loopback always, the
deployment's ``host:`` and listen addresses, and ``--host``. A deployment's folder also gets
``OUT_DIR/operator/``: teleop's identity, which the deployment's policy lets drive the robot
(missions/distributed/security.py). An authority already in OUT_DIR signs
the new certificates and is never replaced unless ``--new-ca`` says so (every certificate it signed
would stop working). Private keys are written 0600 and never printed.
"""

from __future__ import annotations

from pathlib import Path

import typer

from botstage.missions.cli.common import _fail, console, input_file, number, output_dir

DAYS = number(ge=1, le=36500)


def _deployment_processes(path: Path) -> dict[str, list[str]]:
    """Process name -> the hosts it is reached at (its ``host:`` and its listen endpoints' hosts)."""
    from botstage.missions.deployment import check_deployment
    from botstage.robots.ros2.security import ListenError, endpoint_host

    checked = check_deployment(path)
    if not checked.ok or checked.deployment is None:
        raise _fail([str(problem) for problem in checked.problems], 2)
    hosts: dict[str, list[str]] = {}
    for name, process in checked.deployment.processes.items():
        found = [process.host]
        for endpoint in process.listen:
            try:
                found.append(endpoint_host(endpoint)[1] or "")
            except ListenError:
                continue  # the deployment's own check reports it
        hosts[name] = [host for host in found if host and host not in ("localhost", "0.0.0.0", "::")]
    return hosts


def certs(
    out_dir: Path = typer.Argument(..., help="the folder to write into (made if missing)", callback=output_dir),
    process: list[str] = typer.Option(
        [], "--process", metavar="NAME", help="a process to make a certificate for (repeatable)"
    ),
    deployment: Path | None = typer.Option(
        None,
        "--deployment",
        metavar="FILE",
        help="make one for every process of this deployment, and the operator's (teleop's) in OUT_DIR/operator",
        callback=input_file,
    ),
    days: int = typer.Option(365, help="how long the processes' certificates are valid", callback=DAYS),
    host: list[str] = typer.Option(
        [],
        "--host",
        metavar="H",
        help="a host name or address every certificate is valid for (repeatable; "
        "localhost, 127.0.0.1 and ::1 always are)",
    ),
    new_ca: bool = typer.Option(
        False, "--new-ca", help="replace the authority in OUT_DIR (certificates it signed stop being accepted)"
    ),
) -> None:
    """Make a certificate authority and a certificate per process for Zenoh's mutual TLS."""
    from botstage.missions.deployment import OPERATOR
    from botstage.robots.ros2.certs import CA_KEY, CertificateError, make_certificates, subject_alternative_names

    hosts = _deployment_processes(deployment) if deployment is not None else {}
    if deployment is not None:
        hosts.setdefault(OPERATOR, [])  # teleop's identity: its policy lets it drive the robot
    for name in process:
        hosts.setdefault(name, [])
    if not hosts:
        raise typer.BadParameter("name at least one process (--process NAME or --deployment FILE)")
    try:
        for name in hosts:
            hosts[name] = [*hosts[name], *host]
            subject_alternative_names(hosts[name])  # a bad host is a usage error before anything is written
    except CertificateError as error:
        raise typer.BadParameter(str(error), param_hint="'--host'") from None
    try:
        written = make_certificates(out_dir, list(hosts), hosts, days, new_ca=new_ca)
    except ValueError as error:  # a process name that cannot be a node name (nor a folder name)
        raise typer.BadParameter(str(error), param_hint="'--process'") from None
    except CertificateError as error:
        raise _fail(str(error)) from None
    except OSError as error:
        raise _fail(f"cannot write certificates in {out_dir}: {error.strerror or error}") from None
    made = "made" if written.authority_created else "kept"
    _say(f"certificate authority: {written.authority} ({made}; keep {out_dir / CA_KEY} off the robots)")
    for name, files in written.processes.items():
        role = " (teleop's: botstage teleop ... --certs this folder)" if name == OPERATOR else ""
        _say(f"{name}: {files.cert.parent}/ (ca.pem, cert.pem, key.pem); hosts {', '.join(_hosts(hosts[name]))}{role}")


def _say(line: str) -> None:
    """Paths and names only: nothing written here is secret."""
    console.print(line, highlight=False, soft_wrap=True)


def _hosts(extra: list[str]) -> list[str]:
    from botstage.robots.ros2.certs import DEFAULT_HOSTS

    return list(dict.fromkeys([*DEFAULT_HOSTS, *extra]))
