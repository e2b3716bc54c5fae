"""map_server maps: reading what ROS tooling writes, lossless round trips, clear errors."""

from __future__ import annotations

import math
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from botstage.robots.gridmap import FREE, OCCUPIED, UNKNOWN, GridMap, MapError, load, read_pgm, save, write_pgm

SHARED = Path(__file__).resolve().parents[2] / "shared" / "maps" / "tb3_sandbox.yaml"


@pytest.fixture
def tb3() -> Path:
    if not SHARED.exists():
        if os.environ.get("CI") == "true":
            pytest.fail(f"{SHARED} is missing: CI runs with ../shared beside the clone")
        pytest.skip("../shared/maps/tb3_sandbox.yaml is not beside this checkout")
    return SHARED


def test_reads_a_map_saved_by_ros_tooling(tb3: Path) -> None:
    grid = load(tb3)
    assert (grid.width, grid.height, grid.resolution, grid.origin) == (384, 384, 0.05, (-10.0, -10.0, 0.0))
    counts = {v: int((grid.data == v).sum()) for v in (UNKNOWN, FREE, OCCUPIED)}
    assert counts == {UNKNOWN: 138683, FREE: 7903, OCCUPIED: 870}  # 205, 254 and 0 pixels in the PGM
    rows, cols = np.nonzero(grid.data == FREE)
    cx, cy = grid.point(int(rows.mean()), int(cols.mean()))
    assert abs(cx) < 0.1 and abs(cy) < 0.1  # the arena is centred on the world origin
    assert grid.value_at(0.0, 0.0) == UNKNOWN  # the pillar in the middle of the sandbox
    assert grid.is_free(0.5, 0.0)


def test_round_trip_is_lossless(tb3: Path, tmp_path: Path) -> None:
    first = load(tb3)
    save(first, tmp_path / "copy.yaml")
    second = load(tmp_path / "copy.yaml")
    assert np.array_equal(first.data, second.data)
    assert (second.resolution, second.origin) == (first.resolution, first.origin)
    save(second, tmp_path / "again.yaml")
    assert (tmp_path / "again.pgm").read_bytes() == (tmp_path / "copy.pgm").read_bytes()


def write_map(folder: Path, pixels: np.ndarray, **header: object) -> Path:
    write_pgm(folder / "m.pgm", pixels)
    lines = {
        "image": "m.pgm",
        "resolution": 0.1,
        "origin": [1.0, 2.0, 0.0],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
        **header,
    }
    import yaml

    (folder / "m.yaml").write_text(yaml.safe_dump(lines))
    return folder / "m.yaml"


def test_interpretation_modes_and_orientation(tmp_path: Path) -> None:
    # top image row is the top of the map: row 0 of the grid is the image's last row
    pixels = np.array([[0, 254, 205], [254, 254, 128]], dtype=np.uint8)
    grid = load(write_map(tmp_path, pixels))
    assert grid.data.tolist() == [[FREE, FREE, UNKNOWN], [OCCUPIED, FREE, UNKNOWN]]
    negated = load(write_map(tmp_path, pixels, negate=1))
    assert negated.data.tolist() == [[OCCUPIED, OCCUPIED, UNKNOWN], [FREE, OCCUPIED, OCCUPIED]]  # 205 is p=0.8
    scaled = load(write_map(tmp_path, pixels, mode="scale"))
    assert scaled.data[0, 2] == round(99 * ((255 - 128) / 255 - 0.196) / (0.65 - 0.196))
    raw = load(write_map(tmp_path, pixels, mode="raw"))
    assert raw.data.tolist() == [[254, 254, 128], [0, 254, 205]]


def test_ascii_and_16_bit_pgm(tmp_path: Path) -> None:
    (tmp_path / "a.pgm").write_bytes(b"P2\n# made by hand\n2 1\n255\n0 254\n")
    pixels, maxval = read_pgm(tmp_path / "a.pgm")
    assert pixels.tolist() == [[0, 254]] and maxval == 255
    (tmp_path / "b.pgm").write_bytes(b"P5 2 1 65535\n" + np.array([0, 65535], dtype=">u2").tobytes())
    pixels, maxval = read_pgm(tmp_path / "b.pgm")
    assert pixels.tolist() == [[0, 65535]] and maxval == 65535


def test_cells_and_points_are_inverse_even_rotated() -> None:
    grid = GridMap(np.zeros((40, 60), dtype=np.int8), 0.05, (1.0, -2.0, math.radians(30)))
    for row, col in ((0, 0), (10, 20), (39, 59)):
        assert grid.cell(*grid.point(row, col)) == (row, col)
    assert not grid.inside(*grid.cell(-100, -100))
    assert grid.value_at(-100, -100) == UNKNOWN


