"""Maya's chatbot: her categories, A.L.I.C.E., routing, predicates, visitors' memories, the brain
cache, broken AIML, and the converse skill as the engine runs it."""

from __future__ import annotations

import os
import random
import re
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from concurrent.futures import Future
from pathlib import Path
from typing import Any

import pytest

from botstage.robots.clock import SimClock
from botstage.skills.base import Outcome, Skill, SkillContext, SkillLogger
from botstage.skills.chat import cache
from botstage.skills.chat.cache import KEEP, brain_dir, cache_root, fingerprint, load_brain, prune, shared_brain
from botstage.skills.chat.chatbot import Chatbot
from botstage.skills.chat.kernel import SIM_EPOCH, calendar
from botstage.skills.chat.learn import learn_files
from botstage.skills.chat.persona import ALICE_DIR, MAYA_DIR, MAYA_PREDICATES, aiml_files
from botstage.skills.chat.routing import COMMANDS, route
from botstage.skills.converse import Converse
from botstage.skills.execution import SkillExecution
from botstage.skills.testing import DictBoard as Board
from botstage.skills.workers import Workers

AIML_HEAD = '<?xml version="1.0" encoding="UTF-8"?>\n<aiml version="1.0.1">\n'


def aiml(path: Path, body: str) -> Path:
    path.write_text(AIML_HEAD + body + "\n</aiml>\n", encoding="utf-8")
    return path


def category_lines(pattern: str) -> list[re.Pattern[str]]:
    """What a category of Maya's AIML can answer: each <li> of its <random> (or its template),
    as a regular expression where each <bot/> or <get/> may be any text."""
    for path in MAYA_DIR.glob("*.aiml"):
        for category in ET.parse(path).getroot().iter("category"):
            if " ".join(category.findtext("pattern", "").split()) == pattern:
                template = category.find("template")
                assert template is not None
                return [_line(item) for item in template.findall(".//random/li") or [template]]
    raise AssertionError(f"Maya has no category {pattern}")


def _line(element: ET.Element) -> re.Pattern[str]:
    parts = [element.text or ""]
    for child in element:
        parts += ["\0", child.tail or ""]
    text = " ".join("".join(parts).split())
    return re.compile(".+?".join(re.escape(part) for part in text.split("\0")))


def one_of(reply: str, lines: list[re.Pattern[str]]) -> bool:
    return any(line.fullmatch(reply) for line in lines)


@pytest.fixture(scope="session")
def brain_cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("brains")


