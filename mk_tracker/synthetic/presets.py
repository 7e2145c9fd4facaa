"""Preset synthetic scenes: the shared fixtures of the team's tests and benchmarks.

Each preset builds a :class:`~mk_tracker.synthetic.scene.SyntheticScene` from a seed and a
few arguments and is documented with what it exercises: the paper's Sec. 6 test of Schizas,
Maroulas & Ren (2018) (:func:`paper_scene`), occlusion by a pillar or a low wall, two people
crossing with full mutual occlusion, a person approaching the camera (scale change), crowds,
static warm objects (the threshold-detector comparison of the paper's Table 1), people
entering and leaving, and RGB and thermal planes linked by a homography.  :data:`PRESETS`
maps the names used on the command line (``mk_tracker generate --preset``) to them.
"""

from __future__ import annotations

import math

import numpy as np

from mk_tracker.synthetic.people import PERSON_ASPECT
from mk_tracker.synthetic.scene import SyntheticScene, make_scene
from mk_tracker.synthetic.scene_config import (OccluderSpec, PersonSpec, SceneConfig, SceneError,
                                               WarmObjectSpec)

__all__ = ["paper_scene", "occlusion_scene", "crossing_scene", "approach_scene", "crowd_scene",
           "static_warm_objects_scene", "enter_leave_scene", "far_view_scene", "static_camera_scene",
           "cross_modal_scene",
           "CROSS_MODAL_HOMOGRAPHY", "PRESETS"]


def _motion_fields(motion) -> dict:
    """The PersonSpec motion-variation fields of a preset's ``motion`` argument: ``None``
    (off) or a mapping with ``heading_std`` (rad), ``speed_std`` and ``time_constant`` (s);
    see :class:`~mk_tracker.synthetic.scene_config.PersonSpec`."""
    if motion is None:
        return {}
    keys = {"heading_std", "speed_std", "time_constant"}
    if not isinstance(motion, dict) or not set(motion) <= keys:
        raise SceneError("motion must be None or a dict with keys among heading_std, "
                         f"speed_std and time_constant, got {motion!r}")
    return {f"motion_{k}": float(v) for k, v in motion.items()}


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
                thermal_encoding: str = "mono8", stop_fraction: float = 0.0,
                motion: dict | None = None) -> SyntheticScene:
    """``n_people`` people wandering with random turns, crossings and ``occluders`` pillars.

    Each person starts at a random point of the floor (lower 70% of the image) and walks at
    1-3 px/frame through random waypoints on the floor, so people cross each other and pass
    behind the pillars; sizes follow a perspective (``perspective``).  Used for the 5/15/30
    people benchmarks.

    ``stop_fraction`` of the people (issue #19: a person who stops must keep the track) stop
    for good at a waypoint: their walk ends at the last waypoint within ``d`` px of path
    from the start (the first one if none), ``d`` drawn between the distance they walk in
    20% and in 50% of the clip, and they stand there, perfectly still, to the end.  The cut
    draws from a random stream of its own, so at the default 0 the scene is the same as
    before the argument existed, and a stopper's waypoints are the first ones of the walk it
    has at 0.

    ``motion`` (default ``None``: piecewise-straight walks at constant speed) gives every
    person the motion variation ``{"heading_std": rad, "speed_std": relative,
    "time_constant": s}`` (PersonSpec ``motion_*``); the same waypoints, so the same people
    walk the same course with varying heading and speed.
    """
    _check_preset_args(seed, frames, width=width, height=height)
    for name, value in (("n_people", n_people), ("occluders", occluders)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
            raise SceneError(f"{name} must be a non-negative integer, got {value!r}")
    if not (isinstance(stop_fraction, (int, float)) and not isinstance(stop_fraction, bool)
            and 0.0 <= stop_fraction <= 1.0):
        raise SceneError(f"stop_fraction must be in [0, 1], got {stop_fraction!r}")
    varied = _motion_fields(motion)
    rng = np.random.default_rng([seed, 0xC20D])
    stops = np.random.default_rng([seed, 0x5709])
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
        wps = wps.round(2)
        stop = stops.random() < stop_fraction
        walk = float(stops.uniform(0.2, 0.5)) * frames * round(speed, 3)
        if stop:   # the last waypoint within ``walk`` px of path is the last one
            along = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(wps, axis=0).T))))
            wps = wps[:max(int(np.searchsorted(along, walk, side="right")) - 1, 1) + 1]
        people.append(PersonSpec(waypoints=tuple(map(tuple, wps.tolist())),
                                 speed=round(speed, 3), height=0.3 * height,
                                 torso_temperature=float(rng.uniform(301.5, 304.0)),
                                 **varied))
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