@pytest.mark.parametrize(
    ("header", "field", "message"),
    [
        ({"image": None}, "image", "missing"),
        ({"image": "nope.pgm"}, "image", "the image file does not exist"),
        ({"image": "m.png"}, "image", "only PGM images are read so far"),
        ({"resolution": "fine"}, "resolution", "must be a number, got 'fine'"),
        ({"resolution": 0}, "resolution", "must be positive"),
        ({"origin": [1, 2]}, "origin", "must be [x, y, yaw]"),
        ({"origin": [float("nan"), 0, 0]}, "origin", "of finite numbers"),
        ({"negate": 2}, "negate", "must be 0 or 1"),
        ({"free_thresh": 0.9}, "free_thresh", "need 0 <= free_thresh"),
        ({"mode": "fuzzy"}, "mode", "must be one of trinary, scale, raw"),
    ],
)
def test_a_broken_header_names_the_file_and_field(tmp_path: Path, header: dict, field: str, message: str) -> None:
    path = write_map(tmp_path, np.zeros((2, 2), dtype=np.uint8), **header)
    if header.get("image") is None and "image" in header:
        path.write_text(path.read_text().replace("image: null\n", ""))
    with pytest.raises(MapError) as info:
        load(path)
    assert info.value.field == field
    assert message in str(info.value)
    assert str(info.value).startswith(str(tmp_path / ("nope.pgm" if header.get("image") == "nope.pgm" else "m.yaml")))


@pytest.mark.parametrize(
    ("content", "field", "message"),
    [
        (b"P6\n2 2\n255\n" + bytes(12), "header", "not a PGM image"),
        (b"P5\n2 two\n255\n" + bytes(4), "header", "must be numbers"),
        (b"P5\n2 2\n", "header", "the PGM header ends after 3 of 4 fields"),
        (b"P5\n2 2\n255\n" + bytes(3), "pixels", "truncated: 3 of 4 bytes"),
        (b"P2\n2 2\n255\n0 0 0\n", "pixels", "expected 4 values, found 3"),
        (b"P5\n0 2\n255\n", "header", "bad size"),
        (b"P2\n2 2\n255\n0 0 0 300\n", "pixels", "values must lie within 0..255"),
    ],
)
def test_a_broken_image_names_the_file_and_field(tmp_path: Path, content: bytes, field: str, message: str) -> None:
    path = write_map(tmp_path, np.zeros((2, 2), dtype=np.uint8))
    (tmp_path / "m.pgm").write_bytes(content)
    with pytest.raises(MapError) as info:
        load(path)
    assert (info.value.field, info.value.file) == (field, str(tmp_path / "m.pgm"))
    assert message in str(info.value)


def test_the_image_given_instead_of_the_header(tmp_path: Path) -> None:
    write_pgm(tmp_path / "m.pgm", np.full((4, 4), 254, dtype=np.uint8))
    with pytest.raises(MapError, match="not a YAML header"):
        load(tmp_path / "m.pgm")


def test_missing_and_malformed_map_files(tmp_path: Path) -> None:
    with pytest.raises(MapError, match="no such map file"):
        load(tmp_path / "absent.yaml")
    (tmp_path / "bad.yaml").write_text("image: [unclosed\n")
    with pytest.raises(MapError, match="header: not valid YAML at line 2"):
        load(tmp_path / "bad.yaml")


def test_named_places_travel_with_the_map(tmp_path: Path) -> None:
    pixels = np.full((20, 20), 254, dtype=np.uint8)
    pixels[:, 10] = 0  # a wall down the middle (image column 10)
    path = write_map(tmp_path, pixels)
    (tmp_path / "m.places.yaml").write_text("places:\n  left: [1.5, 3.0]\n  right: [2.5, 3.0, 1.57]\n")
    grid = load(path)
    assert grid.places == {"left": (1.5, 3.0, 0.0), "right": (2.5, 3.0, 1.57)}
    save(grid, tmp_path / "copy.yaml")
    assert load(tmp_path / "copy.yaml").places == grid.places
    (tmp_path / "m.places.yaml").write_text("places:\n  in_wall: [2.05, 3.0]\n")
    with pytest.raises(MapError, match=r"places.in_wall: \(2.05, 3\) is not on a free cell"):
        load(path)
    shutil.rmtree(tmp_path / "unused", ignore_errors=True)


def test_points_far_off_the_map_are_outside_not_an_overflow() -> None:
    grid = GridMap(np.zeros((4, 4), dtype=np.uint8), 0.5, (0.0, 0.0, 0.0))
    for x, y in ((1e308, 1.0), (math.inf, 0.0), (math.nan, 1.0), (1.0, -math.inf)):
        assert not grid.inside(*grid.cell(x, y))
        assert not grid.is_free(x, y)
