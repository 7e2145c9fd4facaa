"""Seeded, deterministic synthetic RGB + thermal scenes with ground truth.

A scene is a pair of image planes:

* the **thermal plane** (``thermal_width x thermal_height``), which is also the *world* plane in
  which every object lives: people walk in thermal pixel coordinates, occluders and warm
  objects are boxes in thermal pixels, and ``visible_fraction`` is measured there;
* the **RGB plane** (``width x height``), linked to the thermal plane by the 3x3 homography
  ``H`` of :class:`SceneConfig`.  **H maps thermal pixel coordinates to RGB pixel
  coordinates**: ``[u, v, 1]^T ~ H [x, y, 1]^T``.  ``box_rgb`` of every object is
  :func:`mk_tracker.boxes.transform_box` of its ``box_thermal`` through ``H``, and the RGB
  image draws the object filling that box (rounded to whole pixels).  Without an explicit
  ``H``, it is the identity for planes of equal size, else the plain scaling
  ``diag(width / thermal_width, height / thermal_height, 1)``.

``make_scene(config)`` is lazy: trajectories, sprites, static backgrounds and noise buffers
are prepared once, and :meth:`SyntheticScene.frame` renders frame ``i`` on its own from a
random generator seeded with ``(seed, i)``, so frame ``i`` is identical whether it is
rendered alone or after frames ``0..i-1`` and a long soak test keeps no frames in memory.

Sensor noise: per frame, Gaussian.  For speed, large planes take a window at a random
offset (drawn from the frame's generator) of a fixed noise field of ``(h + 128) x (w + 128)``
samples, so noise is independent between pixels of a frame and, for a given pixel, between
frames except when two frames draw the same offset (1 in 16,384); thermal planes of at most
40,000 pixels (the paper's 100x100 scene) get fresh i.i.d. noise every frame.

Conventions: boxes are ``(x, y, w, h)`` floats (see :mod:`mk_tracker.boxes`); a person's
position is its *foot point* (bottom centre of its box); people lower in the image (larger
foot ``y``) are closer to the camera and drawn in front (so are occluders whose bottom edge is
lower than a person's feet); person ids are 1-based indices into ``config.people``; stamps are
``start_time + i / fps`` seconds.

Thermal values are rendered as temperatures in Kelvin and then encoded:
``"32FC1"`` keeps Kelvin (float32), ``"mono16"`` stores centikelvin (``round(100 T)``, the
0.01 K "TLinear" convention of radiometric cameras), ``"mono8"`` maps
``[mono8_min_kelvin, mono8_max_kelvin]`` linearly onto ``[0, 255]``.

The presets at the end of the module are the shared test fixtures of the team; each is
documented with what it exercises.
"""

from __future__ import annotations

import colorsys
import dataclasses
import math
from dataclasses import dataclass
from typing import Iterator, Sequence

import cv2
import numpy as np

from mk_tracker.boxes import InvalidBoxError, clip_box, transform_box
from mk_tracker.parameters import ParameterError, parameter, validate_config

__all__ = [
    "SceneError", "SceneIndexError", "PersonSpec", "OccluderSpec", "WarmObjectSpec",
    "SceneConfig", "ObjectTruth", "SceneFrame", "SyntheticScene", "make_scene",
    "encode_thermal", "kelvin_to_encoding", "paper_scene", "occlusion_scene",
    "crossing_scene", "approach_scene", "crowd_scene", "static_warm_objects_scene",
    "enter_leave_scene", "cross_modal_scene", "PRESETS",
]

THERMAL_ENCODINGS = ("mono8", "mono16", "32FC1")
PERSON_ASPECT = 1.0 / 2.75  # width / height of a person's box (human ~1:2.5-3)
_NOISE_PAD = 128            # margin of the noise buffers: 128^2 distinct per-frame offsets
_FRESH_NOISE_PIXELS = 40_000  # thermal planes up to this size get fresh i.i.d. noise per frame
_SPRITE_H = 176             # reference height of a person sprite; width = PERSON_ASPECT * it
_SPRITE_W = 64
_WALK_PHASES = 4            # leg poses cycled while walking


class SceneError(ValueError):
    """A scene configuration or a request to a scene is invalid."""


class SceneIndexError(SceneError, IndexError):
    """A frame index outside ``[0, len(scene))``."""


# --------------------------------------------------------------------------------------------
# Configuration


@dataclass(frozen=True)
class PersonSpec:
    """One moving target.

    ``waypoints`` are foot points ``(x, y)`` in the thermal plane; the first is the start.
    The target walks towards each waypoint in turn at ``speed`` px/frame, keeping a constant
    velocity on straight stretches and turning smoothly (at most ``SceneConfig.turn_rate_deg``
    per frame) near a waypoint.  After the last waypoint it stops (``after_last="stop"``) or
    keeps walking straight on (``"continue"``, e.g. to leave the field of view).  It stands
    at its first waypoint until ``start_frame``.

    ``kind="person"`` draws a person (head, textured upper and lower body, walking legs) whose
    box height is ``height`` px at the reference depth, scaled by the scene's perspective;
    ``kind="block"`` draws a ``block_size`` rectangle whose thermal pixels take random
    integer values in ``block_range`` each frame (the objects of the paper's synthetic test).
    Colours are BGR; an empty tuple means "pick a distinct colour from the scene seed".
    """

    waypoints: tuple = parameter(((0.0, 0.0),), "foot points (x, y) in thermal px, start first")
    speed: float = parameter(2.0, "walking speed, thermal px per frame", minimum=0.0)
    height: float = parameter(100.0, "box height in thermal px at the reference depth",
                              minimum=1.0, maximum=4096.0)
    start_frame: int = parameter(0, "frame at which the target starts walking", minimum=0)
    after_last: str = parameter("stop", "behaviour after the last waypoint",
                                choices=("stop", "continue"))
    kind: str = parameter("person", "what is drawn", choices=("person", "block"))
    upper_color: tuple = parameter((), "BGR colour of the upper body; () = from the seed")
    lower_color: tuple = parameter((), "BGR colour of the lower body; () = from the seed")
    torso_temperature: float = parameter(303.0, "clothed torso temperature, K (head +4 K, "
                                         "legs -2.5 K)", minimum=0.0)
    block_size: tuple = parameter((10.0, 10.0), "(w, h) of a block in thermal px")
    block_range: tuple = parameter((240.0, 255.0), "thermal value range of a block's pixels, K")


@dataclass(frozen=True)
class OccluderSpec:
    """A static occluder: a textured box of its own colour in RGB, cool in thermal.

    It hides people whose feet are higher in the image than its bottom edge
    (``box[1] + box[3]``), i.e. people behind it.
    """

    box: tuple = parameter((0.0, 0.0, 10.0, 10.0), "(x, y, w, h) in thermal px")
    color: tuple = parameter((60, 90, 140), "BGR colour")
    temperature: float = parameter(290.0, "surface temperature, K", minimum=0.0)


@dataclass(frozen=True)
class WarmObjectSpec:
    """A static warm object (radiator, lamp): part of the background, never moving.

    Warmer than people, so a plain threshold detector takes it for one; in RGB it is a
    low-saturation grey/white object.
    """

    box: tuple = parameter((0.0, 0.0, 10.0, 10.0), "(x, y, w, h) in thermal px")
    temperature: float = parameter(316.0, "surface temperature, K", minimum=0.0)
    shape: str = parameter("rect", "drawn shape", choices=("rect", "ellipse"))
    color: tuple = parameter((200, 200, 205), "BGR colour in the RGB image")