def far_view_scene(n_people: int = 10, seed: int = 0, frames: int = 140,
                   fps: float = 7.0, stop_fraction: float = 0.0, shadows: float = 0.0,
                   illumination_drift: float = 0.0, heights: tuple = (50.0, 105.0),
                   perspective: float = 0.0, motion: dict | None = None,
                   speed_scale: float = 1.0) -> SyntheticScene:
    """A far view at a low frame rate: small people crossing from edge to edge (640x480).

    The condition of issue #16's unseen outdoor clips: ``fps`` 7, people 50-105 px tall
    (18-38 px wide), 42-112 px/s (6-16 px of motion per frame at 7 fps), each entering at the left or right image
    edge at a random frame and leaving at the other; about a third walk in pairs (a second
    person 0.6 box widths behind the first on the same line), so people cross, walk
    together and hide one another.  One pillar.  No perspective (a far view).

    ``stop_fraction`` of the walkers (a pair together) stop for good between 30% and 70%
    of their way across and stand there to the end: the case a background model absorbs.
    ``shadows`` and ``illumination_drift`` are the scene's ``rgb_shadow_strength`` and
    ``rgb_illumination_drift``; ``heights`` the range of the people's heights at the
    reference row (80% of the image height), ``perspective`` the scene's (sizes
    proportional to the row of the feet).  At their defaults the scene is the same as
    before they existed: the stops draw from a random stream of their own.  ``motion``:
    the people's motion variation, as in :func:`crowd_scene` (default ``None``, straight).
    ``speed_scale`` multiplies every walking speed (default 1: the scene as before): with
    smaller ``heights`` it keeps the speed in body heights per second that of the default
    people (e.g. 50 / 77.5 for 40-60 px people), since a person's image speed scales with
    the image size at a fixed distance-to-ground-speed ratio.
    """
    _check_preset_args(seed, frames)
    if not (isinstance(speed_scale, (int, float)) and math.isfinite(speed_scale)
            and speed_scale > 0):
        raise SceneError(f"speed_scale must be a positive number, got {speed_scale!r}")
    if isinstance(n_people, bool) or not isinstance(n_people, (int, np.integer)) \
            or n_people < 0:
        raise SceneError(f"n_people must be a non-negative integer, got {n_people!r}")
    if not (isinstance(fps, (int, float)) and math.isfinite(fps) and fps > 0):
        raise SceneError(f"fps must be a positive number, got {fps!r}")
    if not (isinstance(stop_fraction, (int, float)) and 0.0 <= stop_fraction <= 1.0):
        raise SceneError(f"stop_fraction must be in [0, 1], got {stop_fraction!r}")
    varied = _motion_fields(motion)
    rng = np.random.default_rng([seed, 0xFA7])
    stops = np.random.default_rng([seed, 0x5709])
    width, height = 640, 480
    nearest = (1.0 - perspective) + perspective * 0.97 / 0.8   # largest size factor
    people = []
    while len(people) < int(n_people):
        h = float(rng.uniform(*heights))
        speed = float(rng.uniform(6.0, 16.0)) * 7.0 / fps * speed_scale  # 42-112 px/s
        y_start = float(rng.uniform(0.3, 0.97)) * height
        y_end = min(max(y_start + float(rng.uniform(-0.15, 0.15)) * height, 0.3 * height),
                    0.97 * height)
        margin = h * nearest * PERSON_ASPECT
        left_to_right = bool(rng.random() < 0.5)
        xs = (-margin, width + margin) if left_to_right else (width + margin, -margin)
        start = int(rng.integers(0, max(int(0.7 * frames), 1)))
        group = 2 if rng.random() < 0.35 else 1
        stop_at = float(stops.uniform(0.3, 0.7)) if stops.random() < stop_fraction else None
        for g in range(min(group, int(n_people) - len(people))):
            lag = g * 1.6 * margin * (1 if left_to_right else -1)
            end = (xs[1] - lag, y_end)
            if stop_at is not None:   # stand still from here on, on the way across
                end = (xs[0] - lag + stop_at * (xs[1] - xs[0]),
                       y_start + stop_at * (y_end - y_start))
            people.append(PersonSpec(
                waypoints=((xs[0] - lag, y_start), end),
                speed=round(speed, 3), height=round(h * (1.0 + 0.05 * g), 2),
                start_frame=start, after_last="continue" if stop_at is None else "stop",
                torso_temperature=float(rng.uniform(301.5, 304.0)), **varied))
    ow, oh = 0.05 * width, 0.35 * height
    cx = float(rng.uniform(0.3, 0.7)) * width
    bottom = float(rng.uniform(0.65, 0.8)) * height
    occ = (OccluderSpec(box=(cx - ow / 2, bottom - oh, ow, oh),
                        color=tuple(int(v) for v in rng.integers(40, 120, 3))),)
    cfg = SceneConfig(seed=seed, frames=frames, fps=float(fps), width=width, height=height,
                      perspective=float(perspective),
                      turn_rate_deg=20.0,
                      people=tuple(people),
                      occluders=occ, rgb_shadow_strength=float(shadows),
                      rgb_illumination_drift=float(illumination_drift))
    return make_scene(cfg)


def static_camera_scene(n_people: int = 10, seed: int = 0, frames: int = 210,
                        fps: float = 7.0, heights: tuple = (72.0, 88.0),
                        speed_scale: float = 1.0) -> SyntheticScene:
    """What a static outdoor surveillance camera sees (issue #13): the far view of
    :func:`far_view_scene` (7 fps by default; people crossing, pairs, a pillar) over a
    ground plane (full perspective: by default adults of 72-88 px at 80% of the image
    height, about 30 px where the walkable ground starts and 105 px at the bottom), a
    quarter of the walkers stopping for good on the way, cast shadows (strength 0.45) and
    the light fading by 25% over the clip.  The test scene of the RGB-only system
    (background subtraction -> tracker).  ``heights`` (at 80% of the image height) and
    ``speed_scale`` are :func:`far_view_scene`'s: smaller people for a farther camera."""
    return far_view_scene(n_people, seed=seed, frames=frames, fps=fps, stop_fraction=0.25,
                          shadows=0.45, illumination_drift=-0.25, heights=tuple(heights),
                          perspective=1.0, speed_scale=speed_scale)


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
    "far_view": far_view_scene,
    "static_camera": static_camera_scene,
    "cross_modal": cross_modal_scene,
}
