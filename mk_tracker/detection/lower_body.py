"""A detection grown down over the person's lower body (issue #19: "boxes cover the whole
body").  Not in Schizas et al. (2018).

Why the legs go missing.  The sparse kernel covariance (3.5)-(3.7) finds the pixels whose
level changed during the window by more than the kernel's similarity radius (3.6).  Where
the background is about as warm as a person's legs (a warm day, a heated floor: legs a few
kelvin cooler than the torso are then within a kelvin of it), the walking legs change the
pixels by less than that, and the object is the head and torso: on a generated crowd with
a 299 K background the boxes are 0.43-0.56 of the person's height and recall at IoU 0.5
falls from 0.58-0.63 to 0.22-0.37 (benchmarks/bench_thermal_conditions.py).

The rule (:func:`grown_down`), on the newest frame, scale-free: below the box, each row's
mean over the box's central half of columns is compared with the mean of the same row
beside the box (half a box width on each side).  The legs differ from the background beside
them, warmer or cooler, by much less than the support needs but by more than the background
differs from itself across the box: a row belongs to the person while ``|centre -
beside|`` is at least ``min_contrast`` times the robust spread of the left-minus-right
difference over the same rows (noise and texture alike).  The box grows to the last such row, across gaps of at
most ``max_gap`` of its height (the space between the legs, a belt), by at most
``max_growth`` of its height, and never into another detection below it.  A box whose
person is whole already ends where the floor begins: the rows under it match the rows
beside it, and it does not grow.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Sequence

import numpy as np

from mk_tracker.parameters import parameter

__all__ = ["LowerBody", "LowerBodyConfig", "grown_down"]


@dataclass(frozen=True)
class LowerBodyConfig:
    """The constants of :func:`grown_down` (``detector.lower_body.*``)."""

    enabled: bool = parameter(
        False, "grow each detection down over the rows under it that differ from the rows "
        "beside it (the legs of a person whose torso alone was detected, on a background "
        "about as warm as the legs); not in the paper")
    min_contrast: float = parameter(
        4.0, "a row under the box belongs to the person while its central mean differs from "
        "the mean beside the box by at least this many times the robust spread of the "
        "left-minus-right difference of the same rows (the background's noise and texture)",
        minimum=0.5, maximum=100.0)
    max_growth: float = parameter(
        1.2, "the box grows by at most this many of its own heights", minimum=0.0,
        maximum=5.0)
    max_gap: float = parameter(
        0.1, "rows that do not differ, up to this fraction of the box's height, do not stop "
        "the growth when person rows follow them", minimum=0.0, maximum=1.0)


def _row_contrast(frame: np.ndarray, rows: slice, centre: tuple[int, int],
                  left: tuple[int, int], right: tuple[int, int]) -> np.ndarray:
    """Per row of ``rows``: |mean over the ``centre`` columns - mean over the ``left`` and
    ``right`` column ranges|, in units of how much the background itself differs across
    the box: the robust spread (median absolute value) of the left mean minus the right
    mean over the same rows, which holds the pixels' noise and the background's texture
    alike."""
    block = frame[rows].astype(np.float64)
    middle = block[:, centre[0]:centre[1]].mean(axis=1)
    lhs = block[:, left[0]:left[1]].mean(axis=1)
    rhs = block[:, right[0]:right[1]].mean(axis=1)
    spread = 1.4826 * float(np.median(np.abs(lhs - rhs)))
    # the centre is compared with the sides' mean, whose difference from one side's mean
    # is half the left-right difference: the same scale, up to a constant
    return np.abs(middle - 0.5 * (lhs + rhs)) / max(spread, 1e-6)


def grown_down(frame: np.ndarray, box: Sequence[float], others: Sequence[Sequence[float]],
               config: LowerBodyConfig) -> tuple[float, float, float, float]:
    """``box`` ``(x, y, w, h)`` with its bottom moved down over the person rows under it
    (module docstring); ``box`` unchanged when no such row follows it, or when there are no
    columns beside it to compare with.  ``others``: the frame's other detections, which the
    growth does not enter."""
    height, width = frame.shape[:2]
    x, y, w, h = (float(v) for v in box)
    bottom = int(math.ceil(y + h))
    limit = min(height, int(math.floor(y + h + config.max_growth * h)))
    c0, c1 = int(round(x + 0.25 * w)), int(round(x + 0.75 * w))
    c0, c1 = max(c0, 0), min(c1, width)
    for ox, oy, ow, oh in others:               # not into another detection below
        if oy >= y + h - 1 and min(ox + ow, c1) - max(ox, c0) > 0:
            limit = min(limit, int(math.floor(oy)))
    half = max(int(round(0.5 * w)), 2)
    left = (max(int(x) - half, 0), max(int(x), 0))
    right = (min(int(math.ceil(x + w)), width), min(int(math.ceil(x + w)) + half, width))
    if c1 - c0 < 2 or limit - bottom < 3 or left[1] - left[0] < 2 or \
            right[1] - right[0] < 2:
        return (x, y, w, h)              # at the image's edge: nothing to compare with
    score = _row_contrast(frame, slice(bottom, limit), (c0, c1), left, right)
    person = score >= config.min_contrast
    gap = max(int(round(config.max_gap * h)), 1)
    last = -1
    since = 0
    for k, on in enumerate(person):
        if on:
            last, since = k, 0
        else:
            since += 1
            if since > gap:
                break
    if last < 0:
        return (x, y, w, h)
    return (x, y, w, float(bottom + last + 1) - y)


class LowerBody:
    """Thermal detector mixin: :func:`grown_down` on a frame's detections (the host
    provides ``config.lower_body`` and ``_newest``)."""

    def _lower_bodies(self, detections: list[Any], make: Callable[[Any, tuple], Any]
                      ) -> list[Any]:
        c = self.config.lower_body
        if not c.enabled or not detections:
            return detections
        frame = self._newest()
        boxes = [d.box for d in detections]
        out = []
        for k, d in enumerate(detections):
            grown = grown_down(frame, d.box, boxes[:k] + boxes[k + 1:], c)
            out.append(d if grown == tuple(float(v) for v in d.box) else make(d, grown))
        return out
