"""What the simulated camera sees: a pinhole perspective view of the map and the people in it.

Good enough for OpenCV detectors to run on, not a graphics engine. The scene is 2.5D, as the
grid is: every blocked cell is a wall from the floor to ``WALL_HEIGHT``, and everyone stands
upright on the floor facing the camera. What is drawn, and why:

- **Walls** by casting one ray per image column across the padded hit grid (the laser's
  ``RAY_STEP`` and refinement, all columns at once with numpy), projected with the pinhole model
  from the ray's depth along the optical axis (not its length, so straight walls stay straight).
  A wall is darker with distance and darker on faces along the map's x axis than on those along
  its y axis, so corners and edges show as they would under real light.
- **Floor and ceiling** as fixed gradients (darker towards the horizon), the same every frame.
- **People** as upright figures ``PERSON_HEIGHT`` tall: legs, a body in a colour that follows
  their id, arms, and a head with a frontal face (skin, hair, eyebrows, eyes, nose shadow, mouth)
  that OpenCV's Haar frontal-face cascade detects from 1.5 m (nearer, the level camera cuts off
  the head) to 4 m and more. They are painted far to
  near, each only in the image columns where no wall is nearer than the person.

A camera ``mounted_on`` the pan turns with it: it looks along the base's yaw, plus its pose's
yaw, plus the pan's present angle (``render(..., pan=angle)``). It turns about its own position
(decision: the lens sits a few centimetres from the AX-12A's axis in the book's bracket, too little
to shift the view of a person a metre or more away).

The camera is level, its device's ``mount_height`` above the floor (``CAMERA_HEIGHT`` when the
profile gives none), at the device's pose on the base, with square pixels. Its view may be
raised by ``look_up`` radians as a shifted lens raises it (the horizon sits that far below the
image centre and verticals stay vertical): a low camera, such as the one on Bittle, sees the faces
of the people standing before it. The focal length is ``CameraInfo.focal_px``. The view is
a function of the world's state alone (no randomness), except for optional sensor noise: a
device ``noise`` is the standard deviation in grey levels, drawn from ``world.noise("camera")``
(``add_grain``).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from functools import lru_cache
from typing import Protocol

import cv2
import numpy as np

from botstage.robots.profile import Device
from botstage.robots.sim.world import RAY_STEP, World

CAMERA_HEIGHT = 1.0  # m: a decision (a Kinect on a PeopleBot's mast); the paper gives no height
WALL_HEIGHT = 2.5  # m: every blocked cell, exhibit plinths included
PERSON_HEIGHT = 1.7  # m, to the top of the hair
PERSON_HALF_WIDTH = 0.3  # m: the widest part of a figure (the arms), for its bounding box
NEAR = 0.15  # m: people nearer the lens than this are not drawn

DEFAULT_WIDTH, DEFAULT_HEIGHT, DEFAULT_FOV = 640, 480, 1.085  # a Kinect's RGB camera

CEILING = np.array([200, 196, 190], np.float32)  # BGR
FLOOR = np.array([92, 118, 140], np.float32)  # a wooden floor
WALL = np.array([178, 206, 222], np.float32)  # cream
FOG = 0.07  # shade = 1 / (1 + FOG * distance): far things are darker

# Looks that follow a person's id (BGR): skin, hair and trousers by id modulo 5, 7 and 3, and the
# shirt shifting against the hair every 7 ids, so neighbours' ids look different and the
# combinations repeat only after 735 people.
SKINS = [(150, 185, 225), (115, 155, 205), (85, 120, 170), (70, 100, 145), (135, 170, 215)]
HAIRS = [(25, 25, 30), (30, 55, 95), (45, 105, 160), (120, 120, 125), (20, 35, 60), (45, 45, 50), (15, 20, 35)]
SHIRTS = [(40, 40, 200), (180, 90, 30), (50, 160, 50), (30, 170, 220), (140, 40, 140), (200, 200, 200), (60, 60, 60)]
TROUSERS = [(70, 50, 40), (40, 40, 40), (110, 90, 60)]
SUBPIXEL = 4  # cv2's ``shift``: coordinates in sixteenths of a pixel, so small faces keep their shape


class Standing(Protocol):
    """Anyone the camera can draw: a crowd's ``Person`` fits."""

    id: int
    x: float
    y: float