@dataclass(frozen=True)
class SceneConfig:
    """Everything that defines a synthetic scene; together with ``seed`` it fixes every pixel."""

    seed: int = parameter(0, "seed of every random choice", minimum=0)
    frames: int = parameter(100, "number of frames", minimum=1)
    fps: float = parameter(25.0, "frame rate, Hz", minimum=1e-3)
    start_time: float = parameter(0.0, "stamp of frame 0, s", minimum=0.0)
    width: int = parameter(640, "RGB width, px", minimum=8, maximum=8192)
    height: int = parameter(480, "RGB height, px", minimum=8, maximum=8192)
    thermal_width: int = parameter(0, "thermal width, px (0 = RGB width)", minimum=0,
                                   maximum=8192)
    thermal_height: int = parameter(0, "thermal height, px (0 = RGB height)", minimum=0,
                                    maximum=8192)
    homography: tuple = parameter((), "row-major 3x3 H mapping thermal px to RGB px; () = "
                                  "identity, or the plane-size scaling when sizes differ")
    thermal_encoding: str = parameter("mono8", "thermal image encoding",
                                      choices=THERMAL_ENCODINGS)
    mono8_min_kelvin: float = parameter(288.0, "temperature shown as 0 in mono8", minimum=0.0)
    mono8_max_kelvin: float = parameter(318.0, "temperature shown as 255 in mono8", minimum=0.0)
    background_temperature: float = parameter(293.0, "mean background temperature, K",
                                              minimum=0.0)
    background_gradient: float = parameter(2.0, "background temperature rise from top to "
                                           "bottom, K")
    background_texture: float = parameter(0.4, "amplitude of the static smooth background "
                                          "temperature variation, K", minimum=0.0)
    thermal_blur_sigma: float = parameter(0.0, "Gaussian blur of the thermal optics, px "
                                          "(applied before the sensor noise; 0 = sharp)",
                                          minimum=0.0, maximum=20.0)
    thermal_noise_std: float = parameter(0.3, "per-frame thermal sensor noise std, K",
                                         minimum=0.0)
    rgb_noise_std: float = parameter(4.0, "per-frame RGB sensor noise std, grey levels",
                                     minimum=0.0, maximum=100.0)
    rgb_background: str = parameter("textured", "RGB background",
                                    choices=("textured", "flat"))
    rgb_background_level: int = parameter(110, "grey level of the RGB background", minimum=0,
                                          maximum=255)
    missing_pixel_fraction: float = parameter(0.0, "fraction of thermal pixels dropped per "
                                              "frame (0, or NaN in 32FC1)", minimum=0.0,
                                              maximum=1.0)
    perspective: float = parameter(0.0, "0: constant size; 1: size proportional to the foot "
                                   "row (horizon at the top), reference depth at 80% of the "
                                   "height", minimum=0.0, maximum=1.0)
    turn_rate_deg: float = parameter(8.0, "maximum change of heading per frame, degrees",
                                     minimum=0.1, maximum=180.0)
    people: tuple = parameter((), "the moving targets (PersonSpec)")
    occluders: tuple = parameter((), "static occluders (OccluderSpec)")
    warm_objects: tuple = parameter((), "static warm objects (WarmObjectSpec)")


# --------------------------------------------------------------------------------------------
# Ground truth and frames


@dataclass(frozen=True)
class ObjectTruth:
    """Ground truth of one target in one frame.

    ``box_thermal`` is the full (unclipped) box in the thermal plane, ``box_rgb`` its
    :func:`~mk_tracker.boxes.transform_box` through ``H``; clip them with
    :func:`~mk_tracker.boxes.clip_box` when needed.  ``visible_fraction`` is the share of the
    target's silhouette pixels that are visible in the thermal image (inside the frame and not
    hidden by occluders or by people in front).  ``in_frame`` / ``in_frame_rgb``: some part of
    the box lies inside the thermal / RGB image.
    """

    id: int
    box_rgb: tuple[float, float, float, float]
    box_thermal: tuple[float, float, float, float]
    visible_fraction: float
    in_frame: bool
    in_frame_rgb: bool
    kind: str = "person"


@dataclass(frozen=True)
class SceneFrame:
    """One rendered frame: images (BGR uint8 and thermal), stamp in seconds, ground truth."""

    index: int
    stamp: float
    rgb: np.ndarray
    thermal: np.ndarray
    objects: tuple[ObjectTruth, ...]

    def object(self, object_id: int) -> ObjectTruth:
        """Ground truth of target ``object_id``; raises :class:`SceneError` if unknown."""
        for obj in self.objects:
            if obj.id == object_id:
                return obj
        raise SceneError(f"no object with id {object_id} in frame {self.index}")


# --------------------------------------------------------------------------------------------
# Helpers


def kelvin_to_encoding(temperature: np.ndarray, encoding: str, mono8_min: float = 288.0,
                       mono8_max: float = 318.0) -> np.ndarray:
    """Encode a Kelvin image as ``"mono8"``, ``"mono16"`` (centikelvin) or ``"32FC1"``."""
    t = np.asarray(temperature, dtype=np.float32)
    if encoding == "32FC1":
        return t.copy()
    if encoding == "mono16":
        return np.clip(np.rint(t * 100.0), 0, 65535).astype(np.uint16)
    if encoding == "mono8":
        if not mono8_max > mono8_min:
            raise SceneError("mono8_max_kelvin must be above mono8_min_kelvin")
        scale = 255.0 / (mono8_max - mono8_min)
        return np.clip(np.rint((t - mono8_min) * scale), 0, 255).astype(np.uint8)
    raise SceneError(f"unknown thermal encoding {encoding!r}; use one of {THERMAL_ENCODINGS}")


def encode_thermal(temperature: np.ndarray, config: SceneConfig) -> np.ndarray:
    """Encode a Kelvin image as ``config.thermal_encoding`` (see :func:`kelvin_to_encoding`)."""
    return kelvin_to_encoding(temperature, config.thermal_encoding, config.mono8_min_kelvin,
                              config.mono8_max_kelvin)


def _color(value: Sequence, what: str) -> tuple[int, int, int]:
    try:
        c = tuple(int(v) for v in value)
    except (TypeError, ValueError) as exc:
        raise SceneError(f"{what} must be three integers (B, G, R), got {value!r}") from exc
    if len(c) != 3 or not all(0 <= v <= 255 for v in c):
        raise SceneError(f"{what} must be three integers in 0..255, got {value!r}")
    return c  # type: ignore[return-value]


def _check_box(box: Sequence, what: str) -> tuple[float, float, float, float]:
    try:
        b = tuple(float(v) for v in box)
    except (TypeError, ValueError) as exc:
        raise SceneError(f"{what} must be (x, y, w, h), got {box!r}") from exc
    if len(b) != 4 or not all(math.isfinite(v) for v in b) or b[2] <= 0 or b[3] <= 0:
        raise SceneError(f"{what} must be four finite numbers with w, h > 0, got {box!r}")
    return b  # type: ignore[return-value]


def _int_box(box: Sequence[float]) -> tuple[int, int, int, int]:
    """Pixel placement of a float box: rounded corners, at least 1x1."""
    x0, y0 = int(round(box[0])), int(round(box[1]))
    x1, y1 = int(round(box[0] + box[2])), int(round(box[1] + box[3]))
    return x0, y0, max(1, x1 - x0), max(1, y1 - y0)


def _paste(dst: np.ndarray, patch: np.ndarray, mask: np.ndarray, x0: int, y0: int) -> None:
    """Copy ``patch`` where ``mask`` (uint8 0/1) into ``dst`` at ``(x0, y0)``, clipped."""
    h, w = mask.shape
    H, W = dst.shape[:2]
    ax0, ay0 = max(x0, 0), max(y0, 0)
    ax1, ay1 = min(x0 + w, W), min(y0 + h, H)
    if ax1 <= ax0 or ay1 <= ay0:
        return
    cv2.copyTo(patch[ay0 - y0:ay1 - y0, ax0 - x0:ax1 - x0],
               mask[ay0 - y0:ay1 - y0, ax0 - x0:ax1 - x0], dst[ay0:ay1, ax0:ax1])


