"""What defines a synthetic scene, and what a rendered frame reports.

:class:`SceneConfig` (with its :class:`PersonSpec`, :class:`OccluderSpec` and
:class:`WarmObjectSpec`) and its seed fix every pixel of a scene
(:mod:`mk_tracker.synthetic.scene` renders it); :class:`SceneFrame` is one rendered frame
with its ground truth :class:`ObjectTruth` per target.  Positions are in the thermal plane
(the world plane, see :mod:`mk_tracker.synthetic.scene`); :func:`validate_scene` checks a
configuration and raises :class:`SceneError`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from mk_tracker.parameters import ParameterError, parameter, validate_config

__all__ = ["SceneError", "SceneIndexError", "PersonSpec", "OccluderSpec", "WarmObjectSpec",
           "SceneConfig", "ObjectTruth", "SceneFrame", "THERMAL_ENCODINGS", "validate_scene",
           "check_box", "check_color"]

THERMAL_ENCODINGS = ("mono8", "mono16", "32FC1")


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

    Motion variation (off at the defaults 0): the walking direction deviates from the
    waypoint course by an Ornstein-Uhlenbeck heading offset of stationary std
    ``motion_heading_std`` rad and the speed by a relative offset of std
    ``motion_speed_std`` (the speed is ``speed * max(1 + offset, 0)``), both with
    correlation time ``motion_time_constant`` s (people.py :func:`ou_offsets`).  Useful
    ranges: heading 0-0.5 rad, speed 0-0.5, time constant 0.3-5 s; the values matched to
    the TUD clips are ``bench_multi_object.REAL_MOTION`` (docs/synthetic_scenes.md).
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
    motion_heading_std: float = parameter(0.0, "std of the OU heading offset from the "
                                          "waypoint course, rad (0 = straight)",
                                          minimum=0.0, maximum=math.pi)
    motion_speed_std: float = parameter(0.0, "std of the OU relative speed offset "
                                        "(0 = constant speed)", minimum=0.0, maximum=5.0)
    motion_time_constant: float = parameter(1.0, "correlation time of the OU offsets, s",
                                            minimum=1e-3, maximum=1e4)


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
    rgb_shadow_strength: float = parameter(
        0.0, "cast shadows in RGB: each person darkens the ground beside its feet by this "
        "fraction (0 = no shadows; a shadow is not part of the person's box)", minimum=0.0,
        maximum=0.9)
    rgb_shadow_length: float = parameter(0.5, "length of a cast shadow along the ground, in "
                                         "person heights", minimum=0.0, maximum=3.0)
    rgb_illumination_drift: float = parameter(
        0.0, "slow lighting change in RGB: the image gain moves linearly from 1 at the first "
        "frame to 1 + this at the last (e.g. -0.3: 30% darker by the end)", minimum=-0.9,
        maximum=2.0)
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
# Validation


def check_color(value: Sequence, what: str) -> tuple[int, int, int]:
    """``value`` as a BGR colour of three integers in 0..255; :class:`SceneError` naming
    ``what`` otherwise."""
    try:
        c = tuple(int(v) for v in value)
    except (TypeError, ValueError) as exc:
        raise SceneError(f"{what} must be three integers (B, G, R), got {value!r}") from exc
    if len(c) != 3 or not all(0 <= v <= 255 for v in c):
        raise SceneError(f"{what} must be three integers in 0..255, got {value!r}")
    return c  # type: ignore[return-value]


def check_box(box: Sequence, what: str) -> tuple[float, float, float, float]:
    """``box`` as a finite ``(x, y, w, h)`` with ``w, h > 0``; :class:`SceneError` naming
    ``what`` otherwise."""
    try:
        b = tuple(float(v) for v in box)
    except (TypeError, ValueError) as exc:
        raise SceneError(f"{what} must be (x, y, w, h), got {box!r}") from exc
    if len(b) != 4 or not all(math.isfinite(v) for v in b) or b[2] <= 0 or b[3] <= 0:
        raise SceneError(f"{what} must be four finite numbers with w, h > 0, got {box!r}")
    return b  # type: ignore[return-value]


def validate_scene(config: SceneConfig) -> None:
    """Raise :class:`SceneError` unless ``config`` is a valid :class:`SceneConfig`
    (declared parameter bounds, waypoints, colours, boxes)."""
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
            check_color(p.upper_color, f"people[{k}].upper_color")
        if p.lower_color:
            check_color(p.lower_color, f"people[{k}].lower_color")
        if p.kind == "block":
            if len(p.block_size) != 2 or min(p.block_size) <= 0:
                raise SceneError(f"people[{k}].block_size must be (w, h) > 0")
            if len(p.block_range) != 2 or p.block_range[0] > p.block_range[1]:
                raise SceneError(f"people[{k}].block_range must be (low, high), low <= high")
    for k, o in enumerate(config.occluders):
        if not isinstance(o, OccluderSpec):
            raise SceneError(f"occluders[{k}] is a {type(o).__name__}, not an OccluderSpec")
        check_box(o.box, f"occluders[{k}].box")
        check_color(o.color, f"occluders[{k}].color")
    for k, o in enumerate(config.warm_objects):
        if not isinstance(o, WarmObjectSpec):
            raise SceneError(f"warm_objects[{k}] is a {type(o).__name__}, not a "
                             "WarmObjectSpec")
        check_box(o.box, f"warm_objects[{k}].box")
        check_color(o.color, f"warm_objects[{k}].color")
