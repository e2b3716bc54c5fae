"""Robot profiles: the shipped ones, located errors for broken ones, and missions that name them."""

from __future__ import annotations

from pathlib import Path

import pytest

from botstage.missions.check import check
from botstage.robots.profile import known_profiles, load_profile

CHEFBOT = Path("robots/profiles/chefbot.yaml")


def test_shipped_profiles_load_with_the_books_figures() -> None:
    assert known_profiles() == ["bittle", "chefbot", "face_tracker", "peoplebot"]
    chefbot, problems, _ = load_profile(CHEFBOT)
    assert problems == [] and chefbot is not None
    base = chefbot.base
    assert (base.wheel_diameter, base.wheel_separation, base.max_wheel_rpm, base.max_linear, base.payload) == (
        0.09,
        0.30,
        80,
        0.35,
        2.0,
    )
    assert (chefbot.battery.nominal_voltage, chefbot.battery.capacity_ah) == (12.0, 10.0)
    # laser: the depth scan; speaker and microphone: on its PC, for the delivery mission
    assert set(chefbot.interfaces) == {"drive", "odometry", "imu", "sonar", "battery", "laser", "speaker", "microphone"}
    assert base.ticks_per_metre == pytest.approx(4480 / (3.141592653589793 * 0.09))
    peoplebot, problems, _ = load_profile(Path("robots/profiles/peoplebot.yaml"))
    assert problems == [] and peoplebot is not None
    people = peoplebot.interfaces["people"]
    assert (people.range_min, people.range_max) == (0.8, 4.0)
    assert {"laser", "people", "camera", "microphone", "display"} <= set(peoplebot.interfaces)


def broken(tmp_path: Path, old: str, new: str) -> list[str]:
    text = CHEFBOT.read_text()
    assert old in text
    path = tmp_path / "bot.yaml"
    path.write_text(text.replace(old, new))
    _, problems, _ = load_profile(path)
    return [str(p).replace(str(tmp_path) + "/", "") for p in problems]


@pytest.mark.parametrize(
    ("old", "new", "expected"),
    [
        (
            "  max_linear: 0.35",
            "  max_linear: 0.5",
            "bot.yaml:14:3: error: 0.5 m/s is faster than the wheels can turn: 80 RPM on 0.09 m wheels give 0.377 m/s",
        ),
        (
            "  max_angular: 2.0 ",
            "  max_angular: 3.0 ",
            "bot.yaml:15:3: error: 3.0 rad/s is faster than the wheels allow (2.51 rad/s turning on the spot)",
        ),
        (
            "  mass: 3.0",
            "  mass: heavy",
            "bot.yaml:20:3: error: base.mass: Input should be a valid number, unable to parse string as a number",
        ),
        ("  payload: 2.0", "  payload: 2.0\n  wheels: 4", "bot.yaml:22:3: error: unknown key 'wheels'"),
        (
            "  battery: {hardware: launchpad}",
            "  jetpack: {hardware: launchpad}",
            "bot.yaml:35:3: error: unknown interface 'jetpack' (known: drive, odometry, imu, laser, sonar, battery, "
            "people, camera, microphone, speaker, display, pan)",
        ),
        (
            "range_min: 0.02, range_max: 4.0",
            "range_min: 5.0, range_max: 4.0",
            "bot.yaml:33:72: error: must be below range_max",
        ),
        ("  empty_voltage: 10.5", "  empty_voltage: 13.0", "bot.yaml:26:3: error: must be below full_voltage"),
        ("  wheel_diameter: 0.09\n", "", "bot.yaml:8:1: error: base: a differential base needs wheel_diameter"),
        (
            "skills: {}",
            "skills: {}\ngaits: {forward: [{skill: wkF, speed: 0.1}], back: {skill: bk, speed: 0.05}, "
            "turn: {skill: crL, speed: 0.03, turn_rate: 0.5}}",
            "bot.yaml:45:1: error: only a legged base walks in gaits; this one is differential",
        ),
    ],
)
def test_broken_profiles_give_located_errors(tmp_path: Path, old: str, new: str, expected: str) -> None:
    assert expected in broken(tmp_path, old, new)


def test_missions_name_robots_by_profile_or_path(tmp_path: Path) -> None:
    mission = tmp_path / "m.yaml"
    body = "trees:\n  main: {wait: {duration: 1}}\n"
    mission.write_text("robot: chefbot\n" + body)
    assert check(mission).problems == []
    mission.write_text("robot: chefbto\n" + body)
    assert [str(p) for p in check(mission).problems] == [
        f"{mission}:1:1: error: unknown robot 'chefbto' (did you mean 'chefbot'?)"
    ]
    (tmp_path / "mine.yaml").write_text(CHEFBOT.read_text().replace("skills: {}", "skills:\n  wait: {speed: 2}"))
    mission.write_text("robot: mine.yaml\n" + body)
    line = CHEFBOT.read_text().splitlines().index("skills: {}") + 2  # the line of `wait:` below it
    assert [str(p).replace(str(tmp_path) + "/", "") for p in check(mission).problems] == [
        f"mine.yaml:{line}:3: error: parameter of 'wait': Extra inputs are not permitted"
    ]
    mission.write_text("world: museum\n" + body)
    assert "a world needs a robot to put in it" in str(check(mission).problems[0])


BITTLE = Path("robots/profiles/bittle.yaml")


def test_bittle_is_a_legged_base_that_walks_in_gaits() -> None:
    bittle, problems, _ = load_profile(BITTLE)
    assert problems == [] and bittle is not None and bittle.gaits is not None
    assert bittle.base.kind == "legged"
    assert [g.skill for g in bittle.gaits.forward] == ["crF", "wkF", "trF"]
    assert bittle.gaits.fastest == bittle.base.max_linear  # the limit is the fastest gait
    assert bittle.interfaces["drive"].hardware == "nyboard"
    assert bittle.backends["hardware"]["baud"] == 115200  # the article's (its repository says 57600)
    # the simulator's stand-in wheels never limit a gait
    assert bittle.base.wheel_top_speed >= bittle.base.max_linear + bittle.base.max_angular * 0.04


@pytest.mark.parametrize(
    ("old", "new", "expected"),
    [
        (
            "  mass: 0.29",
            "  mass: 0.29\n  wheel_diameter: 0.05",
            "base: a legged base has no wheels: remove wheel_diameter",
        ),
        ("{skill: crL, speed: 0.03, turn_rate: 0.5}", "{skill: crR, speed: 0.03, turn_rate: 0.5}", "left variant"),
        ("{skill: wkF, speed: 0.10}", "{skill: 'wk F', speed: 0.10}", "gaits.forward.1.skill: String should match"),
    ],
)
def test_broken_legged_profiles_give_located_errors(tmp_path: Path, old: str, new: str, expected: str) -> None:
    text = BITTLE.read_text()
    assert old in text
    path = tmp_path / "dog.yaml"
    path.write_text(text.replace(old, new))
    _, problems, _ = load_profile(path)
    assert any(expected in str(p) for p in problems), problems


def test_a_legged_base_without_gaits_is_refused(tmp_path: Path) -> None:
    text = BITTLE.read_text()
    path = tmp_path / "dog.yaml"
    path.write_text(text[: text.index("gaits:")] + text[text.index("interfaces:") :])
    _, problems, _ = load_profile(path)
    assert [str(p).replace(str(tmp_path) + "/", "") for p in problems] == [
        "dog.yaml:12:3: error: a legged base needs gaits: (which skill walks how fast: robots/gaits.py)"
    ]
