"""pytest collects scenario files (YAML under a `scenarios` folder) as test items.

Installed with botstage through the `pytest11` entry point; a failure prints the scenario's
readable report: each failed expectation, the state diff, the trace around the first
divergence, and the run folder.
"""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

import pytest

from botstage.missions.scenario import Result, Scenario, load_scenario
from botstage.missions.scenario_suite import run_in_folder


def is_scenario(path: Path, root: Path) -> bool:
    """YAML files under a `scenarios` folder inside the test run's root (not anywhere above it)."""
    try:
        parts = path.relative_to(root).parts
    except ValueError:
        parts = path.parts
    return path.suffix in (".yaml", ".yml") and "scenarios" in parts[:-1]


def pytest_collect_file(file_path: Path, parent: pytest.Collector) -> pytest.Collector | None:
    if is_scenario(file_path, parent.config.rootpath):
        return ScenarioFile.from_parent(parent, path=file_path)
    return None


class ScenarioFailed(Exception):
    def __init__(self, result: Result) -> None:
        super().__init__(result.report())
        self.result = result


class ScenarioFile(pytest.File):
    def collect(self) -> Any:
        yield ScenarioItem.from_parent(self, name=self.path.stem)


class ScenarioItem(pytest.Item):
    def runtest(self) -> None:
        factory = getattr(self.config, "_tmp_path_factory", None)  # pytest's managed, pruned temp folders

        def folder(scenario: Scenario) -> Path:
            if factory is not None:
                return factory.mktemp(f"scenario-{self.name}")
            return Path(tempfile.mkdtemp(prefix=f"botstage-{scenario.name}-"))

        result = run_in_folder(load_scenario(self.path), folder)
        if not result.passed:
            raise ScenarioFailed(result)

    def repr_failure(self, excinfo: pytest.ExceptionInfo[BaseException], style: Any = None) -> str:
        if isinstance(excinfo.value, ScenarioFailed):
            return excinfo.value.result.report()
        return str(super().repr_failure(excinfo, style=style))

    def reportinfo(self) -> tuple[Path, int, str]:
        return self.path, 0, f"scenario {self.name}"
