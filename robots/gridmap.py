"""Occupancy grid maps in the ROS map_server format (a YAML header and a PGM image).

Reads what map_saver writes (and hand-made maps): ``image``, ``resolution``, ``origin``,
``negate``, ``occupied_thresh``, ``free_thresh`` and ``mode`` (trinary, scale or raw), with the
same interpretation as map_server: image row 0 is the top of the map, the grid's row 0 its
bottom, and ``origin`` is the pose of the lower-left cell. Writes the way map_saver does
(0 occupied, 254 free, 205 unknown), so a load-save-load round trip is lossless.

Every problem is a ``MapError`` naming the file and the field.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from botstage.robots.limits import MAX_IMAGE_BYTES
from botstage.robots.located_yaml import FileRefused, NotText, YamlProblem, find_yaml, load_data, read_bytes

FREE, OCCUPIED, UNKNOWN = 0, 100, -1
MODES = ("trinary", "scale", "raw")
_SAVE_OCCUPIED, _SAVE_FREE, _SAVE_UNKNOWN = 0, 254, 205


class MapError(ValueError):
    def __init__(self, file: str | Path, field: str, message: str) -> None:
        self.file = str(file)
        self.field = field
        super().__init__(f"{file}: {field}: {message}")


_FAR = 2**40  # cells: any point farther is simply off the map


@dataclass
class GridMap:
    """``data[row, col]``: 0 free, 100 occupied, -1 unknown (trinary); row 0 is the bottom."""

    data: np.ndarray
    resolution: float
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    negate: bool = False
    occupied_thresh: float = 0.65
    free_thresh: float = 0.196
    mode: str = "trinary"
    places: dict[str, tuple[float, float, float]] = field(default_factory=dict)

    @property
    def height(self) -> int:
        return int(self.data.shape[0])

    @property
    def width(self) -> int:
        return int(self.data.shape[1])

    def cell(self, x: float, y: float) -> tuple[int, int]:
        """(row, col) of the cell holding world point (x, y); may lie outside the grid."""
        ox, oy, yaw = self.origin
        dx, dy = x - ox, y - oy
        if yaw:
            c, s = math.cos(-yaw), math.sin(-yaw)
            dx, dy = c * dx - s * dy, s * dx + c * dy
        row, col = dy / self.resolution, dx / self.resolution
        if not (abs(row) < _FAR and abs(col) < _FAR):  # inf, nan, 1e308: off the map, not an overflow
            return -1, -1
        return math.floor(row), math.floor(col)

    def cells(self, xs: np.ndarray, ys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``cell`` for arrays of points: (rows, cols), possibly outside the grid."""
        ox, oy, yaw = self.origin
        dx, dy = np.asarray(xs, dtype=float) - ox, np.asarray(ys, dtype=float) - oy
        if yaw:
            c, s = math.cos(-yaw), math.sin(-yaw)
            dx, dy = c * dx - s * dy, s * dx + c * dy
        return np.floor(dy / self.resolution).astype(np.int64), np.floor(dx / self.resolution).astype(np.int64)

    def point(self, row: int, col: int) -> tuple[float, float]:
        """World coordinates of a cell's centre."""
        ox, oy, yaw = self.origin
        dx, dy = (col + 0.5) * self.resolution, (row + 0.5) * self.resolution
        if yaw:
            c, s = math.cos(yaw), math.sin(yaw)
            dx, dy = c * dx - s * dy, s * dx + c * dy
        return ox + dx, oy + dy

    def inside(self, row: int, col: int) -> bool:
        return 0 <= row < self.height and 0 <= col < self.width

    def value_at(self, x: float, y: float) -> int:
        """The cell's value at a world point; outside the map counts as unknown."""
        row, col = self.cell(x, y)
        return int(self.data[row, col]) if self.inside(row, col) else UNKNOWN

    def is_free(self, x: float, y: float) -> bool:
        return self.value_at(x, y) == FREE


# -- PGM --------------------------------------------------------------------------------------