@pytest.fixture(autouse=True)
def isolated_cache(brain_cache: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Skills and the CLI find the brain cache through the environment: never the user's here."""
    monkeypatch.setenv("BOTSTAGE_CACHE_DIR", str(brain_cache))


@pytest.fixture(scope="session")
def maya_only(brain_cache: Path) -> Chatbot:
    return Chatbot(load_brain(aiml_files(alice=False), brain_cache).trie, seed=1)


@pytest.fixture(scope="session")
def alice_trie(brain_cache: Path) -> Any:
    return shared_brain(aiml_files(alice=True), brain_cache / "chat").trie


@pytest.fixture
def maya(alice_trie: Any) -> Chatbot:
    return Chatbot(alice_trie, seed=1)


# -- Maya's own categories ------------------------------------------------------------------


def test_maya_greets_with_her_name_and_what_she_offers(maya: Chatbot) -> None:
    for text in ("Hello", "hi Maya", "Hey!", "Good morning"):
        reply = maya.reply(text, "ada")
        assert one_of(reply.removeprefix("Good morning! "), category_lines("CUE GREETING")), reply
        assert "Maya" in reply and "photo" in reply


def test_each_cue_is_one_of_its_categorys_lines(maya: Chatbot) -> None:
    for cue in ("CUE INFORMATION", "CUE COMPLIMENT", "CUE PHOTO READY", "CUE PHOTO CANCELLED", "CUE FALLBACK"):
        lines = category_lines(cue)
        for seed in range(6):
            reply = maya.reply(cue, "ada", random.Random(seed))
            assert one_of(reply, lines), (cue, reply)
            assert "  " not in reply and "<" not in reply


def test_maya_answers_about_the_attraction_and_herself(maya: Chatbot) -> None:
    assert one_of(maya.reply("What is this place?", "v"), category_lines("CUE INFORMATION"))
    assert "the museum" in maya.reply("What is this place?", "v")  # the attraction predicate filled in
    assert "PeopleBot" in maya.reply("Are you a robot?", "v")
    assert maya.reply("What can you do?", "v").startswith("I wander around the museum")
    assert maya.reply("How old are you?", "v") == f"I am {MAYA_PREDICATES['age']} years old. Robots age slowly!"
    assert maya.reply("Where are you?", "v") == "I am in the museum hall, at the museum."


def test_compliments_after_a_photo_and_goodbye_use_the_visitors_name(maya: Chatbot) -> None:
    assert maya.reply("CUE GOODBYE", "bob", random.Random(0)) in (
        "Ciao! Enjoy the rest of your visit.",
        "Goodbye, and thank you for visiting the museum!",
    )
    maya.reply("My name is Bob", "bob")
    assert maya.reply("CUE GOODBYE", "bob") == "Ciao, Bob! Enjoy the rest of your visit."
    assert one_of(maya.reply("How do I look?", "bob", random.Random(3)), category_lines("CUE COMPLIMENT"))


def test_maya_wins_over_alice_where_both_have_a_pattern(alice_trie: Any, maya_only: Chatbot) -> None:
    with_alice = Chatbot(alice_trie, seed=2)
    assert with_alice.reply("Hello", "v") != "Hi there!"  # A.L.I.C.E.'s HELLO, replaced by Maya's
    assert one_of(with_alice.reply("Hello", "v"), category_lines("CUE GREETING"))
    assert one_of(maya_only.reply("Hello", "v"), category_lines("CUE GREETING"))


# -- A.L.I.C.E. ----------------------------------------------------------------------------------


def test_alice_answers_what_maya_has_no_category_for(maya: Chatbot, maya_only: Chatbot) -> None:
    fallback = category_lines("CUE FALLBACK")
    for text in ("What is 2 plus 2?", "Do you like music?", "Tell me a joke", "I am sad"):
        assert one_of(maya_only.reply(text, "v"), fallback)  # Maya alone: her fallback
        answer = maya.reply(text, "v")
        assert answer and not one_of(answer, fallback), (text, answer)
    assert maya.reply("What is 2 plus 2?", "v") == "Four."


def test_the_bundled_alice_set_is_there_and_loads_whole() -> None:
    files = sorted(ALICE_DIR.glob("*.aiml"))
    assert len(files) > 50
    learned = learn_files(files)
    assert learned.problems == []
    assert len(learned.categories) > 90_000


# -- bot predicates ---------------------------------------------------------------------------


def test_bot_predicates_fill_alice_and_maya_templates(maya: Chatbot) -> None:
    assert maya.kernel.getBotPredicate("name") == "Maya"
    assert "blue" in maya.reply("What is your favorite color?", "v")
    assert "a ." not in maya.reply("Are you a robot?", "v")  # no predicate left empty in the sentence


def test_predicates_can_make_another_character(alice_trie: Any) -> None:
    robin = Chatbot(alice_trie, {"name": "Robin", "attraction": "the zoo", "location": "the reptile house"}, seed=0)
    assert robin.reply("What is your name?", "v") == "My name is Robin. What is yours?"
    assert "Robin" in robin.reply("hi robin", "v")  # <bot name="name"/> in a pattern matches the new name
    assert robin.reply("Where are you?", "v") == "I am in the reptile house, at the zoo."


# -- routing --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "command"),
    [
        ("PHOTO", "PHOTO"),
        ("Take a picture of us please", "PHOTO"),
        ("Maya, could you take a photo of us?", "PHOTO"),
        ("Hi Maya! Can we have a picture with you?", "PHOTO"),
        ("YES", "YES"),
        ("yes please", "YES"),
        ("OK!", "YES"),
        ("we're ready", "YES"),
        ("WHATSUP", "WHATSUP"),
        ("What's up, Maya?", "WHATSUP"),
        ("what is there to see here", "WHATSUP"),
        ("tell me about the museum", "WHATSUP"),
        ("CANCEL", "CANCEL"),
        ("never mind", "CANCEL"),
        ("no thanks", "CANCEL"),
        ("CIAO", "CIAO"),
        ("Goodbye!", "CIAO"),
        ("thank you, bye", "CIAO"),
        ("Bye! Thanks Maya!", "CIAO"),
        ("I have to go now", "CIAO"),
        ("hello", None),
        ("Hi Maya!", None),
        ("yes, I like music", None),
        ("I like pictures of cats", None),
        ("photography is my hobby", None),
        ("no", None),
        ("thank you", None),
        ("Take a picture. Actually, tell me about yourself", None),
        ("", None),
        ("?!", None),
    ],
)
def test_routing(text: str, command: str | None) -> None:
    assert route(text) == command


