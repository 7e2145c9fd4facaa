"""The people of a synthetic scene: how they move and how they look.

* **Motion** (:func:`simulate_paths`): each target walks through its waypoints at constant
  speed, its heading turning by at most ``SceneConfig.turn_rate_deg`` per frame; between
  turns this is the noise-free constant-velocity model (2.1)-(2.2) of Schizas, Maroulas &
  Ren (2018), "kept constant for a certain number of frames and then changed" (Sec. 2).
  Optionally (``PersonSpec.motion_heading_std`` / ``motion_speed_std`` > 0, off by
  default) the walking direction and speed vary around the waypoint course as real people
  do: an Ornstein-Uhlenbeck offset of the heading (rad) and of the relative speed, each
  with stationary std ``motion_*_std`` and correlation time ``motion_time_constant`` s
  (:func:`ou_offsets`); the steering towards the waypoint still acts on the true
  position, so the offsets bend the path without leaving the course.
* **Appearance** (:func:`person_sprites`): a person is drawn once per walking phase at a
  reference size (head, textured upper and lower body, walking legs; BGR colours and a
  temperature per body part, K) and resized per frame; a ``block`` target (the paper's
  Sec. 6 objects) is a plain rectangle.  :func:`distinct_colors` gives targets without a
  colour of their own well separated hues.
"""

from __future__ import annotations

import colorsys
import math
from dataclasses import dataclass
from typing import Sequence

import cv2
import numpy as np

from mk_tracker.synthetic.scene_config import PersonSpec

__all__ = ["PERSON_ASPECT", "WALK_PHASES", "Sprite", "block_sprite", "distinct_colors",
           "ou_offsets", "person_sprites", "resized", "simulate_paths"]

PERSON_ASPECT = 1.0 / 2.75  # width / height of a person's box (human ~1:2.5-3)
_SPRITE_H = 176             # reference height of a person sprite; width = PERSON_ASPECT * it
_SPRITE_W = 64
WALK_PHASES = 4            # leg poses cycled while walking


# --------------------------------------------------------------------------------------------
# Motion


def simulate_paths(people: Sequence[PersonSpec], frames: int,
                    turn_rate: float, fps: float = 25.0, seed: int = 0) -> np.ndarray:
    """Foot points ``(frames, P, 2)`` of every target: constant velocity between waypoints,
    heading turning by at most ``turn_rate`` rad per frame; a target heads for the next
    waypoint once the current one is within its turning radius (smooth corners).

    Between turns this is the noise-free constant-velocity model (2.1)-(2.2) of Schizas et
    al. (2018), "kept constant for a certain number of frames and then changed" (Sec. 2).
    A target with motion variation (``motion_heading_std`` or ``motion_speed_std`` > 0)
    draws its offsets (:func:`ou_offsets`, time constant in seconds at ``fps``) from a
    random stream of its own, ``[seed, k, 0x307]`` for target ``k``; a target without one
    draws nothing, so it walks as before the variation existed."""
    out = np.zeros((frames, len(people), 2))
    for k, person in enumerate(people):
        offsets = None
        if person.motion_heading_std > 0 or person.motion_speed_std > 0:
            rng = np.random.default_rng([int(seed), k, 0x307])
            offsets = ou_offsets(rng, frames, fps, person.motion_time_constant,
                                 (person.motion_heading_std, person.motion_speed_std))
        out[:, k] = _simulate_path(person, frames, turn_rate, offsets)
    return out