def read_pgm(path: Path) -> tuple[np.ndarray, int]:
    """A PGM image (binary P5 or ASCII P2, 8 or 16 bit) as a 2-D array, top row first, and its maxval."""
    try:
        raw = read_bytes(path, MAX_IMAGE_BYTES, "map image")  # regular files only, bounded
    except FileNotFoundError:
        raise MapError(path, "image", "the image file does not exist") from None
    except FileRefused as exc:
        raise MapError(path, "image", f"cannot read it: {exc}") from None
    except OSError as exc:
        raise MapError(path, "image", f"cannot read it: {exc.strerror}") from None
    tokens: list[bytes] = []
    position = 0
    while len(tokens) < 4:
        while position < len(raw) and raw[position : position + 1].isspace():
            position += 1
        if raw[position : position + 1] == b"#":  # a comment runs to the end of its line
            end = raw.find(b"\n", position)
            position = len(raw) if end < 0 else end + 1
            continue
        start = position
        while (
            position < len(raw) and not raw[position : position + 1].isspace() and raw[position : position + 1] != b"#"
        ):
            position += 1
        if start == position:
            raise MapError(path, "header", f"the PGM header ends after {len(tokens)} of 4 fields")
        tokens.append(raw[start:position])
    magic = tokens[0]
    if magic not in (b"P5", b"P2"):
        raise MapError(path, "header", f"not a PGM image (magic {magic[:8]!r}, expected P5 or P2)")
    try:
        width, height, maxval = (int(t) for t in tokens[1:])
    except ValueError:
        raise MapError(path, "header", f"width, height and maxval must be numbers, got {tokens[1:]!r}") from None
    if width <= 0 or height <= 0 or not 0 < maxval < 65536:
        raise MapError(path, "header", f"bad size {width}x{height} or maxval {maxval}")
    if magic == b"P2":
        try:
            values = np.array(raw[position:].split(), dtype=np.int64)
        except ValueError:
            raise MapError(path, "pixels", "ASCII pixel values must be numbers") from None
        if values.size != width * height:
            raise MapError(path, "pixels", f"expected {width * height} values, found {values.size}")
        if values.size and (values.min() < 0 or values.max() > maxval):
            raise MapError(path, "pixels", f"values must lie within 0..{maxval}")
        return values.reshape(height, width), maxval
    position += 1  # exactly one whitespace byte after maxval
    dtype = np.dtype(np.uint8) if maxval < 256 else np.dtype(">u2")
    needed = width * height * dtype.itemsize
    body = raw[position : position + needed]
    if len(body) < needed:
        raise MapError(path, "pixels", f"the image is truncated: {len(body)} of {needed} bytes")
    return np.frombuffer(body, dtype=dtype).reshape(height, width).astype(np.int64), maxval


def write_pgm(path: Path, pixels: np.ndarray, comment: str = "") -> None:
    height, width = pixels.shape
    header = b"P5\n" + (f"# {comment}\n".encode() if comment else b"") + f"{width} {height}\n255\n".encode()
    path.write_bytes(header + pixels.astype(np.uint8).tobytes())


# -- map_server YAML -----------------------------------------------------------------------------


def _number(header: dict[str, Any], name: str, file: Path, default: Any = None) -> float:
    if name not in header:
        if default is None:
            raise MapError(file, name, "missing")
        return default
    value = header[name]
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise MapError(file, name, f"must be a number, got {value!r}")
    return float(value)


