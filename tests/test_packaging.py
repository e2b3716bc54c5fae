"""botstage's import names live under `botstage.`: the repository's folders `behaviors/`, `skills/`,
`robots/` and `missions/` are mapped into that namespace when packaged, so a user's project with
packages of the same names (the most natural layout for a robotics project) works beside it."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import tomllib
from pathlib import Path

from tests.tools import install_wheel

ROOT = Path(__file__).resolve().parent.parent
LAYERS = ("behaviors", "skills", "robots", "missions")


def test_every_package_folder_is_listed_under_botstage() -> None:
    setuptools = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["setuptools"]
    assert setuptools["package-dir"] == {f"botstage.{layer}": layer for layer in LAYERS}
    folders = {
        "botstage." + ".".join(init.parent.relative_to(ROOT).parts)
        for layer in LAYERS
        for init in (ROOT / layer).rglob("__init__.py")
    }
    assert sorted(setuptools["packages"]) == sorted(folders)


# A user's project laid out as botstage's own repository is: every one of these would shadow botstage
# if botstage's import names were the bare folder names.
USER_PACKAGES = {
    "skills/__init__.py": "WHO = 'the user'\n",
    "skills/greet.py": "def hello() -> str:\n    return 'hello from the user package'\n",
    "robots/__init__.py": "WHO = 'the user'\n",
    "missions/__init__.py": "WHO = 'the user'\n",
    "behaviors/__init__.py": "WHO = 'the user'\n",
}

# The user's plug-in: a skill that calls into the user's own `skills` package.
PLUGIN = {
    "user_kit/__init__.py": "",
    "user_kit/wave.py": textwrap.dedent(
        """\
        from botstage.skills import In, Outcome, Skill, SkillContext

        import skills.greet


        class Wave(Skill):
            name = "wave"
            description = "wave for a while, greeting as the user's own package says"
            inputs = {"seconds": In(float, default=1.0)}

            def run(self, ctx: SkillContext, seconds: float):
                end = ctx.clock.now() + seconds
                while ctx.clock.now() < end:
                    yield
                return Outcome("success", skills.greet.hello())
        """
    ),
}

MISSION = """\
name: user_demo
robot: peoplebot
world: museum
seed: 3
until: 20
machine:
  outcomes: [done, failed]
  states:
    waving: {skill: wave, inputs: {seconds: 2}, transitions: {success: done, failure: failed}}
"""

SCENARIO = """\
mission: ../user_demo.yaml
expect:
  outcome: done
  states: [waving, done]
"""

MOCKED = """\
mission: ../user_demo.yaml
mocks:
  wave: {always: {outcome: failure}}
expect:
  outcome: failed
"""

USER_TEST = """\
import behaviors
import missions
import robots
import skills


def test_the_users_packages_are_the_users() -> None:
    assert {skills.WHO, robots.WHO, missions.WHO, behaviors.WHO} == {"the user"}
"""


def test_a_user_project_with_its_own_packages_runs_pytest_and_botstage(tmp_path: Path) -> None:
    project = tmp_path / "project"
    for path, text in {**USER_PACKAGES, "missions/user_demo.yaml": MISSION}.items():
        (project / path).parent.mkdir(parents=True, exist_ok=True)
        (project / path).write_text(text, encoding="utf-8")
    (project / "scenarios").mkdir()
    (project / "scenarios" / "waves.yaml").write_text(SCENARIO.replace("../", "../missions/"), encoding="utf-8")
    (project / "scenarios" / "wave_fails.yaml").write_text(MOCKED.replace("../", "../missions/"), encoding="utf-8")
    (project / "tests").mkdir()
    (project / "tests" / "test_users_own.py").write_text(USER_TEST, encoding="utf-8")
    site = install_wheel(tmp_path, "user-kit", PLUGIN, "[botstage.skills]\nwave = user_kit.wave:Wave\n")
    # The project's folder first, as `python -m pytest` and a user's PYTHONPATH put it.
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(project), str(site)]), "COLUMNS": "200"}

    tests = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:xdist", "--rootdir", str(project)],
        cwd=project,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert tests.returncode == 0, tests.stdout + tests.stderr
    assert "3 passed" in tests.stdout, tests.stdout

    run = subprocess.run(
        [sys.executable, "-m", "botstage.missions.cli", "run", "missions/user_demo.yaml", "-q", "--out", "run"],
        cwd=project,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert run.returncode == 0, run.stdout + run.stderr
    assert "outcome done" in run.stdout
    assert '"reason":"hello from the user package"' in (project / "run" / "trace.jsonl").read_text(encoding="utf-8")