def ou_offsets(rng: np.random.Generator, frames: int, fps: float, time_constant: float,
               stds: Sequence[float]) -> np.ndarray:
    """``(frames, len(stds))`` stationary Ornstein-Uhlenbeck processes sampled every frame.

    Exact discretisation: ``x[t+1] = a x[t] + sqrt(1 - a^2) std e[t]``, ``a =
    exp(-1 / (fps * time_constant))``, ``e`` standard normal, ``x[0] ~ N(0, std^2)``, so
    every sample has std ``std`` and samples ``d`` s apart correlate by
    ``exp(-d / time_constant)``."""
    stds = np.asarray(stds, float)
    a = math.exp(-1.0 / (float(fps) * float(time_constant)))
    noise = rng.standard_normal((frames, len(stds)))
    out = np.empty((frames, len(stds)))
    out[0] = noise[0] * stds
    kick = math.sqrt(max(1.0 - a * a, 0.0)) * stds
    for t in range(1, frames):
        out[t] = a * out[t - 1] + kick * noise[t]
    return out


def _simulate_path(p: PersonSpec, frames: int, turn_rate: float,
                   offsets: np.ndarray | None = None) -> np.ndarray:
    """``(frames, 2)`` foot points of one target (see :func:`simulate_paths`); ``offsets``
    ``(frames, 2)``: heading offset (rad) and relative speed offset of every frame."""
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
        if done and cont and offsets is not None:   # walking on, varying: keep stepping
            turn, rel = offsets[t]
            step = speed * max(1.0 + rel, 0.0) if t >= p.start_frame else 0.0
            x += step * math.cos(heading + turn)
            y += step * math.sin(heading + turn)
            t += 1
            continue
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
            turn = 0.0
            if offsets is not None:   # vary around the course (never on the final stop)
                turn, rel = offsets[t]
                if not (last and not cont and dist <= radius):
                    move *= max(1.0 + rel, 0.0)
                else:
                    turn = 0.0
            x += move * math.cos(heading + turn)
            y += move * math.sin(heading + turn)
        done = finish
        t += 1
    out[:len(xs), 0] = xs
    out[:len(ys), 1] = ys
    return out


# --------------------------------------------------------------------------------------------
# Appearance: a person drawn once per walking phase at a reference size, resized per frame


def distinct_colors(rng: np.random.Generator, n: int) -> list[tuple[tuple, tuple]]:
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


@dataclass(frozen=True)
class Sprite:
    """A target drawn at some size: where it is (mask), its BGR colours and its Kelvin."""

    mask: np.ndarray        # uint8 0/1 (h, w)
    rgb: np.ndarray         # uint8 (h, w, 3)
    kelvin: np.ndarray      # float32 (h, w)


def _person_parts(phase: int) -> np.ndarray:
    """Part labels of a person at reference size: 0 none, 1 skin, 2 hair, 3 upper, 4 lower,
    5 shoes.  ``phase`` selects the leg pose (0: together ... 2: widest stride)."""
    W, H = _SPRITE_W, _SPRITE_H
    parts = np.zeros((H, W), np.uint8)
    cx = W // 2
    spread = (0.0, 0.5, 1.0, 0.5)[phase % WALK_PHASES]
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


def person_sprites(rng: np.random.Generator, upper: tuple, lower: tuple,
                    torso_k: float) -> list[Sprite]:
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
    for phase in range(WALK_PHASES):
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
        sprites.append(Sprite(mask=(parts > 0).astype(np.uint8),
                               rgb=np.clip(rgb, 0, 255).astype(np.uint8), kelvin=kel))
    return sprites


def block_sprite(color: tuple, value: float) -> Sprite:
    return Sprite(mask=np.ones((8, 8), np.uint8), rgb=np.full((8, 8, 3), color, np.uint8),
                   kelvin=np.full((8, 8), value, np.float32))


def resized(sprite: Sprite, w: int, h: int) -> Sprite:
    if sprite.mask.shape == (h, w):
        return sprite
    size = (w, h)
    return Sprite(mask=cv2.resize(sprite.mask, size, interpolation=cv2.INTER_NEAREST),
                   rgb=cv2.resize(sprite.rgb, size, interpolation=cv2.INTER_NEAREST),
                   kelvin=cv2.resize(sprite.kelvin, size, interpolation=cv2.INTER_NEAREST))
