"""Expected person size per image row, learnt online, and the split of a group's mask into
people by it (issues #13 and #15).

Both detectors report one box per connected foreground region; people who walk close
together make one region.  Under a camera looking at a ground plane, the image height of a
standing person is close to linear in the image row of their feet, so a region much wider
than one person at its row is a group:

* :class:`PersonHeightModel` fits ``h = a + b * y_bottom`` by least squares with
  exponential forgetting, from the boxes of *isolated* people (:func:`is_person_shaped`:
  an upright aspect ratio, so a fragment or a side-by-side group is not a sample), and
  keeps the samples' residual spread about the line, so that a scene where one height per
  row does not hold can refuse the size (optional: ``detector.size_max_residual``; on the
  project's scenes it did not separate a ground-plane crowd from BU-TIV-lab,
  docs/benchmark_groups.md);
* :func:`people_in_width` says how many people a region of a given width holds
  (``round(width / expected width)`` once it is ``split_ratio`` expected widths wide);
* :func:`parts_are_people` (``detector.min_part_height_fraction``, off by default) keeps a
  split only when every part is as tall as a person at its own row;
* :func:`projection_cuts` cuts the region at the emptiest columns of its mask (the vertical
  projection) near the evenly spaced positions; :func:`split_columns` takes one person
  fewer while a part would be narrower than a person;
* :func:`valley_columns` (``detector.valley_columns``, with ``split_by_valleys``) turns the
  parts of a valley split into column ranges: parts stacked in one column range are one
  upright person, and neighbours are cut at the emptiest column between them, so a split
  never makes a head or a leg box.

The background-subtraction detector (:mod:`mk_tracker.detection.background_detector`) and the
thermal detector (:mod:`mk_tracker.detection.thermal_detector`, ``split_by_person_size``)
use them the same way.
"""

from __future__ import annotations

import math
from typing import Callable, Sequence

import numpy as np

__all__ = ["PersonHeightModel", "is_person_shaped", "parts_are_people", "people_in_width",
           "projection_cuts", "split_columns", "valley_columns"]


