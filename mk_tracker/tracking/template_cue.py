"""A template (spatial-structure) cue for tracks started by hand (issue #16 item 3).

The kernel histograms of Chu et al. 2013 (Sec. III-IV) carry no spatial structure inside a
kernel: two full-width stacked kernels (the 2-kernel layout of tracks started by hand,
Fig. 4a) have no left/right structure, and on real walkers their colour optimum sits
0.12-0.19 box widths behind the person (``benchmarks/diagnose_box_bias.py``,
docs/failure_analysis.md); a passer-by in clothes of the same colours scores like the
target.  A correlation tracker (CSRT) matches the spatial layout of the pixels instead.

This module adds that cue *after* the multiple-kernel search, whose Kalman coupling
(Sec. IV-D) stays the core: the box found by Algorithm 1 is a measurement; a grey template
of the target (the central part of the first box, :func:`start_template`) is matched by
normalised cross-correlation (OpenCV's ``cv2.matchTemplate``, ``TM_CCOEFF_NORMED``) over a
small window around that box (:func:`match_template`), and when the correlation peak is high
and clearly above the correlation at the kernels' own position the measured centre is moved
towards the peak (:func:`template_shift`).  A low peak (the person hidden, turned, or the
window off them) leaves the kernels' result unchanged.  The scale stays the kernels' (the
template is resampled to the current box width).  Not in the paper.

To keep the cost small the window and the template are resampled so that the box is
``template_width_px`` pixels wide (a 40 x 100 px person is matched at 24 x 60); the peak is
refined to sub-pixel precision by a parabola through its neighbours.

The template may follow the person's appearance slowly (``template_update_rate``), only
from frames where the track is seen and the peak is high, and blended with the first
frame's template so it cannot drift away from the person that was started
(:func:`update_template`).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

__all__ = ["TemplateModel", "TemplateMatch", "start_template", "match_template",
           "template_shift", "update_template"]

#: grey-level std (0-255 scale) below which a patch has no structure to match
MIN_TEMPLATE_STD = 2.0


@dataclass
class TemplateModel:
    """A target's template: ``template`` (float32 grey, ``(th, tw)``) is what is matched,
    ``first`` the first frame's template (the anchor of :func:`update_template`);
    ``fraction`` the central share of the box width it covers."""

    template: np.ndarray
    first: np.ndarray
    fraction: float

    @property
    def width(self) -> int:
        return int(self.template.shape[1])


@dataclass(frozen=True)
class TemplateMatch:
    """One :func:`match_template`: the peak's centre offset ``(dx, dy)`` from the box's
    centre in image pixels, the correlation ``peak`` there and ``at_box`` at the box itself
    (NaN when the window cut by the image border does not contain the box); ``inside``: the
    maximum is a peak inside the window, not on its rim (where the correlation still rises
    outwards: the best place lies beyond the window, if anywhere)."""

    dx: float
    dy: float
    peak: float
    at_box: float
    inside: bool = True


def _grey(image: np.ndarray) -> np.ndarray:
    a = np.asarray(image)
    if a.ndim == 3 and a.shape[2] == 3:
        a = cv2.cvtColor(a if a.dtype in (np.uint8, np.float32) else a.astype(np.float32),
                         cv2.COLOR_BGR2GRAY)
    elif a.ndim == 3 and a.shape[2] == 1:
        a = a[:, :, 0]
    if a.ndim != 2:
        raise ValueError(f"image of shape {np.shape(image)} is neither grey nor BGR")
    return a.astype(np.float32, copy=False)


def _inner(box, fraction: float) -> tuple[float, float, float, float]:
    """The central ``fraction`` of the box's width, its full height."""
    x, y, w, h = (float(v) for v in box)
    return x + w * (1.0 - fraction) / 2.0, y, w * fraction, h


def _crop(image: np.ndarray, x0: float, y0: float, x1: float, y1: float
          ) -> tuple[np.ndarray, int, int] | None:
    """Grey pixels of ``[x0, x1) x [y0, y1)`` inside the image, with their top-left corner
    (only the crop is converted: the cue reads a window, not the frame)."""
    a = np.asarray(image)
    if a.ndim not in (2, 3):
        raise ValueError(f"image of shape {a.shape} is neither grey nor BGR")
    height, width = a.shape[:2]
    c0, r0 = max(int(np.floor(x0)), 0), max(int(np.floor(y0)), 0)
    c1, r1 = min(int(np.ceil(x1)), width), min(int(np.ceil(y1)), height)
    if c1 - c0 < 2 or r1 - r0 < 2:
        return None
    return _grey(a[r0:r1, c0:c1]), c0, r0


def start_template(image: np.ndarray, box, width_px: int, fraction: float
                   ) -> TemplateModel | None:
    """The template of ``box`` (x, y, w, h) in ``image`` (BGR or grey): the central
    ``fraction`` of its width (less background beside the person), resampled to ``width_px``
    pixels wide.  None when the box is not wholly inside the image, its pixels are not
    finite, or the patch is flat (std below :data:`MIN_TEMPLATE_STD`): nothing to match."""
    x, y, w, h = _inner(box, fraction)
    height, width = np.shape(image)[:2]
    if not (np.isfinite([x, y, w, h]).all() and w > 1 and h > 1) or x < 0 or y < 0 or \
            x + w > width or y + h > height:
        return None
    cut = _crop(image, x, y, x + w, y + h)
    if cut is None or not np.isfinite(cut[0]).all():
        return None
    th = max(int(round(width_px * h / w)), 2)
    t = cv2.resize(cut[0], (int(width_px), th), interpolation=cv2.INTER_AREA)
    if float(t.std()) < MIN_TEMPLATE_STD:
        return None
    return TemplateModel(template=t, first=t.copy(), fraction=float(fraction))