class CameraView:
    """Renders frames for one camera device; what depends only on the device is computed once."""

    def __init__(self, device: Device) -> None:
        self.device = device
        self.width = device.width or DEFAULT_WIDTH
        self.height = device.height or DEFAULT_HEIGHT
        self.fov = device.field_of_view or DEFAULT_FOV
        if not self.fov < math.pi:
            raise ValueError(f"a pinhole camera's field of view must be under pi rad, got {self.fov}")
        self.focal = (self.width / 2) / math.tan(self.fov / 2)
        self.mount = device.mount_height or CAMERA_HEIGHT
        self.horizon = self.height / 2 + self.focal * math.tan(device.look_up or 0.0)  # the row at the lens's height
        # the ray through each column's centre, as an angle to the left of the optical axis
        self.offsets = np.arctan((self.width / 2 - (np.arange(self.width) + 0.5)) / self.focal)
        self.axis_cos = np.cos(self.offsets)  # ray length to depth along the optical axis
        self.background = _background(self.width, self.height, self.focal, self.horizon, self.mount)
        self.row_centres = (np.arange(self.height, dtype=np.float32) + 0.5)[:, None]

    def camera_pose(self, world: World, pan: float = 0.0) -> tuple[float, float, float]:
        """Where the camera is in the world: the device's pose on the robot's true pose, turned by
        ``pan`` rad (counter-clockwise) when it rides on a pan joint."""
        mx, my, mtheta = self.device.pose
        pose = world.body.pose
        c, s = math.cos(pose.theta), math.sin(pose.theta)
        return pose.x + c * mx - s * my, pose.y + s * mx + c * my, pose.theta + mtheta + pan

    def render(self, world: World, people: Iterable[Standing] = (), pan: float = 0.0) -> np.ndarray:
        """One BGR frame (height x width x 3, uint8) of the world as it is now, the camera turned
        ``pan`` rad on its joint."""
        x, y, heading = self.camera_pose(world, pan)
        distance, along_x = wall_distances(world, x, y, heading + self.offsets)
        depth = distance * self.axis_cos
        frame = self._walls(depth, along_x)
        self._people(frame, depth, x, y, heading, people)
        if self.device.noise:
            frame = add_grain(frame, world.noise("camera"), self.device.noise)
        return frame

    # -- walls --------------------------------------------------------------------------------

    def _walls(self, depth: np.ndarray, along_x: np.ndarray) -> np.ndarray:
        horizon, f = self.horizon, self.focal
        top = (horizon - f * (WALL_HEIGHT - self.mount) / depth).astype(np.float32)
        bottom = (horizon + f * self.mount / depth).astype(np.float32)
        shade = (np.where(along_x, 0.72, 1.0) / (1.0 + FOG * depth)).astype(np.float32)
        colours = np.zeros((self.width, 4), np.uint8)
        colours[:, :3] = WALL[None, :] * shade[:, None]
        wall = (self.row_centres >= top) & (self.row_centres < bottom)
        # one 32-bit word a pixel: choosing words is several times faster than choosing bytes
        packed = np.where(wall, colours.view(np.uint32)[:, 0][None, :], self.background)
        return cv2.cvtColor(packed.view(np.uint8).reshape(self.height, self.width, 4), cv2.COLOR_BGRA2BGR)

    # -- people -------------------------------------------------------------------------------

    def _people(
        self, frame: np.ndarray, depth: np.ndarray, x: float, y: float, heading: float, people: Iterable[Standing]
    ) -> None:
        c, s = math.cos(heading), math.sin(heading)
        placed = []
        for person in people:
            dx, dy = person.x - x, person.y - y
            forward, right = dx * c + dy * s, dx * s - dy * c
            if forward < NEAR:
                continue  # behind the camera, or in the lens
            u = self.width / 2 + self.focal * right / forward
            half = self.focal * PERSON_HALF_WIDTH / forward
            if u + half < 0 or u - half > self.width:
                continue  # outside the field of view
            placed.append((forward, u, person.id))
        for forward, u, pid in sorted(placed, reverse=True):  # painter's order: far to near
            self._figure(frame, depth, forward, u, pid)

    def _figure(self, frame: np.ndarray, depth: np.ndarray, forward: float, u: float, pid: int) -> None:
        """Draw one person into a copy of their bounding box, then keep the columns no wall hides."""
        scale = self.focal / forward  # pixels per metre at the person's depth
        horizon = self.horizon
        x0 = max(0, math.floor(u - PERSON_HALF_WIDTH * scale))
        x1 = min(self.width, math.ceil(u + PERSON_HALF_WIDTH * scale) + 1)
        y0 = max(0, math.floor(horizon - (PERSON_HEIGHT + 0.05 - self.mount) * scale))
        y1 = min(self.height, math.ceil(horizon + self.mount * scale) + 1)
        visible = depth[x0:x1] > forward
        if x1 <= x0 or y1 <= y0 or not visible.any():
            return
        box = np.ascontiguousarray(frame[y0:y1, x0:x1])
        draw_person(box, u - x0, horizon - y0, scale, pid, self.mount)
        frame[y0:y1, x0:x1][:, visible] = box[:, visible]