def test_every_command_word_routes_to_itself() -> None:
    assert [route(c) for c in COMMANDS] == list(COMMANDS)
    assert [route(c.lower() + "!") for c in COMMANDS] == list(COMMANDS)


def test_a_turn_sends_commands_to_the_mission_and_the_rest_to_the_kernel(maya_only: Chatbot) -> None:
    turn = maya_only.turn("take a photo of us", "turner")
    assert (turn.command, turn.reply) == ("PHOTO", "")
    assert "turner" not in maya_only.visitors  # the kernel was never asked
    turn = maya_only.turn("My name is Eve", "turner")
    assert turn.command is None and turn.reply == "Nice to meet you, Eve! I am Maya."


# -- visitors' memories -------------------------------------------------------------------------


def test_two_visitors_each_keep_their_own_name(maya: Chatbot) -> None:
    maya.reply("My name is Ada", "visitor-1")
    maya.reply("Call me Grace", "visitor-2")
    assert maya.reply("What is my name?", "visitor-1") == "Your name is Ada."
    assert maya.reply("What is my name?", "visitor-2") == "Your name is Grace."
    assert maya.reply("What is my name?", "visitor-3") == "You have not told me your name yet. What is it?"
    assert maya.predicate("visitor-1", "name") == "Ada"
    assert maya.visitors == ["visitor-1", "visitor-2", "visitor-3"]


def test_two_chatbots_on_one_brain_share_no_memory(alice_trie: Any) -> None:
    first, second = Chatbot(alice_trie), Chatbot(alice_trie)
    first.reply("My name is Ada", "v")
    assert second.predicate("v", "name") == ""
    assert first.predicate("v", "name") == "Ada"


# -- the kernel, made safe and deterministic --------------------------------------------------


def test_system_and_learn_elements_do_nothing(tmp_path: Path) -> None:
    marker = tmp_path / "owned"
    evil = aiml(
        tmp_path / "evil.aiml",
        f"<category><pattern>RUN *</pattern><template>ran<system>touch {marker} <star/></system></template>"
        "</category><category><pattern>LEARN</pattern><template>learnt<learn>*.aiml</learn></template></category>",
    )
    bot = Chatbot(load_brain([evil], use_cache=False).trie)
    assert bot.reply("run now", "v") == "ran"
    assert not marker.exists()
    assert bot.reply("learn", "v") == "learnt"
    assert bot.kernel.numCategories() == 2


def test_random_choices_follow_the_rng_given(maya: Chatbot) -> None:
    replies = {maya.reply("CUE COMPLIMENT", "v", random.Random(seed)) for seed in range(60)}
    assert len(replies) == len(category_lines("CUE COMPLIMENT"))  # every line is reachable
    again = [maya.reply("CUE COMPLIMENT", "v", random.Random(7)) for _ in range(3)]
    assert len(set(again)) == 1


def test_date_comes_from_the_mission_clock_in_simulation(tmp_path: Path) -> None:
    dated = aiml(tmp_path / "date.aiml", "<category><pattern>DATE</pattern><template><date/></template></category>")
    clock = SimClock(10)
    bot = Chatbot(load_brain([dated], use_cache=False).trie, now=calendar(clock))
    assert bot.reply("date", "v") == "Mon May 18 10:00:00 2026"
    for _ in range(655):
        clock.next_tick()
    assert bot.reply("date", "v") == (SIM_EPOCH.replace(minute=1, second=5, microsecond=500_000)).strftime(
        "%a %b %d %H:%M:%S %Y"
    )


