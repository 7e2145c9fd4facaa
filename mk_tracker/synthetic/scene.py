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

The configuration types are in :mod:`mk_tracker.synthetic.scene_config`, the people's motion
and sprites in :mod:`mk_tracker.synthetic.people`, and the shared test scenes of the team in
:mod:`mk_tracker.synthetic.presets`.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Iterator, Sequence

import cv2
import numpy as np

from mk_tracker.boxes import InvalidBoxError, clip_box, transform_box
from mk_tracker.synthetic.people import (PERSON_ASPECT, WALK_PHASES, block_sprite,
                                         distinct_colors, person_sprites, resized,
                                         simulate_paths, Sprite)
from mk_tracker.synthetic.scene_config import (THERMAL_ENCODINGS, ObjectTruth, SceneConfig,
                                               SceneError, SceneFrame, SceneIndexError,
                                               check_box, check_color, validate_scene)

__all__ = ["SyntheticScene", "make_scene", "encode_thermal", "kelvin_to_encoding"]

_NOISE_PAD = 128            # margin of the noise buffers: 128^2 distinct per-frame offsets
_FRESH_NOISE_PIXELS = 40_000  # thermal planes up to this size get fresh i.i.d. noise per frame


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
        validate_scene(config)
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
        self._paths = simulate_paths(c.people, c.frames, math.radians(c.turn_rate_deg),
                                     fps=c.fps, seed=c.seed)
        steps = np.diff(self._paths, axis=0, prepend=self._paths[:1])
        self._walked = np.cumsum(np.hypot(steps[..., 0], steps[..., 1]), axis=0)
        # appearance of every target
        palette = distinct_colors(static, len(c.people))
        self.colors: dict[int, tuple[tuple, tuple]] = {}
        self._sprites: list[list[Sprite]] = []
        for k, p in enumerate(c.people):
            upper = check_color(p.upper_color, "upper_color") if p.upper_color else palette[k][0]
            lower = check_color(p.lower_color, "lower_color") if p.lower_color else palette[k][1]
            self.colors[k + 1] = (upper, lower)
            if p.kind == "block":
                self._sprites.append([block_sprite(upper, float(p.block_range[1]))])
            else:
                self._sprites.append(person_sprites(static, upper, lower,
                                                     float(p.torso_temperature)))
        # static occluders, pre-rendered in both planes
        self._occluders = []
        for k, o in enumerate(c.occluders):
            box_t = check_box(o.box, "occluder box")
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

    def _sized(self, sprite: Sprite, w: int, h: int) -> Sprite:
        """``sprite`` resized to ``w x h``, memoised (sizes change slowly between frames)."""
        key = (id(sprite), w, h)
        hit = self._resize_cache.get(key)
        if hit is None:
            if len(self._resize_cache) > 256:
                self._resize_cache.clear()
            hit = self._resize_cache[key] = resized(sprite, w, h)
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
                sprite = sprites[int(self._walked[i, k] / stride) % WALK_PHASES]
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
        if c.rgb_shadow_strength > 0:
            self._cast_shadows(rgb, layers)
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
        if c.rgb_illumination_drift != 0 and len(self) > 1:
            gain = 1.0 + c.rgb_illumination_drift * i / (len(self) - 1)
            cv2.convertScaleAbs(rgb, dst=rgb, alpha=gain)
        if c.rgb_noise_std > 0:
            oy, ox = (int(v) for v in rng.integers(0, _NOISE_PAD, size=2))
            H, W = c.height, c.width
            cv2.add(rgb, self._rgb_noise_pos[oy:oy + H, ox:ox + W], dst=rgb)
            cv2.subtract(rgb, self._rgb_noise_neg[oy:oy + H, ox:ox + W], dst=rgb)
        truth = self._truth(i, layers, labels, placed)
        return SceneFrame(index=i, stamp=c.start_time + i / c.fps, rgb=rgb, thermal=thermal,
                          objects=truth)

    def _cast_shadows(self, rgb: np.ndarray, layers) -> None:
        """Darken the ground beside each person's feet (``rgb_shadow_strength``), in place.

        A shadow is a flat ellipse on the ground from the feet towards the right, as cast
        by a low sun on the left: ``rgb_shadow_length`` person heights long and a fifth of a
        height deep.  It darkens the background only (people and occluders are drawn over
        it), keeping the chromaticity: the case shadow suppression is built for
        (Horprasert et al. 1999)."""
        c = self.config
        mask = np.zeros(rgb.shape[:2], np.uint8)
        for _bottom, is_occ, k, _box_t, box_r, _item in layers:
            if is_occ or c.people[k].kind != "person":
                continue
            x, y, w, h = box_r
            length = c.rgb_shadow_length * h
            if length <= 0 or w <= 0 or h <= 0:
                continue
            centre = (int(round(x + 0.5 * w + 0.5 * length)), int(round(y + h)))
            axes = (max(int(round(0.5 * length + 0.3 * w)), 1), max(int(round(0.1 * h)), 1))
            cv2.ellipse(mask, centre, axes, 0.0, 0.0, 360.0, 255, -1)
        shaded = mask > 0
        rgb[shaded] = (rgb[shaded] * (1.0 - c.rgb_shadow_strength)).astype(np.uint8)

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
