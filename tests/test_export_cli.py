"""`botstage export`: a mission as BehaviorTree.CPP XML that botstage reads back, a finished run as
Groot2's .btlog, and clear errors for the wrong kind of input."""

from __future__ import annotations

from pathlib import Path

from typer.testing import CliRunner

from botstage.missions.cli import app
from botstage.missions.groot2.btlog import read_btlog
from botstage.missions.runner import run
from tests.monitor_harness import ROOT

HELLO = ROOT / "missions" / "examples" / "hello.yaml"
runner = CliRunner()


def test_a_mission_exports_as_xml_that_botstage_reads_back(tmp_path: Path) -> None:
    xml = tmp_path / "hello.xml"
    done = runner.invoke(app, ["export", str(HELLO), "-f", "btcpp", "-o", str(xml)])
    assert done.exit_code == 0, done.output
    assert xml.read_text().startswith("<") and 'BTCPP_format="4"' in xml.read_text()
    checked = runner.invoke(app, ["validate", str(xml)])
    assert checked.exit_code == 0 and "ok" in checked.output, checked.output
    printed = runner.invoke(app, ["export", str(HELLO), "-f", "btcpp"])
    assert printed.exit_code == 0 and printed.stdout == xml.read_text()


def test_a_finished_run_exports_as_a_btlog(tmp_path: Path) -> None:
    run(HELLO, out=tmp_path / "hello-run")
    done = runner.invoke(app, ["export", str(tmp_path / "hello-run"), "-f", "btlog"])
    assert done.exit_code == 0, done.output
    log = read_btlog(tmp_path / "hello-run.btlog")
    assert "<BehaviorTree" in log.xml and log.transitions


def test_the_wrong_input_is_said_so(tmp_path: Path) -> None:
    bad = runner.invoke(app, ["export", str(HELLO), "-f", "png"])
    assert bad.exit_code == 2 and "expected one of btcpp, btlog" in bad.output
    assert "is not a run folder" in runner.invoke(app, ["export", str(HELLO), "-f", "btlog"]).output
    assert "is a folder" in runner.invoke(app, ["export", str(tmp_path), "-f", "btcpp"]).output
    broken = tmp_path / "broken.yaml"
    broken.write_text("name: broken\nrobot: peoplebot\nworld: museum\nroot: main\ntrees:\n  main: {wiat: {}}\n")
    failed = runner.invoke(app, ["export", str(broken), "-f", "btcpp"])
    assert failed.exit_code == 1 and "broken.yaml:6:" in failed.output, failed.output