def load(path: str | Path) -> GridMap:
    """Load a map_server map (and its ``<name>.places.yaml`` beside it, if any)."""
    path = Path(path)
    try:
        header = load_data(path)  # bounded like every YAML file botstage reads
    except FileNotFoundError:
        raise MapError(path, "file", "no such map file") from None
    except NotText:
        raise MapError(path, "file", "not a YAML header (is this the image? give the .yaml beside it)") from None
    except (FileRefused, OSError) as exc:
        raise MapError(path, "file", f"cannot read it: {exc}") from None
    except YamlProblem as exc:
        problem = exc.problem
        raise MapError(path, "header", f"not valid YAML at line {problem.location.line}: {problem.message}") from None
    if not isinstance(header, dict):
        raise MapError(path, "header", "a map header is a mapping (image:, resolution:, origin:, ...)")
    image = header.get("image")
    if not isinstance(image, str) or not image:
        raise MapError(path, "image", "missing" if image is None else f"must be a file name, got {image!r}")
    resolution = _number(header, "resolution", path)
    if resolution <= 0:
        raise MapError(path, "resolution", f"must be positive, got {resolution}")
    origin = header.get("origin")
    if not (
        isinstance(origin, list)
        and len(origin) == 3
        and all(isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in origin)
    ):
        raise MapError(path, "origin", f"must be [x, y, yaw] of finite numbers, got {origin!r}")
    negate = header.get("negate", 0)
    if negate not in (0, 1, True, False):
        raise MapError(path, "negate", f"must be 0 or 1, got {negate!r}")
    occupied = _number(header, "occupied_thresh", path, 0.65)
    free = _number(header, "free_thresh", path, 0.196)
    if not 0 <= free <= occupied <= 1:
        raise MapError(path, "free_thresh", f"need 0 <= free_thresh ({free}) <= occupied_thresh ({occupied}) <= 1")
    mode = header.get("mode", "trinary")
    if mode not in MODES:
        raise MapError(path, "mode", f"must be one of {', '.join(MODES)}, got {mode!r}")
    image_path = path.parent / image
    if image_path.suffix.lower() != ".pgm":
        raise MapError(path, "image", f"{image!r}: only PGM images are read so far (save PNG maps as PGM)")
    pixels, maxval = read_pgm(image_path)
    p = pixels / maxval if negate else (maxval - pixels) / maxval  # occupancy probability per pixel
    if mode == "raw":
        data = pixels
    else:
        data = np.full(p.shape, UNKNOWN, dtype=np.int64)
        data[p > occupied] = OCCUPIED
        data[p < free] = FREE
        if mode == "scale":
            between = (p >= free) & (p <= occupied)
            data[between] = np.rint(99 * (p[between] - free) / (occupied - free)).astype(np.int64)
    grid = GridMap(
        np.flipud(data).astype(np.int8 if mode != "raw" else np.int64).copy(),
        resolution,
        (float(origin[0]), float(origin[1]), float(origin[2])),
        bool(negate),
        occupied,
        free,
        mode,
    )
    places_path = path.with_name(path.stem + ".places.yaml")
    if places_path.exists():
        grid.places = load_places(places_path, grid)
    return grid


def save(grid: GridMap, path: str | Path) -> None:
    """Write ``<path>`` (YAML) and its PGM beside it, as map_saver does (trinary)."""
    path = Path(path)
    image = path.with_suffix(".pgm")
    pixels = np.full(grid.data.shape, _SAVE_UNKNOWN, dtype=np.uint8)
    pixels[grid.data == OCCUPIED] = _SAVE_OCCUPIED
    pixels[grid.data == FREE] = _SAVE_FREE
    write_pgm(image, np.flipud(pixels), f"CREATOR: botstage {grid.resolution:.3f} m/pix")
    header = {
        "image": image.name,
        "mode": "trinary",
        "resolution": grid.resolution,
        "origin": [float(v) for v in grid.origin],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
    }
    path.write_text(yaml.safe_dump(header, sort_keys=False), encoding="utf-8")
    if grid.places:
        places = {name: [float(v) for v in pose] for name, pose in grid.places.items()}
        path.with_name(path.stem + ".places.yaml").write_text(yaml.safe_dump({"places": places}, sort_keys=False))


def load_places(path: Path, grid: GridMap) -> dict[str, tuple[float, float, float]]:
    """Named places: ``places: {name: [x, y, yaw]}``, each on a free cell of the map."""
    try:
        content = load_data(path)
    except (OSError, ValueError):
        raise MapError(path, "places", "not valid YAML") from None
    places = content.get("places") if isinstance(content, dict) else None
    if not isinstance(places, dict):
        raise MapError(path, "places", "expected `places: {name: [x, y, yaw]}`")
    found: dict[str, tuple[float, float, float]] = {}
    for name, pose in places.items():
        if not (
            isinstance(pose, list)
            and len(pose) in (2, 3)
            and all(isinstance(v, int | float) and not isinstance(v, bool) for v in pose)
        ):
            raise MapError(path, f"places.{name}", f"must be [x, y] or [x, y, yaw], got {pose!r}")
        x, y, yaw = (float(v) for v in (*pose, 0.0)[:3])
        if not grid.is_free(x, y):
            raise MapError(path, f"places.{name}", f"({x:g}, {y:g}) is not on a free cell of the map")
        found[str(name)] = (x, y, yaw)
    return found


MAPS_DIR = Path(__file__).resolve().parent / "maps"  # the maps botstage ships


def known_maps() -> list[str]:
    return sorted(p.stem for p in MAPS_DIR.glob("*.yaml") if not p.name.endswith(".places.yaml"))


def map_path(name_or_path: str, relative_to: Path | None = None) -> Path | None:
    """The map a mission's `world:` names: a shipped map's name, or a map YAML's path."""
    return find_yaml(name_or_path, MAPS_DIR, known_maps(), relative_to)
