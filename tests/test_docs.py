"""The manual in docs/: it builds, its getting-started page runs, its reference matches the code.

- The site builds with ``mkdocs build --strict`` (a broken link, a missing anchor or any other
  warning is an error) into a temporary folder, offline (the theme loads no web fonts).
- Every fenced ``bash``, ``console`` and ``python`` block of the getting-started page runs, in
  order, in one temporary folder where ``missions`` points at the checkout's (the page's commands
  are written "inside the checkout"), with the test environment's ``botstage`` first on the PATH;
  each must exit 0. A ``bash`` block is one script (``set -e``); in a ``console`` block the lines
  after ``$ `` are the commands and the rest is output. Conventions, as HTML comments on the line
  just before a block (invisible on GitHub and on the site):
  ``<!-- docs-test: skip (reason) -->`` leaves the block out (installing with pip: the test runs
  with the environment it is in); ``<!-- docs-test: file NAME -->`` writes the block to NAME in
  the folder instead of running it (a mission the next commands use). ``text`` and ``yaml``
  blocks without a comment are shown output or examples and are not run.
- Each CLI verb (the Click command tree, as lazily loading groups answer it), each node kind (of
  botstage's scope and of the XML node sets) and each skill of the live registries has its entry,
  by anchor, in the generated reference pages.
- The README stays short and links only to pages that exist; the README's example validates.
"""

from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
BIN = Path(sys.executable).parent
BLOCK = re.compile(r"(?:<!-- docs-test: (?P<mark>[^>]*?) -->\n)?```(?P<lang>\w*)[^\n]*\n(?P<body>.*?)```", re.S)

pytest.importorskip("mkdocs", reason="the docs extra (in the test extra) builds the manual")


