"""Scenario files run one after another without pytest (`botstage test`): which files a list of
files and folders names, and each run's folder: made only when the scenario runs, kept only when
it ran and failed (its report names it)."""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

from botstage.missions.scenario import Result, Scenario, load_scenario, run_scenario


class SuiteError(Exception):
    """A named file or folder does not exist, or the folders hold no scenario file."""


def scenario_files(roots: list[Path]) -> list[Path]:
    """The scenario files of these files and folders (a folder's YAML files, sorted, recursively)."""
    files: list[Path] = []
    for root in roots:
        if root.is_dir():
            files += sorted(p for p in root.rglob("*.y*ml") if p.suffix in (".yaml", ".yml"))
        elif root.exists():
            files.append(root)
        else:
            raise SuiteError(f"{root} does not exist")
    if not files:
        raise SuiteError(f"no scenario files under {', '.join(map(str, roots))}")
    return files


def run_suite(files: Iterable[Path]) -> Iterator[tuple[Path, Result]]:
    """Each file's result in turn; a passed scenario's run folder is removed, a failed one's stays."""
    for path in files:
        yield path, run_in_folder(load_scenario(path), _temporary)


def _temporary(scenario: Scenario) -> Path:
    return Path(tempfile.mkdtemp(prefix=f"botstage-{scenario.name}-"))


def run_in_folder(scenario: Scenario, make_folder: Callable[[Scenario], Path]) -> Result:
    """Run a scenario in a folder ``make_folder`` gives, made only if the scenario can run at all
    (it checks); the folder stays only when the run happened and failed (its report names it):
    a pass, an invalid mission, an error before the run or during it leave nothing behind."""
    if scenario.problems or scenario.spec is None:
        return Result(scenario, False, [str(p) for p in scenario.problems])  # nothing to run: no folder
    folder = make_folder(scenario)
    keep = False
    try:
        result = run_scenario(scenario, folder)
        keep = not result.passed and result.folder is not None
        return result
    finally:
        if not keep:
            shutil.rmtree(folder, ignore_errors=True)