def _subpixel(r: np.ndarray, row: int, col: int) -> tuple[float, float]:
    """Peak position refined by a parabola through its neighbours on each axis."""
    def vertex(a: float, b: float, c: float) -> float:
        d = a - 2.0 * b + c
        return 0.0 if d >= 0.0 else float(np.clip(0.5 * (a - c) / d, -0.5, 0.5))
    dc = vertex(r[row, col - 1], r[row, col], r[row, col + 1]) \
        if 0 < col < r.shape[1] - 1 else 0.0
    dr = vertex(r[row - 1, col], r[row, col], r[row + 1, col]) \
        if 0 < row < r.shape[0] - 1 else 0.0
    return col + dc, row + dr


def _bilinear(r: np.ndarray, u: float, v: float) -> float:
    if not (0.0 <= u <= r.shape[1] - 1 and 0.0 <= v <= r.shape[0] - 1):
        return float("nan")
    c0, r0 = min(int(u), r.shape[1] - 2) if r.shape[1] > 1 else 0, \
        min(int(v), r.shape[0] - 2) if r.shape[0] > 1 else 0
    fu, fv = u - c0, v - r0
    c1, r1 = min(c0 + 1, r.shape[1] - 1), min(r0 + 1, r.shape[0] - 1)
    top = r[r0, c0] * (1 - fu) + r[r0, c1] * fu
    bottom = r[r1, c0] * (1 - fu) + r[r1, c1] * fu
    return float(top * (1 - fv) + bottom * fv)


def match_template(model: TemplateModel, image: np.ndarray, box, radius: float,
                   radius_y: float | None = None) -> TemplateMatch | None:
    """Normalised cross-correlation of the template over ``box`` (the kernels' result)
    shifted by up to ``radius`` box widths in x and ``radius_y`` (default ``radius``) box
    widths in y, at the box's current width.

    The window is cut by the image border where it crosses it.  None when it holds no full
    template, or the box or the pixels are not finite; correlations OpenCV cannot normalise
    (a flat window) count as -1."""
    b = np.asarray(box, dtype=np.float64).reshape(-1)
    if b.shape != (4,) or not np.isfinite(b).all() or b[2] <= 1 or b[3] <= 1:
        return None
    x, y, w, h = _inner(b, model.fraction)
    s = model.width / w                      # image px -> template px
    reach = radius * float(b[2])
    reach_y = (radius if radius_y is None else radius_y) * float(b[2])
    cut = _crop(image, x - reach, y - reach_y, x + w + reach, y + h + reach_y)
    if cut is None:
        return None
    window, c0, r0 = cut
    size = (int(round(window.shape[1] * s)), int(round(window.shape[0] * s)))
    th, tw = model.template.shape
    if size[0] < tw or size[1] < th or not np.isfinite(window).all():
        return None
    small = cv2.resize(window, size, interpolation=cv2.INTER_AREA)
    r = cv2.matchTemplate(small, model.template, cv2.TM_CCOEFF_NORMED)
    r = np.nan_to_num(r, nan=-1.0, posinf=-1.0, neginf=-1.0)
    _, peak, _, (col, row) = cv2.minMaxLoc(r)
    # a maximum on the map's rim is no peak: the correlation still rises outwards, so the
    # best place lies beyond the window (or the image), if anywhere
    inside = 0 < col < r.shape[1] - 1 and 0 < row < r.shape[0] - 1
    u, v = _subpixel(r, row, col)
    # the template's top-left corner when it sits on the box itself (the resize maps
    # window px to small px by size / window.shape, within a rounding of s)
    sx, sy = size[0] / window.shape[1], size[1] / window.shape[0]
    u0, v0 = (x - c0) * sx, (y - r0) * sy
    return TemplateMatch(dx=(u - u0) / sx, dy=(v - v0) / sy, peak=float(peak),
                         at_box=_bilinear(r, u0, v0), inside=inside)


def template_shift(match: TemplateMatch | None, box, min_peak: float, min_gain: float,
                   weight: float) -> tuple[float, float]:
    """How far to move the kernels' box: ``weight`` times the peak's offset when the peak is
    inside the window, at least ``min_peak`` and at least ``min_gain`` above the correlation
    at the box itself; (0, 0) otherwise (no match, a low peak: occlusion or a different
    view, a maximum on the window's rim, or a box whose own correlation is unknown because
    the image border cuts it)."""
    if match is None or not match.inside or not np.isfinite(match.at_box) or \
            not np.isfinite(match.peak):
        return 0.0, 0.0
    if match.peak < min_peak or match.peak - match.at_box < min_gain:
        return 0.0, 0.0
    if not (np.isfinite(match.dx) and np.isfinite(match.dy)):
        return 0.0, 0.0
    return weight * match.dx, weight * match.dy


def update_template(model: TemplateModel, image: np.ndarray, box, rate: float) -> None:
    """Blend the patch at ``box`` into the template at ``rate``, then pull it back towards
    the first frame's template at the same rate (``T <- (1-a)((1-a) T + a P) + a T_1``), so
    the template follows slow changes of the person's look but never wanders further from
    the first view than one blend step allows.  No change when the patch cannot be read
    (outside the image, flat or not finite)."""
    if rate <= 0.0:
        return
    fresh = start_template(image, box, model.width, model.fraction)
    if fresh is None:
        return
    patch = fresh.template
    if patch.shape != model.template.shape:      # a rounding of the height
        patch = cv2.resize(patch, model.template.shape[::-1], interpolation=cv2.INTER_AREA)
    a = float(rate)
    blended = (1.0 - a) * model.template + a * patch
    model.template = ((1.0 - a) * blended + a * model.first).astype(np.float32)
