"""OpenCat's serial protocol: the host's commands, the board's replies, and what garbage does."""

from __future__ import annotations

import random

import pytest

from botstage.robots.drivers import opencat_protocol as opencat

# OpenCat 2 boots, then rests
BOOT = b"k\r\n\r\n* Start *\r\nBittle\r\nN_250224\r\nInit IMU\r\nSkill\r\nReady!\r\ng\r\nd\r\n"


def test_commands_are_what_the_firmware_reads() -> None:
    assert opencat.skill_command("wkF") == b"kwkF\n"
    assert opencat.REST == b"d\n"
    assert opencat.beep_command(12, 8) == b"b 12 8\n"
    assert opencat.joint_command({8: -20, 0: 30}) == b"i 0 30 8 -20\n"
    assert opencat.joint_command({0: 30}, together=False) == b"m 0 30\n"


@pytest.mark.parametrize("name", ["", "wk F", "wk\nF", "1wk", "w" * 17, "wkF;d", "wkF\u00e9"])
def test_a_skill_name_the_firmware_would_misread_is_refused(name: str) -> None:
    with pytest.raises(opencat.CommandError):
        opencat.skill_command(name)


@pytest.mark.parametrize(
    "call",
    [
        lambda: opencat.joint_command({16: 0}),
        lambda: opencat.joint_command({0: 126}),  # '~' (126) ends a binary command in OpenCat 2
        lambda: opencat.joint_command({}),
        lambda: opencat.beep_command(65, 8),
        lambda: opencat.token_command("k"),
        lambda: opencat.token_command("x"),
        lambda: opencat.token_command("m", True),
        lambda: opencat.token_command("m", *range(40)),
    ],
)
def test_bad_arguments_are_refused(call) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(opencat.CommandError):
        call()


def test_boot_text_acks_and_news_are_told_apart() -> None:
    decoder = opencat.ReplyDecoder()
    replies = decoder.feed(
        BOOT + b"k\r\nLow power:6V\r\ncheck battery\r\n?\r\nwrong key!\r\nOVF\r\n12.5\t-3.0\t0.25\r\nG\r\n"
    )
    assert replies[0] == opencat.Ack("k")
    assert opencat.Ready() in replies
    assert opencat.Text("Bittle") in replies
    tail = replies[replies.index(opencat.Ready()) + 1 :]
    assert tail == [
        opencat.Ack("g"),
        opencat.Ack("d"),
        opencat.Ack("k"),
        opencat.LowBattery(6),
        opencat.LowBattery(None),
        opencat.UnknownSkill(),
        opencat.UnknownSkill(),
        opencat.Overflow(),
        opencat.Attitude(12.5, -3.0, 0.25),
        opencat.Ack("G"),
    ]
    assert not decoder.bad


def test_lines_split_anywhere_decode_the_same() -> None:
    whole = opencat.ReplyDecoder().feed(BOOT)
    rng = random.Random(4)
    for _ in range(50):
        decoder, replies, at = opencat.ReplyDecoder(), [], 0
        while at < len(BOOT):
            step = rng.randint(1, 7)
            replies += decoder.feed(BOOT[at : at + step])
            at += step
        assert replies == whole


def test_garbage_is_dropped_counted_and_the_next_line_parses() -> None:
    decoder = opencat.ReplyDecoder()
    replies = decoder.feed(b"\x00\xff\x13k\r\n" + b"x" * 1000 + b"\r\nk\r\n\xe9t\xe9\r\n" + b"\x07" * 5000 + b"\nd\r\n")
    assert replies == [opencat.Ack("k"), opencat.Ack("d")]
    assert decoder.bad == {"control_bytes": 1, "too_long": 2, "not_ascii": 1}


def test_an_endless_line_is_bounded() -> None:
    decoder = opencat.ReplyDecoder()
    for _ in range(1000):
        assert decoder.feed(b"y" * 1000) == []
    assert len(decoder._partial) <= opencat.MAX_LINE  # memory stays bounded without a newline
    assert decoder.feed(b"\r\nk\r\n") == [opencat.Ack("k")]


def test_the_first_line_after_a_resync_is_counted_as_cut() -> None:
    decoder = opencat.ReplyDecoder()
    decoder.feed(b"Read")
    decoder.resync()
    assert decoder.feed(b"\x01y!\r\nk\r\n") == [opencat.Ack("k")]
    assert decoder.bad == {"cut": 1}


def test_the_board_reads_tokens_and_drops_what_it_would_misread() -> None:
    decoder = opencat.CommandDecoder()
    commands = decoder.feed(b"kwkF\nd\n\nb 12 8\r\nxyz\n" + b"k" + b"a" * 100 + b"\nkbal")
    assert commands == [
        opencat.Command("k", "wkF"),
        opencat.Command("d", ""),
        opencat.Command("b", "12 8"),
    ]
    assert decoder.feed(b"ance\n") == [opencat.Command("k", "balance")]
    assert decoder.bad == {"unknown_token": 1, "too_long": 1}