class PersonHeightModel:
    """``h = a + b * y_bottom`` fitted online by least squares with exponential forgetting
    (weights ``(1 - 1/memory)^age``); without enough spread in ``y`` it is the weighted mean
    height.

    **Validity** (not in the paper: Schizas et al. (2018) have no size prior).  One height
    per image row holds for people standing on a ground plane seen from above; in a near
    indoor scene a half-body box and a whole-body box end on the same row.  The model keeps
    the weighted residual variance of its samples about the line, ``var(h) - b^2 var(y)``
    (``var(h)`` without a slope), and :meth:`height_at` gives no size while the relative
    residual spread (:meth:`relative_residual`: its square root over the mean height) is
    above ``max_relative_residual`` or the samples' total weight is below ``min_samples``:
    every split that reads the expected size then acts as if none was learnt.

    **Row range.**  The model also keeps the lowest and highest feet row of its samples
    (:attr:`rows`, for benchmarks/diagnose_background.py --rows).  Evaluating the line only
    within that range (no extrapolation) lost held out in the background detector and was
    deleted (commit c3cd90a has it; docs/benchmark_background_detector.md).
    """

    def __init__(self, memory: float, max_relative_residual: float = math.inf,
                 min_samples: float = 2.5) -> None:
        self.decay = 1.0 - 1.0 / max(float(memory), 1.0)
        self.max_relative_residual = float(max_relative_residual)
        self.min_samples = float(min_samples)
        self.sums = np.zeros(6)          # n, y, h, yy, yh, hh
        self.rows: tuple[float, float] | None = None   # lowest, highest sample row

    @property
    def samples(self) -> float:
        """Total weight of the samples (their count without forgetting)."""
        return float(self.sums[0])

    def add(self, y_bottom: float, height: float) -> None:
        self.sums *= self.decay
        self.sums += (1.0, y_bottom, height, y_bottom * y_bottom, y_bottom * height,
                      height * height)
        y = float(y_bottom)
        self.rows = (y, y) if self.rows is None else (min(self.rows[0], y),
                                                       max(self.rows[1], y))

    def _line(self) -> tuple[float, float, float, float] | None:
        """``(mean y, mean h, slope, residual variance)`` of the weighted fit; None with
        fewer than about 3 samples."""
        n, sy, sh, syy, syh, shh = self.sums
        if n < 2.5:
            return None
        mean_y, mean_h = sy / n, sh / n
        var_y = syy / n - mean_y ** 2
        var_h = shh / n - mean_h ** 2
        if var_y < 1.0:                  # all samples on (nearly) one row
            return mean_y, mean_h, 0.0, max(var_h, 0.0)
        b = (syh / n - mean_y * mean_h) / var_y
        return mean_y, mean_h, b, max(var_h - b * b * var_y, 0.0)

    def relative_residual(self) -> float | None:
        """Weighted residual standard deviation of the samples about the fitted line over
        their mean height; None with fewer than about 3 samples."""
        line = self._line()
        if line is None or not line[1] > 0:
            return None
        return math.sqrt(line[3]) / line[1]

    def is_level(self, tolerance: float) -> bool:
        """Whether the samples say one height for every row: their feet rows span at least
        one mean height, and over that span the fitted line changes, and the samples
        scatter about it (residual std), by at most ``tolerance`` of the mean height.  A
        person whose height stays the same while their feet cross many rows is not on a
        ground plane seen from above (where height follows the row) but on stairs or a
        facade-like layout, or far away: the row then says nothing of their depth, and one
        height serves every row (False with fewer than about 3 samples)."""
        line = self._line()
        if line is None or self.rows is None or not line[1] > 0 or tolerance <= 0:
            return False
        _mean_y, mean_h, b, var = line
        span = self.rows[1] - self.rows[0]
        return bool(span >= mean_h and abs(b) * span <= tolerance * mean_h
                    and math.sqrt(var) <= tolerance * mean_h)

    def explained(self) -> float | None:
        """Share of the samples' height variance the line explains (R^2, 0 without a slope
        or spread); None with fewer than about 3 samples."""
        n, _, sh, _, _, shh = self.sums
        line = self._line()
        if line is None:
            return None
        var_h = shh / n - (sh / n) ** 2
        return 0.0 if not var_h > 0 else float(1.0 - line[3] / var_h)

    def valid(self) -> bool:
        """Whether the fit explains its samples: at least ``min_samples`` of weight and a
        relative residual spread of at most ``max_relative_residual``."""
        if self.samples < self.min_samples:
            return False
        if math.isinf(self.max_relative_residual):
            return self._line() is not None
        spread = self.relative_residual()
        return spread is not None and spread <= self.max_relative_residual

    def allows(self) -> bool:
        """Whether a split may run: always without a check (``max_relative_residual``
        infinite: as before the check existed), else only while :meth:`valid`."""
        return math.isinf(self.max_relative_residual) or self.valid()

    def height_at(self, y_bottom: float) -> float | None:
        """Expected height of a person whose feet are at row ``y_bottom``; None with fewer
        than about 3 samples, or while the fit is not :meth:`valid`."""
        line = self._line()
        if line is None or not self.valid():
            return None
        mean_y, mean_h, b, _ = line
        return float(mean_h + b * (y_bottom - mean_y))

    def heights_at(self, rows: np.ndarray) -> np.ndarray | None:
        """:meth:`height_at` of every feet row in ``rows`` from one fit (None as there)."""
        line = self._line()
        if line is None or not self.valid():
            return None
        mean_y, mean_h, b, _ = line
        return mean_h + b * (np.asarray(rows, dtype=np.float64) - mean_y)


def is_person_shaped(width: float, height: float, aspect: float) -> bool:
    """Whether a ``width x height`` box is one upright person of width/height ``aspect``
    (between 0.6 and 1.5 times it): a size sample for :class:`PersonHeightModel`."""
    return 0.6 * aspect * height <= width <= 1.5 * aspect * height


def people_in_width(width: float, expected_width: float, split_ratio: float) -> int:
    """How many people side by side a region ``width`` wide holds: 1 up to ``split_ratio``
    expected widths, else ``round(width / expected_width)`` (at least 2)."""
    if not expected_width > 0 or width <= split_ratio * expected_width:
        return 1
    return max(2, int(round(width / expected_width)))


def parts_are_people(boxes: Sequence[Sequence[float]],
                     height_at: Callable[[float], float | None], fraction: float) -> bool:
    """Whether every part box ``(x, y, w, h)`` of a split is a whole person: at least
    ``fraction`` of the expected height ``height_at(y + h)`` at its *own* bottom row.  A
    part whose row has no expected height is not one.  ``fraction`` 0 accepts every split.
    Not in the paper: a guard on the size split for scenes where the width rule cuts a
    near person's body or a far person's head into pieces (docs/benchmark_groups.md)."""
    if fraction <= 0.0:
        return True
    for _, y, _, h in boxes:
        expected = height_at(float(y) + float(h))
        if expected is None or float(h) < fraction * expected:
            return False
    return True


def projection_cuts(columns: np.ndarray, people: int) -> list[int]:
    """Cut positions (column indices, increasing) that split a region whose vertical
    projection is ``columns`` into ``people`` parts: near each evenly spaced position
    ``k * len / people`` (within a third of a part), the emptiest column; among equals the
    one nearest the even position."""
    n = len(columns)
    step = n / people
    window = max(1, int(step / 3))
    cuts: list[int] = []
    for k in range(1, people):
        centre = int(round(k * step))
        lo, hi = max(1, centre - window), min(n - 1, centre + window)
        if hi <= lo:
            continue
        candidates = np.arange(lo, hi)
        best = np.lexsort((np.abs(candidates - centre), columns[lo:hi]))[0]
        cut = int(candidates[best])
        if not cuts or cut > cuts[-1]:
            cuts.append(cut)
    return cuts