def reference_module():
    spec = importlib.util.spec_from_file_location("docs_reference", DOCS / "hooks" / "reference.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def env() -> dict[str, str]:
    return {**os.environ, "PATH": f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}", "COLUMNS": "120"}


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("site")
    command = [str(BIN / "mkdocs"), "build", "--strict", "-f", str(ROOT / "mkdocs.yml"), "-d", str(out)]
    result = subprocess.run(
        command, capture_output=True, text=True, cwd=out, env={**env(), "NO_MKDOCS_2_WARNING": "1"}, timeout=600
    )
    assert result.returncode == 0, result.stdout + result.stderr
    warnings = [line for line in result.stderr.splitlines() if line.startswith(("WARNING", "ERROR"))]
    assert warnings == []
    return out


def test_the_site_builds_strict_with_every_page(site: Path) -> None:
    for page in DOCS.rglob("*.md"):
        if "hooks" not in page.parts:
            assert (site / page.relative_to(DOCS).with_suffix(".html")).is_file(), page
    for generated in ("cli", "nodes", "skills", "schema", "python-api"):
        assert (site / "reference" / f"{generated}.html").is_file()
    assert (site / "reference" / "mission.schema.json").is_file()
    assert "fonts.googleapis" not in (site / "index.html").read_text(encoding="utf-8")


def blocks(page: Path) -> list[tuple[str, str, str]]:
    """(language, mark, body) of every fenced block of a page, in order."""
    return [(m["lang"], (m["mark"] or "").strip(), m["body"]) for m in BLOCK.finditer(page.read_text(encoding="utf-8"))]


def test_every_getting_started_block_runs(tmp_path: Path) -> None:
    (tmp_path / "missions").symlink_to(ROOT / "missions", target_is_directory=True)
    ran = 0
    for lang, mark, body in blocks(DOCS / "getting-started.md"):
        if mark.startswith("skip"):
            continue
        if mark.startswith("file "):
            (tmp_path / mark.removeprefix("file ").strip()).write_text(body, encoding="utf-8")
            continue
        assert not mark, f"unknown docs-test mark {mark!r}"
        if lang in ("bash", "sh"):
            command = ["bash", "-e", "-o", "pipefail", "-c", body]
        elif lang == "console":
            script = "\n".join(line[2:] for line in body.splitlines() if line.startswith("$ "))
            command = ["bash", "-e", "-o", "pipefail", "-c", script]
        elif lang == "python":
            command = [sys.executable, "-c", body]
        else:
            continue
        result = subprocess.run(command, capture_output=True, text=True, cwd=tmp_path, env=env(), timeout=600)
        assert result.returncode == 0, f"{body}\n{result.stdout}\n{result.stderr}"
        ran += 1
    assert ran >= 5
    assert (tmp_path / "runs" / "first_py" / "summary.json").is_file()
    assert (tmp_path / "entertainer.svg").read_text().lstrip().startswith("<?xml")


def test_the_getting_started_conventions_are_the_ones_the_docstring_names() -> None:
    marks = {mark.split()[0] for _, mark, _ in blocks(DOCS / "getting-started.md") if mark}
    assert marks <= {"skip", "file"}


def ids(site: Path, page: str) -> set[str]:
    return reference_module().anchors((site / "reference" / page).read_text(encoding="utf-8"))


def test_every_cli_verb_has_a_reference_entry(site: Path) -> None:
    reference = reference_module()
    paths = [path for path, _, _ in reference.cli_commands()]
    assert ("run",) in paths and ("validate",) in paths and ("serve", "robot") in paths
    found = ids(site, "cli.html")
    missing = [" ".join(path) for path in paths if reference.cli_anchor(path) not in found]
    assert missing == []
    # every option of `run` is there, as `botstage run --help` prints it
    page = (site / "reference" / "cli.html").read_text(encoding="utf-8")
    for option in ("--monitor", "--backend", "--seed", "--until", "--set"):
        assert f"<code>{option}" in page


def test_every_node_kind_and_skill_has_a_reference_entry(site: Path) -> None:
    from botstage.behaviors.kinds import NodeKinds
    from botstage.skills.registry import Registry

    kinds, skills = list(NodeKinds.default()), list(Registry.default())
    assert "sequence" in kinds and "wait" in skills
    assert [k for k in kinds if f"kind-{k}" not in ids(site, "nodes.html")] == []
    assert [s for s in skills if f"skill-{s}" not in ids(site, "skills.html")] == []
    # the XML node sets (`botstage nodes --scope btcpp`) have their own entries, apart from botstage's
    xml = NodeKinds.default("btcpp").listed()
    assert "Sequence" in xml and "RecoveryNode" in xml and "sequence" not in xml
    assert [k for k in xml if f"kind-btcpp-{k}" not in ids(site, "nodes.html")] == []


def test_the_schema_reference_lists_every_mission_key(site: Path) -> None:
    from botstage.missions.schema import json_schema

    page = (site / "reference" / "schema.html").read_text(encoding="utf-8")
    for key in json_schema()["properties"]:
        assert f"<code>{key}</code>" in page, key


def test_the_python_api_reference_comes_from_the_docstrings(site: Path) -> None:
    page = (site / "reference" / "python-api.html").read_text(encoding="utf-8")
    for name in ("botstage.missions.api.Mission", "botstage.missions.api.StateMachine", "botstage.skills.Skill"):
        assert f'id="{name}"' in page, name


def test_the_readme_is_short_and_links_into_the_docs() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(readme.splitlines()) <= 200
    links = re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", readme)
    assert any(link.startswith("docs/") for link in links)
    for link in links:
        if "://" not in link:
            assert (ROOT / link).exists(), link
    for block in re.findall(r"```python\n(.*?)```", readme, re.S):
        assert "from botstage." in block


def test_the_readme_example_validates(tmp_path: Path) -> None:
    (example,) = re.findall(r"```yaml\n(.*?)```", (ROOT / "README.md").read_text(encoding="utf-8"), re.S)
    (tmp_path / "hello_patrol.yaml").write_text(example, encoding="utf-8")
    result = subprocess.run(
        [str(BIN / "botstage"), "validate", "hello_patrol.yaml"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env=env(),
    )
    assert result.returncode == 0, result.stdout + result.stderr


def test_no_development_history_in_the_manual() -> None:
    history = re.compile(r"\bissue \d+|this round|earlier round|missed this|\bwas made\b.*before", re.I)
    found = [
        f"{page.relative_to(ROOT)}:{number}: {line.strip()}"
        for page in [ROOT / "README.md", *DOCS.rglob("*.md")]
        for number, line in enumerate(page.read_text(encoding="utf-8").splitlines(), 1)
        if history.search(line)
    ]
    assert found == []