def _distinct_colors(rng: np.random.Generator, n: int) -> list[tuple[tuple, tuple]]:
    """``n`` (upper, lower) pairs of saturated BGR colours, hues spread over the circle."""
    out = []
    golden = 0.61803398875
    h0 = float(rng.random())
    for k in range(n):
        hu = (h0 + golden * k) % 1.0
        hl = (hu + 0.33 + 0.34 * float(rng.random())) % 1.0
        su, sl = 0.65 + 0.35 * float(rng.random()), 0.55 + 0.45 * float(rng.random())
        vu, vl = 0.6 + 0.35 * float(rng.random()), 0.45 + 0.4 * float(rng.random())
        ru, gu, bu = colorsys.hsv_to_rgb(hu, su, vu)
        rl, gl, bl = colorsys.hsv_to_rgb(hl, sl, vl)
        out.append(((int(bu * 255), int(gu * 255), int(ru * 255)),
                    (int(bl * 255), int(gl * 255), int(rl * 255))))
    return out


# --------------------------------------------------------------------------------------------
# Sprites: a person drawn once per walking phase at a reference size, resized per frame


@dataclass(frozen=True)
class _Sprite:
    mask: np.ndarray        # uint8 0/1 (h, w)
    rgb: np.ndarray         # uint8 (h, w, 3)
    kelvin: np.ndarray      # float32 (h, w)


def _person_parts(phase: int) -> np.ndarray:
    """Part labels of a person at reference size: 0 none, 1 skin, 2 hair, 3 upper, 4 lower,
    5 shoes.  ``phase`` selects the leg pose (0: together ... 2: widest stride)."""
    W, H = _SPRITE_W, _SPRITE_H
    parts = np.zeros((H, W), np.uint8)
    cx = W // 2
    spread = (0.0, 0.5, 1.0, 0.5)[phase % _WALK_PHASES]
    hip_y, foot_y = int(0.53 * H), H - 4
    # legs first (the upper body overlaps their top)
    for side in (-1, 1):
        hip_x = cx + side * 8
        foot_x = int(round(cx + side * (6 + spread * 16)))
        cv2.line(parts, (hip_x, hip_y), (foot_x, foot_y - 4), 4, thickness=13)
        cv2.rectangle(parts, (foot_x - 7, foot_y - 6), (foot_x + 7, H - 1), 5, thickness=-1)
    # arms (upper-body colour), slightly swinging against the legs
    for side in (-1, 1):
        hand_x = int(round(cx + side * (27 - 2 * spread)))
        cv2.line(parts, (cx + side * 24, int(0.19 * H)), (hand_x, int(0.52 * H)), 3,
                 thickness=9)
        cv2.circle(parts, (hand_x, int(0.53 * H)), 4, 1, thickness=-1)
    # torso: shoulders-to-hips rounded trapezoid
    cv2.ellipse(parts, (cx, int(0.23 * H)), (24, 10), 0, 180, 360, 3, thickness=-1)
    torso = np.array([[cx - 24, int(0.23 * H)], [cx + 24, int(0.23 * H)],
                      [cx + 17, int(0.56 * H)], [cx - 17, int(0.56 * H)]], np.int32)
    cv2.fillConvexPoly(parts, torso, 3)
    # neck and head
    cv2.rectangle(parts, (cx - 5, int(0.12 * H)), (cx + 5, int(0.17 * H)), 1, thickness=-1)
    cv2.ellipse(parts, (cx, int(0.075 * H)), (11, 13), 0, 0, 360, 1, thickness=-1)
    cv2.ellipse(parts, (cx, int(0.055 * H)), (12, 10), 0, 180, 360, 2, thickness=-1)
    return parts