def split_columns(mask: np.ndarray, people: int, min_width: float = 0.0
                  ) -> list[tuple[int, int]]:
    """``(first, end)`` column ranges of a region's ``mask`` split into ``people`` parts at
    :func:`projection_cuts` of its column sums; ranges without a mask pixel are left out.

    ``min_width``: a part narrower than this is a limb or a shadow, not a person; the split
    is then tried with one person fewer, down to the whole region (one range).
    """
    columns = mask.sum(axis=0).astype(np.float64)
    for count in range(people, 1, -1):
        edges = [0] + projection_cuts(columns, count) + [mask.shape[1]]
        parts = [(a, b) for a, b in zip(edges[:-1], edges[1:]) if b > a and columns[a:b].any()]
        if len(parts) >= 2 and all(b - a >= min_width for a, b in parts):
            return parts
    filled = np.flatnonzero(columns)
    return [(int(filled[0]), int(filled[-1]) + 1)] if filled.size else []


def valley_columns(labels: np.ndarray, n: int, overlap: float = 0.5,
                   values: np.ndarray | None = None, depth: float = 0.0
                   ) -> list[tuple[int, int]]:
    """``(first, end)`` column ranges, left to right, of the upright people in a footprint
    whose valley split (:func:`mk_tracker.detection.pixel_clustering.valley_split`) gave
    ``labels`` (``(h, w)`` int, 1..n on the footprint, 0 off it).

    A part's *columns* are those of its core: with ``values`` (the intensities the split
    ran on, objects on the high side) its pixels within ``depth / 2`` of its own maximum
    (the split's core of a peak), else all its pixels.  The watershed hands a plateau to
    the nearest peak, so a part's full extent may reach under its neighbour; its core does
    not.  The parts are taken in the order of their cores' mean column.  A part whose core
    columns share at least ``overlap`` of the narrower of its range and the current
    person's with the current person's is stacked on it (a head above a torso, legs below
    it: one person, the ranges joined); otherwise it starts the next person.  Two
    neighbours are cut at the emptiest column of the footprint's vertical projection
    (column sums of ``labels > 0``) strictly between their mean core columns; among equals
    the one with the lowest sum of ``values`` (the valley), then the one nearest the
    midpoint.  Each person keeps every footprint pixel of its columns: whole rows, never a
    horizontal cut.  One range (the footprint's columns) when the parts are all stacked;
    ``[]`` for an empty footprint.
    """
    mask = labels > 0
    columns = mask.sum(axis=0).astype(np.float64)
    filled = np.flatnonzero(columns)
    if filled.size == 0:
        return []
    whole = [(int(filled[0]), int(filled[-1]) + 1)]
    cols = np.arange(labels.shape[1], dtype=np.float64)
    heat = (np.where(mask, values, 0.0).sum(axis=0) if values is not None
            else np.zeros(labels.shape[1]))
    parts = []
    for k in range(1, n + 1):
        own = labels == k
        if values is not None and own.any():
            own &= values >= values[own].max() - 0.5 * depth
        counts = own.sum(axis=0).astype(np.float64)
        used = np.flatnonzero(counts)
        if used.size == 0:
            continue
        parts.append((float((counts * cols).sum() / counts.sum()), int(used[0]),
                      int(used[-1]) + 1, counts))
    parts.sort(key=lambda p: p[0])
    people: list[list] = []                 # [first, end, core column counts]
    for _, first, end, counts in parts:
        if people:
            a, b, held = people[-1]
            shared = min(b, end) - max(a, first)
            if shared >= overlap * min(b - a, end - first):
                people[-1] = [min(a, first), max(b, end), held + counts]
                continue
        people.append([first, end, counts])
    if len(people) < 2:
        return whole
    centres = [float((p[2] * cols).sum() / p[2].sum()) for p in people]
    edges = [int(filled[0])]
    for left, right in zip(centres[:-1], centres[1:]):
        lo, hi = max(int(math.floor(left)) + 1, edges[-1] + 1), int(math.ceil(right))
        if hi <= lo:
            continue
        candidates = np.arange(lo, hi)
        middle = 0.5 * (left + right)
        best = np.lexsort((np.abs(candidates - middle), heat[lo:hi], columns[lo:hi]))[0]
        edges.append(int(candidates[best]))
    edges.append(int(filled[-1]) + 1)
    out = [(a, b) for a, b in zip(edges[:-1], edges[1:]) if b > a and columns[a:b].any()]
    return out if len(out) > 1 else whole
