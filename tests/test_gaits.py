"""Gait choice (the Bittle article's direction classes, linear first) and gait dead reckoning."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError

from botstage.robots import PROFILES_DIR
from botstage.robots.gaits import Direction, GaitOdometry, Gaits, choose, motion_of
from botstage.robots.interfaces import Pose2D
from botstage.robots.profile import load_profile


@pytest.fixture(scope="module")
def gaits() -> Gaits:
    profile, problems, _ = load_profile(PROFILES_DIR / "bittle.yaml")
    assert profile is not None and profile.gaits is not None, problems
    return profile.gaits


@pytest.mark.parametrize(
    ("v", "w", "skill", "direction"),
    [
        (0.1, 0.0, "wkF", Direction.FORWARD),
        (0.1, 0.4, "wkF", Direction.FORWARD),  # linear first: the turn is not taken while walking
        (-0.1, -0.4, "bk", Direction.BACK),
        (0.0, 0.4, "crL", Direction.LEFT),  # counter-clockwise is left (REP 103)
        (0.0, -0.4, "crR", Direction.RIGHT),
        (0.0, 0.0, "balance", Direction.STOP),
        (0.005, 0.02, "balance", Direction.STOP),  # under the dead bands: standing
    ],
)
def test_the_article_s_direction_classes(gaits: Gaits, v: float, w: float, skill: str, direction: Direction) -> None:
    choice = choose(gaits, v, w)
    assert (choice.skill, choice.direction) == (skill, direction)


@pytest.mark.parametrize(
    ("v", "skill"), [(0.02, "crF"), (0.07, "crF"), (0.08, "wkF"), (0.14, "wkF"), (0.16, "trF"), (5.0, "trF")]
)
def test_the_forward_gait_nearest_the_speed_asked_wins(gaits: Gaits, v: float, skill: str) -> None:
    choice = choose(gaits, v, 0.0)
    assert choice.skill == skill
    assert choice.v == motion_of(gaits, skill)[0] > 0  # the body goes at the gait's speed, not the one asked


def test_a_turn_moves_like_its_gait_and_right_mirrors_left(gaits: Gaits) -> None:
    left, right = choose(gaits, 0.0, 1.0), choose(gaits, 0.0, -1.0)
    assert left.w == -right.w == gaits.turn.turn_rate
    assert left.v == right.v == gaits.turn.speed
    assert motion_of(gaits, "crR") == (right.v, right.w)
    assert motion_of(gaits, "sit") == (0.0, 0.0)  # a posture stands still


def test_a_turning_gait_must_be_the_left_one() -> None:
    with pytest.raises(ValidationError, match="left variant"):
        Gaits.model_validate(
            {"forward": [{"skill": "wkF", "speed": 0.1}], "back": {"skill": "bk", "speed": 0.05},
             "turn": {"skill": "crR", "speed": 0.03, "turn_rate": 0.5}}
        )  # fmt: skip


def test_odometry_follows_the_arc_of_a_gait() -> None:
    odometry = GaitOdometry(Pose2D(1.0, 2.0, 0.0))
    odometry.advance(math.pi, 0.1, 0.5)  # half a turn... of a quarter circle
    radius = 0.1 / 0.5
    pose = odometry.pose
    assert pose.theta == pytest.approx(math.pi / 2)
    assert (pose.x, pose.y) == pytest.approx((1.0 + radius, 2.0 + radius))
    assert odometry.distance == pytest.approx(0.1 * math.pi)
    covariance = odometry.covariance
    assert covariance[2, 2] == pytest.approx((0.2 * math.pi / 2) ** 2 + 0.18**2 * 0.1 * math.pi)
    assert np.all(np.linalg.eigvalsh(covariance) > 0)  # heading doubt spreads position
    odometry.advance(2.0, -0.05, 0.0)  # straight back along the new heading
    assert (odometry.pose.x, odometry.pose.y) == pytest.approx((1.0 + radius, 2.0 + radius - 0.1))