def test_an_unmatched_input_gets_the_fallback_not_silence(maya_only: Chatbot) -> None:
    assert one_of(maya_only.reply("colourless green ideas sleep furiously", "v"), category_lines("CUE FALLBACK"))


# -- the brain cache --------------------------------------------------------------------------


def test_the_second_load_uses_the_brain_file(tmp_path: Path) -> None:
    files = aiml_files(alice=False)
    first = load_brain(files, tmp_path)
    assert first.origin == "learned" and first.path is not None and first.path.exists()
    second = load_brain(files, tmp_path)
    assert second.origin == "cache" and second.path == first.path
    assert second.trie.template_count == first.trie.template_count > 40
    for text in ("hello", "My name is Ada", "what is my name", "CUE PHOTO READY", "are you a robot"):
        assert Chatbot(second.trie).reply(text, "v", random.Random(1)) == Chatbot(first.trie).reply(
            text, "v", random.Random(1)
        )
    assert list(tmp_path.iterdir()) == [first.path]  # no temporary file left behind


def test_a_changed_aiml_file_makes_the_cache_stale(tmp_path: Path) -> None:
    source = aiml(tmp_path / "a.aiml", "<category><pattern>PING</pattern><template>pong</template></category>")
    cache_dir = tmp_path / "cache"
    assert load_brain([source], cache_dir).origin == "learned"
    assert load_brain([source], cache_dir).origin == "cache"
    aiml(source, "<category><pattern>PING</pattern><template>pong again</template></category>")
    rebuilt = load_brain([source], cache_dir)
    assert rebuilt.origin == "learned"
    assert Chatbot(rebuilt.trie).reply("ping", "v") == "pong again"
    assert load_brain([source], cache_dir).origin == "cache"