GRAIN_BITS = 16  # fair bits counted per pixel and channel: a binomial with standard deviation 2


def add_grain(frame: np.ndarray, rng: np.random.Generator, std: float) -> np.ndarray:
    """``frame`` with zero-mean sensor grain of standard deviation ``std`` grey levels per pixel
    and channel, clipped to 0-255.

    The grain is a count of 16 random bits less 8 (a binomial: standard deviation 2, as close to
    Gaussian as sensor noise needs), scaled to ``std``: five times cheaper to draw than
    ``normal()`` at 640x480 (4 against 21 ms), which is most of what a simulated frame costs."""
    bits = rng.integers(0, 1 << GRAIN_BITS, size=frame.shape, dtype=np.uint16)
    grain = np.bitwise_count(bits).astype(np.int16) - GRAIN_BITS // 2
    if std == 2.0:
        return np.clip(frame.astype(np.int16) + grain, 0, 255).astype(np.uint8)
    return np.clip(np.rint(frame + grain * np.float32(std / 2.0)), 0, 255).astype(np.uint8)


def render_view(world: World, people: Iterable[Standing], device: Device) -> np.ndarray:
    """One frame from ``device`` on the robot (build a ``CameraView`` once to render many)."""
    return CameraView(device).render(world, people)


def wall_distances(world: World, x: float, y: float, angles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """How far each ray from (x, y) runs before it meets a blocked cell, and whether the face it
    meets runs along the map's x axis (a row boundary), for shading.

    ``World.cast`` marches the rays; six halvings refine the surface to under a millimetre, fine
    enough that the last stretch of a ray crosses a second cell boundary only at a corner."""
    halvings = 6
    high = world.cast(x, y, angles, halvings=halvings)  # off the map is a hit: every ray ends
    low = high - RAY_STEP * world.grid.resolution / 2**halvings
    cos, sin = np.cos(angles), np.sin(angles)
    rows_in, _ = world.padded_cells(x + cos * high, y + sin * high)
    rows_out, _ = world.padded_cells(x + cos * low, y + sin * low)
    return high, rows_in != rows_out


@lru_cache(maxsize=8)
def _background(width: int, height: int, focal: float, horizon: float, mount: float) -> np.ndarray:
    """Ceiling above the horizon and floor below, each darker towards it: BGR and a spare byte
    packed in one uint32 a pixel (read-only, shared)."""
    rows = np.arange(height) + 0.5 - horizon
    floor_distance = focal * mount / np.maximum(rows, 1e-6)
    ceiling_distance = focal * (WALL_HEIGHT - mount) / np.maximum(-rows, 1e-6)
    floor = FLOOR[None, :] / (1.0 + FOG * floor_distance[:, None])
    ceiling = CEILING[None, :] / (1.0 + 0.5 * FOG * ceiling_distance[:, None])
    column = np.zeros((height, 4), np.uint8)
    column[:, :3] = np.where((rows > 0)[:, None], floor, ceiling)
    image = np.ascontiguousarray(np.broadcast_to(column.view(np.uint32), (height, width)))
    image.setflags(write=False)
    return image


def draw_person(
    image: np.ndarray, u: float, horizon: float, scale: float, pid: int, camera_height: float = CAMERA_HEIGHT
) -> None:
    """Draw a person facing the camera: ``u`` the image column of their centre line, ``horizon``
    the row at the camera's height (``camera_height`` m above the floor), ``scale`` pixels per
    metre at their depth. Only cv2 primitives,
    sized from metres, so one figure serves every distance."""
    k = 1 << SUBPIXEL

    def at(side: float, up: float) -> tuple[int, int]:
        """(side m right of the centre line, up m above the floor) to fixed-point pixels."""
        return round((u + side * scale) * k), round((horizon - (up - camera_height) * scale) * k)

    def size(a: float, b: float) -> tuple[int, int]:
        return max(1, round(a * scale * k)), max(1, round(b * scale * k))

    def ellipse(side: float, up: float, a: float, b: float, colour: tuple[int, int, int], start: int = 0) -> None:
        end = 360 if start == 0 else start + 180
        cv2.ellipse(image, at(side, up), size(a, b), 0, start, end, colour, -1, cv2.LINE_AA, SUBPIXEL)

    def box(left: float, bottom: float, right: float, top: float, colour: tuple[int, int, int]) -> None:
        corners = np.array([at(left, bottom), at(right, bottom), at(right, top), at(left, top)], np.int32)
        cv2.fillConvexPoly(image, corners, colour, cv2.LINE_AA, SUBPIXEL)

    def line(a: tuple[float, float], b: tuple[float, float], width: float, colour: tuple[int, int, int]) -> None:
        thickness = max(1, round(width * scale))
        cv2.line(image, at(*a), at(*b), colour, thickness, cv2.LINE_AA, SUBPIXEL)

    skin = SKINS[pid % len(SKINS)]
    hair = HAIRS[pid % len(HAIRS)]
    shirt = SHIRTS[(pid + pid // len(HAIRS)) % len(SHIRTS)]
    sleeve = tuple(int(c * 0.8) for c in shirt)
    trousers = TROUSERS[pid % len(TROUSERS)]
    shadow = tuple(int(c * 0.78) for c in skin)
    socket = tuple(int(c * 0.62) for c in skin)
    dark = (30, 30, 35)

    # legs and shoes
    for side in (-1, 1):
        box(side * 0.02, 0.05, side * 0.14, 0.88, trousers)
        ellipse(side * 0.085, 0.035, 0.07, 0.035, dark)
    # arms, hands, then the body over the shoulders
    for side in (-1, 1):
        box(side * 0.19, 0.82, side * 0.28, 1.42, sleeve)
        ellipse(side * 0.235, 0.77, 0.032, 0.06, shadow)  # hands
    box(-0.2, 0.84, 0.2, 1.38, shirt)
    ellipse(0.0, 1.38, 0.22, 0.07, shirt, start=180)  # rounded shoulders
    box(-0.035, 1.4, 0.035, 1.5, socket)  # the neck, in the chin's shadow
    # the head, in a face's usual proportions: eyes halfway from the chin to the crown
    ellipse(0.0, 1.6, 0.09, 0.1, hair)  # hair behind the head
    ellipse(-0.076, 1.58, 0.016, 0.028, shadow)  # ears
    ellipse(0.076, 1.58, 0.016, 0.028, shadow)
    ellipse(0.0, 1.57, 0.075, 0.1, skin)
    ellipse(0.0, 1.655, 0.08, 0.045, hair, start=180)  # the hair's fringe over the forehead
    brow = tuple(int(c * 0.45) for c in hair)
    for side in (-1, 1):
        ellipse(side * 0.032, 1.587, 0.026, 0.016, socket)  # the eye socket's shade
        line((side * 0.012, 1.607), (side * 0.056, 1.61), 0.011, brow)  # eyebrows
        ellipse(side * 0.032, 1.585, 0.015, 0.007, (150, 155, 160))  # the white of the eye
        ellipse(side * 0.032, 1.585, 0.009, 0.009, dark)  # iris and pupil
    line((0.0, 1.568), (0.0, 1.55), 0.012, shadow)  # the nose's shadow, below a bright bridge
    ellipse(0.0, 1.545, 0.018, 0.008, shadow)
    ellipse(0.0, 1.513, 0.028, 0.009, (60, 60, 140))  # mouth