def _person_sprites(rng: np.random.Generator, upper: tuple, lower: tuple,
                    torso_k: float) -> list[_Sprite]:
    W, H = _SPRITE_W, _SPRITE_H
    skin = [(60, 90, 160), (80, 130, 200), (120, 170, 230), (40, 60, 110)]
    skin_c = np.array(skin[int(rng.integers(len(skin)))], np.float32)
    hair_c = np.array([20, 25, 35], np.float32) * float(0.5 + rng.random())
    shoe_c = np.array([30, 30, 30], np.float32)
    yy, xx = np.mgrid[0:H, 0:W]
    # texture fixed to the body: a pattern for the upper body, a noise weave for the lower
    pattern = int(rng.integers(3))
    period = float(rng.uniform(7.0, 14.0))
    if pattern == 0:      # horizontal stripes
        upper_tex = np.where((yy // (period / 2)) % 2 == 0, 1.0, 0.72)
    elif pattern == 1:    # vertical stripes
        upper_tex = np.where((xx // (period / 2)) % 2 == 0, 1.0, 0.72)
    else:                 # checks
        upper_tex = np.where(((xx // period) + (yy // period)) % 2 == 0, 1.0, 0.78)
    upper_tex = upper_tex * (1.0 + 0.08 * rng.standard_normal((H, W)))
    lower_tex = 1.0 + 0.12 * cv2.GaussianBlur(rng.standard_normal((H, W)).astype(np.float32),
                                              (0, 0), 1.5) * 2.0
    thermal_tex = cv2.GaussianBlur(rng.standard_normal((H, W)).astype(np.float32), (0, 0),
                                   4.0) * 2.0  # ~ +-0.4 K folds of clothing
    up = np.array(upper, np.float32)
    lo = np.array(lower, np.float32)
    sprites = []
    for phase in range(_WALK_PHASES):
        parts = _person_parts(phase)
        rgb = np.zeros((H, W, 3), np.float32)
        kel = np.full((H, W), torso_k, np.float32)
        rgb[parts == 1] = skin_c
        rgb[parts == 2] = hair_c
        sel = parts == 3
        rgb[sel] = up[None, :] * upper_tex[sel][:, None]
        sel = parts == 4
        rgb[sel] = lo[None, :] * lower_tex[sel][:, None]
        rgb[parts == 5] = shoe_c
        kel[parts == 1] = torso_k + 4.0
        kel[parts == 2] = torso_k + 1.0
        kel[parts == 3] = torso_k
        kel[parts == 4] = torso_k - 2.5
        kel[parts == 5] = torso_k - 5.0
        kel += thermal_tex * (parts > 0)
        sprites.append(_Sprite(mask=(parts > 0).astype(np.uint8),
                               rgb=np.clip(rgb, 0, 255).astype(np.uint8), kelvin=kel))
    return sprites


def _block_sprite(color: tuple, value: float) -> _Sprite:
    return _Sprite(mask=np.ones((8, 8), np.uint8), rgb=np.full((8, 8, 3), color, np.uint8),
                   kelvin=np.full((8, 8), value, np.float32))


def _resized(sprite: _Sprite, w: int, h: int) -> _Sprite:
    if sprite.mask.shape == (h, w):
        return sprite
    size = (w, h)
    return _Sprite(mask=cv2.resize(sprite.mask, size, interpolation=cv2.INTER_NEAREST),
                   rgb=cv2.resize(sprite.rgb, size, interpolation=cv2.INTER_NEAREST),
                   kelvin=cv2.resize(sprite.kelvin, size, interpolation=cv2.INTER_NEAREST))


def _occluder_rgb(rng: np.random.Generator, color: tuple, w: int, h: int) -> np.ndarray:
    """A textured box: vertical planks with noise and dark edges."""
    c = np.array(color, np.float32)
    xx = np.arange(w)[None, :]
    planks = np.where((xx // max(2, w // 5)) % 2 == 0, 1.0, 0.85)
    grain = 1.0 + 0.08 * rng.standard_normal((h, w))
    img = c[None, None, :] * (planks * grain)[:, :, None]
    img = np.clip(img, 0, 255).astype(np.uint8)
    cv2.rectangle(img, (0, 0), (w - 1, h - 1), tuple(int(v * 0.5) for v in color), 1)
    return img


# --------------------------------------------------------------------------------------------
# Trajectories


def _simulate_paths(people: Sequence[PersonSpec], frames: int,
                    turn_rate: float) -> np.ndarray:
    """Foot points ``(frames, P, 2)`` of every target: constant velocity between waypoints,
    heading turning by at most ``turn_rate`` rad per frame; a target heads for the next
    waypoint once the current one is within its turning radius (smooth corners).

    Between turns this is the noise-free constant-velocity model (2.1)-(2.2) of Schizas et
    al. (2018), "kept constant for a certain number of frames and then changed" (Sec. 2)."""
    out = np.zeros((frames, len(people), 2))
    for k, person in enumerate(people):
        out[:, k] = _simulate_path(person, frames, turn_rate)
    return out


def _simulate_path(p: PersonSpec, frames: int, turn_rate: float) -> np.ndarray:
    """``(frames, 2)`` foot points of one target (see :func:`_simulate_paths`)."""
    wps = [(float(x), float(y)) for x, y in p.waypoints]
    out = np.empty((frames, 2))
    x, y = wps[0]
    speed = float(p.speed)
    cont = p.after_last == "continue"
    n = len(wps)
    target = min(1, n - 1)
    done = n <= 1
    heading = math.atan2(wps[target][1] - y, wps[target][0] - x)
    radius = max(speed, 1.05 * speed / turn_rate)
    two_pi = 2.0 * math.pi
    t = 0
    xs: list[float] = []
    ys: list[float] = []
    while t < frames:
        xs.append(x)
        ys.append(y)
        if done:   # stopped for good, or walking straight on: the rest is closed-form
            if cont:
                steps = np.clip(np.arange(t, frames) - max(t, p.start_frame), 0, None)
                direction = np.array([math.cos(heading), math.sin(heading)])
                out[t:] = np.array([x, y]) + (steps * speed)[:, None] * direction
            else:
                out[t:] = x, y
            break
        tx, ty = wps[target]
        dist = math.hypot(tx - x, ty - y)
        last = target >= n - 1
        finish = False
        if not last and dist <= radius:
            target += 1
            tx, ty = wps[target]
            dist = math.hypot(tx - x, ty - y)
            last = target >= n - 1
        elif last and dist <= max(speed, 1e-9):
            finish = True
        if t >= p.start_frame:
            delta = (math.atan2(ty - y, tx - x) - heading + math.pi) % two_pi - math.pi
            if not (last and dist <= radius):   # near the final waypoint steer straight at
                delta = min(max(delta, -turn_rate), turn_rate)  # it (never circle it)
            heading += delta
            move = min(speed, dist) if (last and not cont) else speed
            x += move * math.cos(heading)
            y += move * math.sin(heading)
        done = finish
        t += 1
    out[:len(xs), 0] = xs
    out[:len(ys), 1] = ys
    return out


# --------------------------------------------------------------------------------------------
# The scene


def _validate(config: SceneConfig) -> None:
    if not isinstance(config, SceneConfig):
        raise SceneError(f"expected a SceneConfig, got {type(config).__name__}")
    try:
        validate_config(config)
    except ParameterError as exc:
        raise SceneError(str(exc)) from exc
    if not config.mono8_max_kelvin > config.mono8_min_kelvin:
        raise SceneError("mono8_max_kelvin must be above mono8_min_kelvin")
    for k, p in enumerate(config.people):
        if not isinstance(p, PersonSpec):
            raise SceneError(f"people[{k}] is a {type(p).__name__}, not a PersonSpec")
        try:
            validate_config(p)
        except ParameterError as exc:
            raise SceneError(f"people[{k}]: {exc}") from exc
        if len(p.waypoints) == 0:
            raise SceneError(f"people[{k}] has no waypoints")
        try:
            wp = np.asarray(p.waypoints, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise SceneError(f"people[{k}].waypoints must be (x, y) pairs") from exc
        if wp.ndim != 2 or wp.shape[1] != 2 or not np.all(np.isfinite(wp)):
            raise SceneError(f"people[{k}].waypoints must be finite (x, y) pairs")
        if p.upper_color:
            _color(p.upper_color, f"people[{k}].upper_color")
        if p.lower_color:
            _color(p.lower_color, f"people[{k}].lower_color")
        if p.kind == "block":
            if len(p.block_size) != 2 or min(p.block_size) <= 0:
                raise SceneError(f"people[{k}].block_size must be (w, h) > 0")
            if len(p.block_range) != 2 or p.block_range[0] > p.block_range[1]:
                raise SceneError(f"people[{k}].block_range must be (low, high), low <= high")
    for k, o in enumerate(config.occluders):
        if not isinstance(o, OccluderSpec):
            raise SceneError(f"occluders[{k}] is a {type(o).__name__}, not an OccluderSpec")
        _check_box(o.box, f"occluders[{k}].box")
        _color(o.color, f"occluders[{k}].color")
    for k, o in enumerate(config.warm_objects):
        if not isinstance(o, WarmObjectSpec):
            raise SceneError(f"warm_objects[{k}] is a {type(o).__name__}, not a "
                             "WarmObjectSpec")
        _check_box(o.box, f"warm_objects[{k}].box")
        _color(o.color, f"warm_objects[{k}].color")


def _homography(config: SceneConfig, tw: int, th: int) -> np.ndarray:
    if config.homography:
        try:
            H = np.asarray(config.homography, dtype=np.float64).reshape(3, 3)
        except (TypeError, ValueError) as exc:
            raise SceneError("homography must be 9 numbers (row-major 3x3)") from exc
        if not np.all(np.isfinite(H)) or abs(np.linalg.det(H)) < 1e-12:
            raise SceneError("homography must be finite and invertible")
        return H / H[2, 2] if H[2, 2] != 0 else H
    return np.diag([config.width / tw, config.height / th, 1.0])


class SyntheticScene:
    """A lazily rendered scene; see the module docstring.  Build it with :func:`make_scene`.

    Attributes: ``config``; ``homography`` (3x3, thermal px -> RGB px); ``rgb_size`` and
    ``thermal_size`` as ``(width, height)``; ``colors`` ``{id: (upper BGR, lower BGR)}``.
    """

    def __init__(self, config: SceneConfig):
        _validate(config)
        self.config = config
        c = config
        tw = c.thermal_width or c.width
        th = c.thermal_height or c.height
        self.rgb_size = (c.width, c.height)
        self.thermal_size = (tw, th)
        self.homography = _homography(c, tw, th)
        self._identity = bool(np.array_equal(self.homography, np.eye(3)))
        self._resize_cache: dict = {}
        static = np.random.default_rng([c.seed, 0x5CE1E])
        self._paths = _simulate_paths(c.people, c.frames, math.radians(c.turn_rate_deg))
        steps = np.diff(self._paths, axis=0, prepend=self._paths[:1])
        self._walked = np.cumsum(np.hypot(steps[..., 0], steps[..., 1]), axis=0)
        # appearance of every target
        palette = _distinct_colors(static, len(c.people))
        self.colors: dict[int, tuple[tuple, tuple]] = {}
        self._sprites: list[list[_Sprite]] = []
        for k, p in enumerate(c.people):
            upper = _color(p.upper_color, "upper_color") if p.upper_color else palette[k][0]
            lower = _color(p.lower_color, "lower_color") if p.lower_color else palette[k][1]
            self.colors[k + 1] = (upper, lower)
            if p.kind == "block":
                self._sprites.append([_block_sprite(upper, float(p.block_range[1]))])
            else:
                self._sprites.append(_person_sprites(static, upper, lower,
                                                     float(p.torso_temperature)))
        # static occluders, pre-rendered in both planes
        self._occluders = []
        for k, o in enumerate(c.occluders):
            box_t = _check_box(o.box, "occluder box")
            box_r = self._to_rgb(box_t)
            xr, yr, wr, hr = _int_box(box_r)
            xt, yt, wt, ht = _int_box(box_t)
            self._occluders.append({
                "bottom": box_t[1] + box_t[3], "label": -(k + 1),
                "rgb": (xr, yr, _occluder_rgb(static, o.color, wr, hr),
                        np.ones((hr, wr), np.uint8)),
                "thermal": (xt, yt, np.full((ht, wt), o.temperature, np.float32),
                            np.ones((ht, wt), np.uint8))})
        self._bg_kelvin = self._thermal_background(static)
        self._bg_rgb = self._rgb_background(static)
        pad = _NOISE_PAD
        self._thermal_noise = (static.standard_normal((th + pad, tw + pad), dtype=np.float32)
                               * np.float32(c.thermal_noise_std))
        rgb_noise = static.standard_normal((c.height + pad, c.width + pad, 3),
                                           dtype=np.float32) * c.rgb_noise_std
        self._rgb_noise_pos = np.clip(np.rint(rgb_noise), 0, 255).astype(np.uint8)
        self._rgb_noise_neg = np.clip(np.rint(-rgb_noise), 0, 255).astype(np.uint8)

    # -- static parts --------------------------------------------------------------------

    def _to_rgb(self, box: Sequence[float]) -> tuple[float, float, float, float]:
        if self._identity:   # transform_box through the identity returns the box itself
            return tuple(float(v) for v in box)  # type: ignore[return-value]
        try:
            return transform_box(box, self.homography)
        except InvalidBoxError as exc:
            raise SceneError(f"box {tuple(box)} cannot be mapped to the RGB plane: {exc}")

    def _thermal_background(self, rng: np.random.Generator) -> np.ndarray:
        c = self.config
        tw, th = self.thermal_size
        rows = (np.arange(th, dtype=np.float32) / max(th - 1, 1) - 0.5) * c.background_gradient
        bg = np.empty((th, tw), np.float32)
        bg[:] = np.float32(c.background_temperature) + rows[:, None]
        if c.background_texture > 0:
            smooth = cv2.GaussianBlur(rng.standard_normal((th, tw)).astype(np.float32),
                                      (0, 0), max(tw, th) / 20.0)
            smooth /= max(float(np.abs(smooth).max()), 1e-6)
            bg += np.float32(c.background_texture) * smooth
        for o in c.warm_objects:
            x, y, w, h = _int_box(o.box)
            self._draw_shape(bg, x, y, w, h, o.shape, float(o.temperature))
        return bg

    def _rgb_background(self, rng: np.random.Generator) -> np.ndarray:
        c = self.config
        W, H = c.width, c.height
        level = float(c.rgb_background_level)
        img = np.full((H, W, 3), level, np.float32)
        if c.rgb_background == "textured":
            # a wall above a floor: warm-grey gradient, faint tiles, soft blotches
            yy = np.arange(H, dtype=np.float32)[:, None] / H
            img *= (0.8 + 0.4 * yy)[:, :, None]
            img *= np.array([0.95, 1.0, 1.05], np.float32)
            blot = cv2.GaussianBlur(rng.standard_normal((H, W)).astype(np.float32), (0, 0),
                                    max(W, H) / 40.0)
            blot /= max(float(np.abs(blot).max()), 1e-6)
            img += 14.0 * blot[:, :, None]
            horizon = int(0.3 * H)
            img[horizon:horizon + 2] *= 0.8
            tile = max(8, W // 16)
            for x in range(0, W, tile):
                img[horizon:, x:x + 1] *= 0.9
            for y in range(horizon, H, max(6, tile // 2)):
                img[y:y + 1, :] *= 0.9
        bg = np.clip(img, 0, 255).astype(np.uint8)
        for o in c.warm_objects:
            x, y, w, h = _int_box(self._to_rgb(o.box))
            self._draw_shape(bg, x, y, w, h, o.shape, tuple(int(v) for v in o.color))
            if o.shape == "rect":   # radiator fins
                for fx in range(x + 3, x + w - 2, 6):
                    cv2.line(bg, (fx, y + 2), (fx, y + h - 3),
                             tuple(int(v * 0.8) for v in o.color), 1)
        return bg

    @staticmethod
    def _draw_shape(img: np.ndarray, x: int, y: int, w: int, h: int, shape: str,
                    value) -> None:
        if shape == "ellipse":
            cv2.ellipse(img, (x + w // 2, y + h // 2), (max(w // 2, 1), max(h // 2, 1)), 0, 0,
                        360, value, thickness=-1)
        else:
            cv2.rectangle(img, (x, y), (x + w - 1, y + h - 1), value, thickness=-1)

    # -- geometry of a frame ------------------------------------------------------------

    def __len__(self) -> int:
        return self.config.frames

    def stamp(self, index: int) -> float:
        """Time stamp of frame ``index`` in seconds."""
        return self.config.start_time + self._check_index(index) / self.config.fps

    def _check_index(self, index) -> int:
        if isinstance(index, (bool, np.bool_)) or not isinstance(index, (int, np.integer)):
            raise SceneError(f"frame index must be an integer, got {index!r}")
        i = int(index)
        if i < 0:
            i += len(self)
        if not 0 <= i < len(self):
            raise SceneIndexError(f"frame {index} outside [0, {len(self)})")
        return i

    def boxes_thermal(self, index: int) -> np.ndarray:
        """``(P, 4)`` boxes of every target in the thermal plane at frame ``index``."""
        i = self._check_index(index)
        c = self.config
        out = np.zeros((len(c.people), 4))
        th = self.thermal_size[1]
        for k, p in enumerate(c.people):
            fx, fy = self._paths[i, k]
            if p.kind == "block":
                w, h = float(p.block_size[0]), float(p.block_size[1])
            else:
                scale = 1.0
                if c.perspective > 0:
                    scale = (1.0 - c.perspective) + c.perspective * fy / (0.8 * th)
                h = max(4.0, p.height * max(scale, 0.05))
                w = h * PERSON_ASPECT
            out[k] = (fx - w / 2.0, fy - h, w, h)
        return out

    def _sized(self, sprite: _Sprite, w: int, h: int) -> _Sprite:
        """``sprite`` resized to ``w x h``, memoised (sizes change slowly between frames)."""
        key = (id(sprite), w, h)
        hit = self._resize_cache.get(key)
        if hit is None:
            if len(self._resize_cache) > 256:
                self._resize_cache.clear()
            hit = self._resize_cache[key] = _resized(sprite, w, h)
        return hit

    def _layers(self, i: int):
        """Depth-ordered (back to front) drawables of frame ``i``."""
        c = self.config
        boxes = self.boxes_thermal(i)
        layers = []
        for k, p in enumerate(c.people):
            sprites = self._sprites[k]
            if p.kind == "block":
                sprite = sprites[0]
            else:
                stride = max(boxes[k, 3] * 0.18, 1.0)
                sprite = sprites[int(self._walked[i, k] / stride) % _WALK_PHASES]
            box_t = tuple(float(v) for v in boxes[k])
            layers.append((box_t[1] + box_t[3], 0, k, box_t, self._to_rgb(box_t), sprite))
        for k, o in enumerate(self._occluders):
            layers.append((o["bottom"], 1, k, None, None, o))
        layers.sort(key=lambda item: (item[0], item[1], item[2]))
        return layers

    def _label_map(self, layers) -> tuple[np.ndarray, list]:
        """Thermal-plane label image (0 background, id >0 target, <0 occluder) and, per
        target, its placement and resized sprite."""
        tw, th = self.thermal_size
        labels = np.zeros((th, tw), np.int32)
        placed = []
        for bottom, is_occ, k, box_t, box_r, item in layers:
            if is_occ:
                x, y, kel, mask = item["thermal"]
                _paste(labels, np.full(mask.shape, item["label"], np.int32), mask, x, y)
                placed.append((True, k, x, y, None, item))
                continue
            x, y, w, h = _int_box(box_t)
            if x >= tw or y >= th or x + w <= 0 or y + h <= 0:   # off-screen: not drawn
                placed.append((False, k, x, y, None, None))
                continue
            spr = self._sized(item, w, h)
            _paste(labels, np.full((h, w), k + 1, np.int32), spr.mask, x, y)
            placed.append((False, k, x, y, spr, None))
        return labels, placed

    def _truth(self, i: int, layers, labels: np.ndarray, placed) -> tuple[ObjectTruth, ...]:
        c = self.config
        tw, th = self.thermal_size
        counts = np.bincount(np.clip(labels.ravel(), 0, None), minlength=len(c.people) + 1)
        full = {k: int(spr.mask.sum()) if spr is not None else 0
                for is_occ, k, _, _, spr, _ in placed if not is_occ}
        by_k = {layer[2]: layer for layer in layers if not layer[1]}
        out = []
        for k, p in enumerate(c.people):
            _, _, _, box_t, box_r, _ = by_k[k]
            vis = counts[k + 1] / full[k] if full[k] else 0.0
            out.append(ObjectTruth(
                id=k + 1, box_rgb=box_r, box_thermal=box_t,
                visible_fraction=float(min(1.0, vis)),
                in_frame=clip_box(box_t, tw, th) is not None,
                in_frame_rgb=clip_box(box_r, c.width, c.height) is not None, kind=p.kind))
        return tuple(out)

    def ground_truth(self, index: int) -> tuple[ObjectTruth, ...]:
        """Ground truth of frame ``index`` without rendering the images."""
        i = self._check_index(index)
        layers = self._layers(i)
        labels, placed = self._label_map(layers)
        return self._truth(i, layers, labels, placed)

    # -- rendering ------------------------------------------------------------------------

    def frame(self, index: int) -> SceneFrame:
        """Render frame ``index`` (random access; identical to sequential rendering)."""
        i = self._check_index(index)
        c = self.config
        rng = np.random.default_rng([c.seed, 0xF4A3E, i])
        layers = self._layers(i)
        labels, placed = self._label_map(layers)
        tw, th = self.thermal_size
        # thermal: background, targets and occluders in depth order, sensor noise, blocks
        kelvin = self._bg_kelvin.copy()
        for is_occ, k, x, y, spr, occ in placed:
            if is_occ:
                _, _, kel, mask = occ["thermal"]
                _paste(kelvin, kel, mask, x, y)
            elif spr is not None and c.people[k].kind == "person":
                _paste(kelvin, spr.kelvin, spr.mask, x, y)
        if c.thermal_blur_sigma > 0:
            cv2.GaussianBlur(kelvin, (0, 0), c.thermal_blur_sigma, dst=kelvin,
                             borderType=cv2.BORDER_REPLICATE)
        oy, ox = (int(v) for v in rng.integers(0, _NOISE_PAD, size=2))
        if c.thermal_noise_std > 0:
            if tw * th <= _FRESH_NOISE_PIXELS:   # small (the paper's 100x100): exact i.i.d.
                kelvin += rng.standard_normal((th, tw), dtype=np.float32) * np.float32(
                    c.thermal_noise_std)
            else:   # large: a random window of a fixed noise field (fast, see module doc)
                kelvin += self._thermal_noise[oy:oy + th, ox:ox + tw]
        for is_occ, k, x, y, spr, _ in placed:
            if is_occ or spr is None or c.people[k].kind != "block":
                continue
            h, w = spr.mask.shape
            x0, y0, x1, y1 = max(x, 0), max(y, 0), min(x + w, tw), min(y + h, th)
            if x1 <= x0 or y1 <= y0:
                continue
            region = kelvin[y0:y1, x0:x1]
            sel = labels[y0:y1, x0:x1] == k + 1
            lo, hi = c.people[k].block_range
            region[sel] = rng.integers(int(round(lo)), int(round(hi)) + 1,
                                       size=int(sel.sum())).astype(np.float32)
        thermal = encode_thermal(kelvin, c)
        if c.missing_pixel_fraction > 0:
            drop = rng.random((th, tw)) < c.missing_pixel_fraction
            thermal[drop] = np.nan if thermal.dtype == np.float32 else 0
        # RGB: static background, targets and occluders in depth order, sensor noise
        rgb = self._bg_rgb.copy()
        for bottom, is_occ, k, box_t, box_r, item in layers:
            if is_occ:
                x, y, img, mask = item["rgb"]
                _paste(rgb, img, mask, x, y)
                continue
            x, y, w, h = _int_box(box_r)
            if x >= c.width or y >= c.height or x + w <= 0 or y + h <= 0:
                continue
            spr = self._sized(item, w, h)
            _paste(rgb, spr.rgb, spr.mask, x, y)
        if c.rgb_noise_std > 0:
            oy, ox = (int(v) for v in rng.integers(0, _NOISE_PAD, size=2))
            H, W = c.height, c.width
            cv2.add(rgb, self._rgb_noise_pos[oy:oy + H, ox:ox + W], dst=rgb)
            cv2.subtract(rgb, self._rgb_noise_neg[oy:oy + H, ox:ox + W], dst=rgb)
        truth = self._truth(i, layers, labels, placed)
        return SceneFrame(index=i, stamp=c.start_time + i / c.fps, rgb=rgb, thermal=thermal,
                          objects=truth)

    def __getitem__(self, index: int) -> SceneFrame:
        return self.frame(index)

    def __iter__(self) -> Iterator[SceneFrame]:
        for i in range(len(self)):
            yield self.frame(i)

    def replaced(self, **changes) -> "SyntheticScene":
        """A new scene with ``dataclasses.replace(self.config, **changes)``, e.g.
        ``paper_scene().replaced(missing_pixel_fraction=0.05)``; raises :class:`SceneError`
        for an unknown field or an invalid value."""
        try:
            config = dataclasses.replace(self.config, **changes)
        except TypeError as exc:
            raise SceneError(f"cannot change the scene config: {exc}") from exc
        return make_scene(config)

    def foot_points(self, index: int) -> np.ndarray:
        """``(P, 2)`` foot points (bottom centres) in the thermal plane at frame ``index``."""
        return self._paths[self._check_index(index)].copy()

    def info(self) -> dict:
        """JSON-ready description: sizes, homography (thermal px -> RGB px), seed, config."""
        return {
            "seed": self.config.seed,
            "frames": len(self),
            "fps": self.config.fps,
            "rgb_size": list(self.rgb_size),
            "thermal_size": list(self.thermal_size),
            "homography": self.homography.tolist(),
            "homography_direction": "thermal pixel -> RGB pixel",
            "thermal_encoding": self.config.thermal_encoding,
            "config": _jsonable(dataclasses.asdict(self.config)),
        }


def _jsonable(value):
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def make_scene(config: SceneConfig) -> SyntheticScene:
    """Build the lazy scene of ``config``; raises :class:`SceneError` on a bad config."""
    return SyntheticScene(config)


# --------------------------------------------------------------------------------------------
# Presets: the shared fixtures of the team's tests and benchmarks


def _check_preset_args(seed, frames=None, **sizes) -> None:
    """Reject a bad seed, frame count or size before a preset computes anything with it."""
    values = {"seed": (seed, 0)}
    if frames is not None:
        values["frames"] = (frames, 1)
    for name, value in sizes.items():
        values[name] = (value, 8)
    for name, (value, low) in values.items():
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
            raise SceneError(f"{name} must be an integer >= {low}, got {value!r}")


def paper_scene(seed: int = 0, background_level: float = 20.0) -> SyntheticScene:
    """The synthetic test of Schizas, Maroulas & Ren (2018), Sec. 6.

    As in the paper: 100x100 frames, 60 frames, three 10x10 objects whose pixels take values
    240..255 (drawn uniformly per pixel and frame), object 1 moving left -> right, object 2
    top -> bottom, object 3 right -> left, background Gaussian noise of variance 20;
    thermal is mono8.  Interpretation where the text is silent:

    * the background *level* is ``background_level`` (20) rather than 0, so the zero-mean
      noise (std sqrt(20) = 4.47) is not clipped at 0 by the 8-bit encoding and its measured
      variance stays 20 (the paper's figures show a black-looking background);
    * the mono8 mapping is the identity (``mono8_min_kelvin=0``, ``mono8_max_kelvin=255``), so
      the scene's "Kelvin" values are the paper's intensities; objects carry no extra noise;
    * the objects cross the whole frame in 60 frames at a constant 1.525 px/frame: object 1
      along row 25 (centroid x 5 -> 95), object 2 along column 50 (y 5 -> 95), object 3 along
      row 75 (x 95 -> 5), chosen so that the objects never overlap;
    * ground-truth boxes move continuously, while the blocks are drawn at the rounded pixel
      position (at most 0.5 px from the ground truth in x or y).  The paper's "centroid
      pixel" (Sec. 2, floor of the mean pixel index) of a block drawn at columns
      ``x0 .. x0 + 9`` is ``x0 + 4``, while the box centre in the :mod:`mk_tracker.boxes`
      convention is ``x0 + 5``: compare like with like;
    * the paper's frames 20/40/60 are our frames 19/39/59 (0-based); fps 25;
    * RGB is a grey copy of the same content (white blocks on a dark background).
    """
    _check_preset_args(seed)
    v = 90.0 / 59.0
    people = []
    # waypoints are foot points (bottom centre) = centroid + (0, 5)
    for start, end in (((5.0, 25.0), (95.0, 25.0)), ((50.0, 5.0), (50.0, 95.0)),
                       ((95.0, 75.0), (5.0, 75.0))):
        people.append(PersonSpec(waypoints=((start[0], start[1] + 5.0), (end[0], end[1] + 5.0)),
                                 speed=v, kind="block", block_size=(10.0, 10.0),
                                 block_range=(240.0, 255.0), upper_color=(255, 255, 255),
                                 lower_color=(255, 255, 255), after_last="stop"))
    cfg = SceneConfig(seed=seed, frames=60, fps=25.0, width=100, height=100,
                      thermal_encoding="mono8", mono8_min_kelvin=0.0, mono8_max_kelvin=255.0,
                      background_temperature=background_level, background_gradient=0.0,
                      background_texture=0.0, thermal_noise_std=math.sqrt(20.0),
                      rgb_noise_std=math.sqrt(20.0), rgb_background="flat",
                      rgb_background_level=int(round(background_level)),
                      people=tuple(people))
    return make_scene(cfg)


def occlusion_scene(seed: int = 0, hidden_frames: int = 20, full: bool = True,
                    frames: int = 140, speed: float = 2.0) -> SyntheticScene:
    """One person walks left -> right behind a static pillar (640x480, 25 fps).

    ``full=True``: the pillar hides the whole body for ``hidden_frames`` (+-2) frames
    (visible_fraction 0 then); ``full=False``: a low wall hides only the lower body (legs,
    ~40% of the silhouette) for ``hidden_frames`` (+-2) frames, and part of it a little
    longer while the person walks past its ends.  The person (id 1, 150 px tall)
    enters fully visible from the left and ends fully visible on the right.
    """
    _check_preset_args(seed, frames)
    if hidden_frames < 0:
        raise SceneError("hidden_frames must be >= 0")
    h = 150.0
    w = h * PERSON_ASPECT
    foot_y = 330.0
    # the occluder is wider than the person's box by speed * hidden_frames
    occ_w = w + speed * hidden_frames
    if full:
        occ = OccluderSpec(box=(320.0 - occ_w / 2.0, foot_y - h - 20.0, occ_w, h + 40.0),
                           color=(70, 110, 150))
    else:
        occ = OccluderSpec(box=(320.0 - occ_w / 2.0, foot_y - 0.47 * h, occ_w, 0.47 * h + 20),
                           color=(70, 110, 150))
    travel = speed * (frames - 1)
    person = PersonSpec(waypoints=((320.0 - travel / 2.0, foot_y), (320.0 + travel / 2.0,
                                                                    foot_y)),
                        speed=speed, height=h, upper_color=(40, 40, 200),
                        lower_color=(150, 60, 20), after_last="continue")
    cfg = SceneConfig(seed=seed, frames=frames, people=(person,), occluders=(occ,))
    return make_scene(cfg)


def crossing_scene(seed: int = 0, frames: int = 120, speed: float = 3.0) -> SyntheticScene:
    """Two people cross, with full mutual occlusion at the crossing (640x480, 25 fps).

    Person 1 is close to the camera (200 px tall, feet on row 450) and walks left -> right
    at ``speed``; person 2 is farther away (64 px tall, feet on row 354) and walks right ->
    left at ``speed / 2``.  Both reach x = 320 at frame ``frames // 2``; person 2's whole
    silhouette then lies behind person 1's torso, so it is completely hidden
    (visible_fraction 0) for several frames around the crossing.
    """
    _check_preset_args(seed, frames)
    meet = frames // 2
    p1 = PersonSpec(waypoints=((320.0 - speed * meet, 450.0), (320.0 + speed * meet, 450.0)),
                    speed=speed, height=200.0, upper_color=(30, 30, 210),
                    lower_color=(140, 70, 20), after_last="continue")
    v2 = speed / 2.0
    p2 = PersonSpec(waypoints=((320.0 + v2 * meet, 354.0), (320.0 - v2 * meet, 354.0)),
                    speed=v2, height=64.0, upper_color=(40, 190, 40),
                    lower_color=(30, 160, 200), after_last="continue")
    return make_scene(SceneConfig(seed=seed, frames=frames, people=(p1, p2)))


def approach_scene(seed: int = 0, frames: int = 120) -> SyntheticScene:
    """One person walks from the back of the room towards the camera (640x480).

    With full perspective the box height grows with the foot row: from ~56 px at foot row
    150 to ~170 px at row 460 (x3 scale change), drifting slightly sideways.
    """
    _check_preset_args(seed, frames)
    person = PersonSpec(waypoints=((300.0, 150.0), (360.0, 460.0)),
                        speed=310.0 / max(frames - 1, 1) * 1.02, height=135.0,
                        upper_color=(160, 40, 160), lower_color=(40, 120, 40))
    return make_scene(SceneConfig(seed=seed, frames=frames, perspective=1.0, people=(person,)))


def crowd_scene(n_people: int = 5, seed: int = 0, width: int = 640, height: int = 480,
                frames: int = 300, occluders: int = 2, perspective: float = 0.6,
                thermal_encoding: str = "mono8") -> SyntheticScene:
    """``n_people`` people wandering with random turns, crossings and ``occluders`` pillars.

    Each person starts at a random point of the floor (lower 70% of the image) and walks at
    1-3 px/frame through random waypoints on the floor, so people cross each other and pass
    behind the pillars; sizes follow a perspective (``perspective``).  Used for the 5/15/30
    people benchmarks.
    """
    _check_preset_args(seed, frames, width=width, height=height)
    for name, value in (("n_people", n_people), ("occluders", occluders)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
            raise SceneError(f"{name} must be a non-negative integer, got {value!r}")
    rng = np.random.default_rng([seed, 0xC20D])
    x0, x1 = 0.06 * width, 0.94 * width
    y0, y1 = 0.38 * height, 0.98 * height
    people = []
    for _ in range(int(n_people)):
        speed = float(rng.uniform(1.0, 3.0))
        # a random walk of legs 0.1-0.3 width long, reflected into the floor area
        n_wp = int(frames * speed / (0.1 * width)) + 3
        legs = rng.uniform(0.1, 0.3, n_wp) * width
        angles = rng.uniform(-np.pi, np.pi, n_wp)
        wps = np.empty((n_wp, 2))
        wps[0] = rng.uniform(x0, x1), rng.uniform(y0, y1)
        for j in range(1, n_wp):
            p = wps[j - 1] + legs[j] * np.array([np.cos(angles[j]), np.sin(angles[j])])
            for axis, lo, hi in ((0, x0, x1), (1, y0, y1)):
                if p[axis] < lo:
                    p[axis] = min(2 * lo - p[axis], hi)
                elif p[axis] > hi:
                    p[axis] = max(2 * hi - p[axis], lo)
            wps[j] = p
        people.append(PersonSpec(waypoints=tuple(map(tuple, wps.round(2).tolist())),
                                 speed=round(speed, 3), height=0.3 * height,
                                 torso_temperature=float(rng.uniform(301.5, 304.0))))
    occ = []
    for k in range(int(occluders)):
        ow, oh = 0.06 * width, 0.42 * height
        cx = width * (k + 1) / (occluders + 1) + float(rng.uniform(-0.05, 0.05)) * width
        bottom = float(rng.uniform(0.6, 0.85)) * height
        occ.append(OccluderSpec(box=(cx - ow / 2, bottom - oh, ow, oh),
                                color=tuple(int(v) for v in rng.integers(40, 120, 3))))
    cfg = SceneConfig(seed=seed, frames=frames, width=width, height=height,
                      perspective=perspective, thermal_encoding=thermal_encoding,
                      people=tuple(people), occluders=tuple(occ))
    return make_scene(cfg)


def static_warm_objects_scene(seed: int = 0, frames: int = 100) -> SyntheticScene:
    """Static warm objects (two radiators, a lamp) plus one cooler person walking by.

    For the threshold-detector comparison of the paper's Table 1: the radiators (318 K) and
    lamp (322 K) are warmer than the person (torso 302 K, head 306 K), so any threshold low
    enough to catch the person also fires on them, while they never move.
    """
    _check_preset_args(seed, frames)
    warm = (WarmObjectSpec(box=(40.0, 250.0, 90.0, 50.0), temperature=318.0),
            WarmObjectSpec(box=(520.0, 270.0, 80.0, 45.0), temperature=318.0),
            WarmObjectSpec(box=(300.0, 40.0, 36.0, 36.0), temperature=322.0, shape="ellipse",
                           color=(220, 240, 250)))
    person = PersonSpec(waypoints=((190.0, 440.0), (470.0, 430.0)), speed=3.0, height=150.0,
                        torso_temperature=302.0, upper_color=(30, 140, 230),
                        lower_color=(90, 40, 40), after_last="stop")
    return make_scene(SceneConfig(seed=seed, frames=frames, people=(person,),
                                  warm_objects=warm, mono8_max_kelvin=325.0))


def enter_leave_scene(seed: int = 0, frames: int = 150) -> SyntheticScene:
    """Person 1 enters from the left edge, person 2 leaves through the right edge.

    Person 1 starts fully outside (in_frame False), walks in and stays; person 2 starts inside
    and walks out, ending fully outside (in_frame False, visible_fraction 0).
    """
    _check_preset_args(seed, frames)
    p1 = PersonSpec(waypoints=((-60.0, 400.0), (260.0, 400.0)), speed=3.0, height=140.0,
                    upper_color=(200, 160, 30), lower_color=(40, 40, 40))
    p2 = PersonSpec(waypoints=((420.0, 300.0), (760.0, 300.0)), speed=3.0, height=120.0,
                    upper_color=(40, 40, 190), lower_color=(100, 100, 30),
                    after_last="continue", start_frame=20)
    return make_scene(SceneConfig(seed=seed, frames=frames, people=(p1, p2)))


CROSS_MODAL_HOMOGRAPHY = (1.92, 0.06, 18.0,
                          -0.04, 1.95, 12.0,
                          2.0e-5, 1.0e-5, 1.0)


def cross_modal_scene(seed: int = 0, frames: int = 100, thermal_encoding: str = "mono16",
                      thermal_size: tuple[int, int] = (320, 240)) -> SyntheticScene:
    """Thermal ``thermal_size`` (320x240, or e.g. 640x512) and RGB 640x480 linked by a
    non-identity homography.

    For 320x240, ``H`` is :data:`CROSS_MODAL_HOMOGRAPHY` (thermal px -> RGB px): roughly a
    x1.93 zoom with a small rotation, an offset and a mild perspective term; for another
    thermal size it is that matrix times ``diag(320 / tw, 240 / th, 1)``, and the people's
    paths and heights are scaled the same way, so the RGB boxes stay about the same (the
    person's aspect ratio is fixed in the thermal plane).  Two people
    walk in the thermal plane; their RGB boxes are their thermal boxes mapped through ``H``.
    """
    _check_preset_args(seed, frames)
    try:
        tw, th = (int(v) for v in thermal_size)
    except (TypeError, ValueError) as exc:
        raise SceneError(f"thermal_size must be (width, height), got {thermal_size!r}") from exc
    if tw < 8 or th < 8:
        raise SceneError(f"thermal_size must be at least 8x8, got {thermal_size!r}")
    sx, sy = tw / 320.0, th / 240.0

    def scaled(points):
        return tuple((x * sx, y * sy) for x, y in points)

    p1 = PersonSpec(waypoints=scaled(((40.0, 200.0), (160.0, 180.0), (280.0, 210.0))),
                    speed=1.5 * sx, height=80.0 * sy, upper_color=(30, 30, 200),
                    lower_color=(120, 80, 20))
    p2 = PersonSpec(waypoints=scaled(((260.0, 150.0), (80.0, 160.0))), speed=1.2 * sx,
                    height=60.0 * sy, upper_color=(40, 180, 40), lower_color=(40, 40, 40))
    H = np.asarray(CROSS_MODAL_HOMOGRAPHY, dtype=np.float64).reshape(3, 3) @ np.diag(
        [1.0 / sx, 1.0 / sy, 1.0])
    cfg = SceneConfig(seed=seed, frames=frames, width=640, height=480, thermal_width=tw,
                      thermal_height=th, homography=tuple(H.ravel().tolist()),
                      thermal_encoding=thermal_encoding, people=(p1, p2))
    return make_scene(cfg)


PRESETS = {
    "paper": paper_scene,
    "occlusion": occlusion_scene,
    "crossing": crossing_scene,
    "approach": approach_scene,
    "crowd": crowd_scene,
    "static_warm_objects": static_warm_objects_scene,
    "enter_leave": enter_leave_scene,
    "cross_modal": cross_modal_scene,
}