@pytest.mark.parametrize("damage", ["garbage", "truncated", "flipped", "empty"])
def test_a_corrupt_brain_file_is_rebuilt_not_a_crash(tmp_path: Path, damage: str) -> None:
    files = aiml_files(alice=False)
    path = load_brain(files, tmp_path).path
    assert path is not None
    data = path.read_bytes()
    if damage == "garbage":
        path.write_bytes(b"\x00\xff" * 1000)
    elif damage == "truncated":
        path.write_bytes(data[: len(data) // 2])
    elif damage == "flipped":
        path.write_bytes(data[:-100] + bytes([data[-100] ^ 0xFF]) + data[-99:])
    else:
        path.write_bytes(b"")
    rebuilt = load_brain(files, tmp_path)
    assert rebuilt.origin == "learned"
    assert any("unreadable" in note and "rebuilt" in note for note in rebuilt.notes)
    assert Chatbot(rebuilt.trie).reply("what is my name", "v") == "You have not told me your name yet. What is it?"
    assert load_brain(files, tmp_path).origin == "cache"  # and the rebuilt file is good


def test_an_unwritable_cache_still_gives_a_brain(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    loaded = load_brain(aiml_files(alice=False), blocker / "cache")
    assert loaded.origin == "learned" and loaded.path is None
    assert any("not writable" in note for note in loaded.notes)


def test_the_cache_folder_follows_the_environment(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("BOTSTAGE_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert brain_dir() == tmp_path / "xdg" / "botstage" / "chat"
    monkeypatch.setenv("XDG_CACHE_HOME", "relative/path")  # the XDG spec says to ignore it
    assert cache_root() == Path.home() / ".cache" / "botstage"
    monkeypatch.setenv("BOTSTAGE_CACHE_DIR", str(tmp_path / "mine"))
    assert brain_dir() == tmp_path / "mine" / "chat"
    assert brain_dir(tmp_path / "given") == tmp_path / "given"


def test_the_key_is_the_contents_in_order(tmp_path: Path) -> None:
    a = aiml(tmp_path / "a.aiml", "<category><pattern>A</pattern><template>a</template></category>")
    b = aiml(tmp_path / "b.aiml", "<category><pattern>A</pattern><template>b</template></category>")
    assert fingerprint([a, b]) != fingerprint([b, a])  # the later file wins: order matters
    before = fingerprint([a, b])
    a.touch()
    assert fingerprint([a, b]) == before  # a touched file with the same content is not stale


def test_old_brain_files_are_pruned(tmp_path: Path) -> None:
    for n in range(KEEP + 3):
        brain = tmp_path / f"brain-{n}.brn"
        brain.write_bytes(b"x")
        os.utime(brain, ns=(n * 10**9, n * 10**9))
    prune(tmp_path, KEEP)
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"brain-{n}.brn" for n in range(3, KEEP + 3)]


def test_the_process_shares_one_brain_per_aiml_set(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(cache, "_loaded", {})
    files = aiml_files(alice=False)
    assert shared_brain(files, tmp_path) is shared_brain(files, tmp_path)


# -- broken AIML --------------------------------------------------------------------------------


def test_broken_xml_is_a_located_error_and_the_rest_still_loads(tmp_path: Path) -> None:
    good = aiml(tmp_path / "good.aiml", "<category><pattern>PING</pattern><template>pong</template></category>")
    broken = tmp_path / "broken.aiml"
    broken.write_text(
        AIML_HEAD
        + "<category><pattern>ZIP</pattern><template>zap</template></category>\n"
        + "<category><pattern>HELLO</pattern>\n"
        + "  <template>hi</templat>\n"
        + "</category>\n</aiml>\n"
    )
    loaded = load_brain([good, broken, *aiml_files(alice=False)], tmp_path)
    assert [str(p) for p in loaded.problems] == [
        f"{broken}:5:17: error: not well-formed XML: mismatched tag (file skipped)"
    ]
    bot = Chatbot(loaded.trie)
    assert bot.reply("ping", "v") == "pong"
    assert bot.reply("zip", "v") != "zap"  # nothing of the broken file, not even what came before the error
    assert "Maya" in bot.reply("hello", "v")
    cached = load_brain([good, broken, *aiml_files(alice=False)], tmp_path)
    assert cached.origin == "cache" and cached.problems == loaded.problems  # reported on every start


def test_an_aiml_mistake_skips_its_category_only(tmp_path: Path) -> None:
    source = aiml(
        tmp_path / "mistake.aiml",
        "<category><pattern>ONE</pattern><template>1</template></category>\n"
        "<category><template>no pattern</template></category>\n"
        "<category><pattern>TWO</pattern><template>2</template></category>",
    )
    loaded = load_brain([source], use_cache=False)
    assert len(loaded.problems) == 1
    problem = loaded.problems[0]
    assert (problem.location.file, problem.location.line) == (str(source), 4)
    assert "Unexpected <template> tag" in problem.message
    bot = Chatbot(loaded.trie)
    assert (bot.reply("one", "v"), bot.reply("two", "v")) == ("1", "2")


def test_a_missing_file_is_a_problem_too(tmp_path: Path) -> None:
    loaded = load_brain([tmp_path / "nowhere.aiml", *aiml_files(alice=False)], use_cache=False)
    assert [p.message for p in loaded.problems] == ["cannot read: No such file or directory"]
    assert loaded.trie.template_count > 40


# -- the converse skill -------------------------------------------------------------------------


class Harness:
    """A skill run as the engine runs it on the sim clock: a step per tick, work drained between."""

    def __init__(self, interfaces: dict[str, Any] | None = None, workers: Any = None) -> None:
        self.clock = SimClock(10)
        self.workers = workers or Workers()
        self.logs: list[str] = []
        self.interfaces = interfaces or {}

    def context(self, skill: Skill, node: str = "node") -> SkillContext:
        return SkillContext(
            clock=self.clock,
            params=skill.params,
            logger=SkillLogger(node, sink=lambda n, level, message: self.logs.append(f"{level}: {message}")),
            blackboard=Board(),
            workers=self.workers,
            interfaces=self.interfaces,
            rng=random.Random(f"0:{node}"),
            node=node,
        )

    def execution(self, skill: Skill, node: str = "node") -> SkillExecution:
        return SkillExecution(skill, self.context(skill, node))

    def tick(self) -> None:
        if isinstance(self.workers, Workers):
            self.workers.drain()
        self.clock.next_tick()

    def run(self, skill: Skill, max_ticks: int = 10_000, node: str = "node", **inputs: Any) -> tuple[Outcome, int]:
        run = self.execution(skill, node)
        outcome, ticks = run.start(inputs), 0
        while outcome is None:
            self.tick()
            ticks += 1
            assert ticks < max_ticks, "the skill never ended"
            outcome = run.step()
        return outcome, ticks

    def close(self) -> None:
        if isinstance(self.workers, Workers):
            self.workers.shutdown()


@pytest.fixture
def harness() -> Iterator[Harness]:
    h = Harness()
    yield h
    h.close()


def test_converse_replies_as_maya(harness: Harness) -> None:
    outcome, ticks = harness.run(Converse(), text="My name is Ada", visitor="ada")
    assert outcome == Outcome(
        "replied", "", {"reply": "Nice to meet you, Ada! I am Maya.", "command": None, "heard": "My name is Ada"}
    )
    assert ticks == 2  # a tick for the brain to load, one for the reply: both in the worker pool
    outcome, ticks = harness.run(Converse(), text="What is my name?", visitor="ada")
    assert outcome.outputs["reply"] == "Your name is Ada."
    assert ticks == 1  # the run's Maya is loaded once


def test_converse_routes_commands_without_the_chatbot(harness: Harness) -> None:
    outcome, ticks = harness.run(Converse(), text="Could you take a picture of us?")
    assert outcome.name == "command" and ticks == 0
    assert outcome.outputs == {"reply": "", "command": "PHOTO", "heard": "Could you take a picture of us?"}
    assert harness.workers.outstanding == 0
    outcome, _ = harness.run(Converse(), text="ciao")
    assert outcome.outputs["command"] == "CIAO"


def test_converse_without_input(harness: Harness) -> None:
    for text in ("", "   \n"):
        outcome, ticks = harness.run(Converse(), text=text)
        assert (outcome.name, ticks) == ("no_input", 0)
        assert outcome.outputs == {"reply": "", "command": None, "heard": ""}


def test_a_cue_asks_for_mayas_line_and_is_not_a_visitor(harness: Harness) -> None:
    outcome, _ = harness.run(Converse(), cue="photo ready")
    assert outcome.name == "replied"
    assert one_of(outcome.outputs["reply"], category_lines("CUE PHOTO READY"))
    assert outcome.outputs["heard"] == ""
    outcome, _ = harness.run(Converse(), cue="goodbye", text="hello")
    assert outcome.name == "failure" and "not both" in outcome.reason


def test_visitors_are_remembered_per_run(harness: Harness) -> None:
    harness.run(Converse(), text="My name is Ada", visitor="a")
    harness.run(Converse(), text="My name is Bob", visitor="b", node="other")  # another node, same run
    assert harness.run(Converse(), text="what is my name", visitor="a")[0].outputs["reply"] == "Your name is Ada."
    assert harness.run(Converse(), text="what is my name", visitor="b")[0].outputs["reply"] == "Your name is Bob."
    other_run = Harness()
    try:
        reply = other_run.run(Converse(), text="what is my name", visitor="a")[0].outputs["reply"]
    finally:
        other_run.close()
    assert reply == "You have not told me your name yet. What is it?"


class LazyFuture(Future[Any]):
    """Work that runs when the pool says so, or as soon as someone waits for its result."""

    def __init__(self, work: Any) -> None:
        super().__init__()
        self._work = work

    def run(self) -> None:
        if not self.done():
            try:
                self.set_result(self._work())
            except Exception as error:
                self.set_exception(error)

    def result(self, timeout: float | None = None) -> Any:
        self.run()
        return super().result(timeout)

    def exception(self, timeout: float | None = None) -> BaseException | None:
        self.run()
        return super().exception(timeout)


class Backwards:
    """A worker pool that does the latest work first: the worst order threads could take."""

    def __init__(self) -> None:
        self.futures: list[LazyFuture] = []

    def submit(self, fn: Any, *args: Any, **kwargs: Any) -> Future[Any]:
        self.futures.append(LazyFuture(lambda: fn(*args, **kwargs)))
        return self.futures[-1]

    def run_backwards(self) -> None:
        for future in reversed(self.futures):
            future.run()


def test_replies_asked_in_one_tick_are_answered_in_the_order_asked() -> None:
    pool = Backwards()
    harness = Harness(workers=pool)
    tell = harness.execution(Converse({"alice": False}), "tell")
    ask = harness.execution(Converse({"alice": False}), "ask")
    assert tell.start({"text": "My name is Ada", "visitor": "v"}) is None
    assert ask.start({"text": "What is my name?", "visitor": "v"}) is None
    pool.run_backwards()  # Maya loads
    harness.tick()
    assert tell.step() is None and ask.step() is None  # both replies asked in this tick
    pool.run_backwards()  # the question's work runs first; it waits for the introduction
    harness.tick()
    told, asked = tell.step(), ask.step()
    assert told is not None and told.outputs["reply"] == "Nice to meet you, Ada! I am Maya."
    assert asked is not None and asked.outputs["reply"] == "Your name is Ada."


class Pending:
    """A worker pool whose work never finishes by itself: the skill must keep ticking."""

    def __init__(self) -> None:
        self.submitted: list[tuple[Any, Future[Any]]] = []

    def submit(self, fn: Any, *args: Any, **kwargs: Any) -> Future[Any]:
        future: Future[Any] = Future()
        self.submitted.append((lambda: fn(*args, **kwargs), future))
        return future

    def finish(self, index: int) -> None:
        work, future = self.submitted[index]
        future.set_result(work())


def test_loading_and_replying_never_block_a_tick() -> None:
    pool = Pending()
    harness = Harness(workers=pool)
    run = harness.execution(Converse({"alice": False}))
    assert run.start({"text": "hello"}) is None
    assert [getattr(f, "__name__", "") for f, _ in pool.submitted] == ["<lambda>"]
    for _ in range(5):
        harness.tick()
        assert run.step() is None  # still loading: the skill yields, the tick goes on
    pool.finish(0)
    harness.tick()
    assert run.step() is None  # the reply is submitted in turn
    assert len(pool.submitted) == 2
    pool.finish(1)
    harness.tick()
    outcome = run.step()
    assert outcome is not None and outcome.name == "replied" and "Maya" in outcome.outputs["reply"]


def test_converse_times_out_while_the_chatbot_loads() -> None:
    harness = Harness(workers=Pending())
    outcome, ticks = harness.run(Converse({"alice": False}), text="hello", timeout=1.5)
    assert (outcome.name, ticks) == ("timeout", 15)
    assert "not loaded within 1.5 s" in outcome.reason


def test_a_broken_aiml_file_is_logged_once_per_run(harness: Harness, tmp_path: Path) -> None:
    broken = tmp_path / "broken.aiml"
    broken.write_text(AIML_HEAD + "<category><pattern>X</pattern>\n")
    skill = Converse({"alice": False, "aiml": [str(broken)]})
    assert harness.run(skill, text="hello")[0].name == "replied"
    assert harness.run(skill, text="hello")[0].name == "replied"
    warnings = [line for line in harness.logs if line.startswith("warning")]
    assert warnings == [f"warning: {broken}:4:1: error: not well-formed XML: no element found (file skipped)"]


def test_no_aiml_at_all_is_a_failure_with_its_reason(harness: Harness, tmp_path: Path, monkeypatch: Any) -> None:
    monkeypatch.setattr("botstage.skills.converse.aiml_files", lambda alice, extra: [tmp_path / "missing.aiml"])
    outcome, _ = harness.run(Converse(), text="hello")
    assert outcome.name == "failure"
    assert "no AIML category was learnt" in outcome.reason and "missing.aiml" in outcome.reason
