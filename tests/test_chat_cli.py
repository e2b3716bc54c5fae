"""`botstage chat`: the converse skill's kernel and routing in a terminal, driven through stdin."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from botstage.missions.cli import app
from tests.test_converse import brain_cache, isolated_cache  # noqa: F401 (fixtures: the test cache)

runner = CliRunner()


def chat(*args: str, lines: list[str]) -> tuple[list[str], str, int]:
    result = runner.invoke(app, ["chat", "--seed", "3", *args], input="".join(line + "\n" for line in lines))
    return result.stdout.splitlines(), result.stderr, result.exit_code


def test_a_conversation_with_maya_and_alice() -> None:
    out, err, code = chat(lines=["Hello", "My name is Ada", "what is 2 plus 2", "What is my name?"])
    assert code == 0, err
    assert len(out) == 4 and all(line.startswith("Maya: ") for line in out)
    assert "I am Maya" in out[0] and "photo" in out[0]
    assert out[1:] == ["Maya: Nice to meet you, Ada! I am Maya.", "Maya: Four.", "Maya: Your name is Ada."]
    assert "categories" in err.splitlines()[-1]


def test_commands_are_shown_as_the_missions_events() -> None:
    out, _, code = chat("--no-alice", lines=["take a picture of us please", "yes", "whatsup", "never mind", "bye"])
    assert code == 0
    assert [line.split()[1] for line in out] == ["PHOTO", "YES", "WHATSUP", "CANCEL", "CIAO"]
    assert all(line.startswith("-> ") for line in out)


def test_each_visitor_has_a_memory_of_their_own() -> None:
    out, _, code = chat(
        "--no-alice",
        "--visitor",
        "ada",
        lines=[
            "my name is Ada",
            "/visitor bob",
            "what is my name",
            "call me Bob",
            "/visitor ada",
            "what is my name",
            "/visitor bob",
            "what is my name",
        ],
    )
    assert code == 0
    replies = [line for line in out if line.startswith("Maya: ")]
    assert replies == [
        "Maya: Nice to meet you, Ada! I am Maya.",
        "Maya: You have not told me your name yet. What is it?",
        "Maya: Nice to meet you, Bob! I am Maya.",
        "Maya: Your name is Ada.",
        "Maya: Your name is Bob.",
    ]


def test_quit_and_the_end_of_input_end_the_chat() -> None:
    out, _, code = chat("--no-alice", lines=["hello", "quit", "my name is Ada"])
    assert code == 0 and len(out) == 1
    out, _, code = chat("--no-alice", lines=[])
    assert code == 0 and out == []


def test_blank_lines_are_not_utterances() -> None:
    out, _, _ = chat("--no-alice", lines=["", "   ", "hello"])
    assert len(out) == 1


def test_the_brain_is_learnt_once_then_loaded(tmp_path: Path) -> None:
    _, err, _ = chat("--no-alice", "--cache-dir", str(tmp_path), lines=["hello"])
    assert "learnt and cached" in err
    _, err, _ = chat("--no-alice", "--cache-dir", str(tmp_path), lines=["hello"])
    assert "loaded from the cache" in err


def test_broken_aiml_is_reported_and_the_chat_goes_on(tmp_path: Path) -> None:
    broken = tmp_path / "broken.aiml"
    broken.write_text('<aiml version="1.0.1">\n<category><pattern>X</pattern><template>y</template>\n</aiml>\n')
    good = tmp_path / "good.aiml"
    good.write_text(
        '<aiml version="1.0.1"><category><pattern>PING</pattern><template>pong</template></category></aiml>'
    )
    out, err, code = chat("--no-alice", "--aiml", str(broken), "--aiml", str(good), lines=["ping", "hello"])
    assert code == 0
    assert f"{broken}:3:3: error: not well-formed XML: mismatched tag (file skipped)" in err.splitlines()
    assert out[0] == "Maya: pong" and "Maya" in out[1]


def test_a_missing_aiml_file_is_reported(tmp_path: Path) -> None:
    missing = tmp_path / "missing.aiml"
    out, err, code = chat("--no-alice", "--aiml", str(missing), lines=["hi"])
    assert code == 0 and out[0].startswith("Maya: ")
    assert f"{missing}:1:1: error: cannot read: No such file or directory (file skipped)" in err.splitlines()


def test_no_aiml_at_all_is_an_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("botstage.skills.chat.persona.MAYA_DIR", tmp_path)  # Maya's own AIML gone too
    out, err, code = chat("--no-alice", "--cache-dir", str(tmp_path / "cache"), lines=["hello"])
    assert (code, out) == (2, [])
    assert "error: no AIML category was learnt" in err
