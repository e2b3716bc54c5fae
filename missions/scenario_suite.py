"""Scenario files run one after another without pytest (`botstage test`): which files a list of
files and folders names, and each run's folder, kept only when the scenario fails (its report names it)."""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

from missions.scenario import Result, load_scenario, run_scenario


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
        folder = Path(tempfile.mkdtemp(prefix=f"botstage-{path.stem}-"))
        result = run_scenario(load_scenario(path), folder)
        if result.passed:
            shutil.rmtree(folder, ignore_errors=True)
        yield path, result
