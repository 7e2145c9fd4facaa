"""Whole-person boxes for a detection that holds several people (issue #15).

The sparse kernel covariance detector (Schizas, Maroulas & Ren 2018) reports one object per
connected support; people who touch or overlap in the image become one object, and the
tracker then follows a group.  docs/benchmark_groups.md ("Where the pipeline's loss goes")
measured what that costs: with the detector's own boxes, but each box that holds two or
more people replaced by those people's true boxes, the thermal -> RGB pipeline's MOTA at
640x480 rises from 0.16 / 0.25 to 0.66 / 0.73 with 8 people and from 0.03 / -0.14 to 0.63
/ 0.79 with 15; the same boxes cut into equal column strips gain nothing.  What a group box
needs is one *whole-person* box per person, at the right height and row.

The cover (not in the paper; a ground-plane size prior with a greedy hypothesis cover, the
idea of human-shape hypotheses of Zhao & Nevatia, "Tracking multiple humans in complex
situations", TPAMI 2004, reduced to boxes):

* a person whose feet are at image row ``y`` is ``h(y)`` tall and ``a h(y)`` wide: the
  detector's :class:`~mk_tracker.detection.person_size.PersonHeightModel`, learnt online
  from its isolated (person-shaped) detections, and their mean width / height ``a``;
* a detection wider than ``width_ratio`` expected widths, or taller than ``height_ratio``
  expected heights, at its bottom row is a group;
* its warm pixels (the newest frame, warmer than the scene's background by the similarity
  radius of (3.6)) are covered greedily by person boxes.  Every box with its feet on a row
  inside the detection and its centre on a column across it (rows and columns every
  ``resolution`` person widths) is a candidate when at least ``min_fill`` of it is warm;
  the candidate that holds the most warm pixels no chosen box holds yet is chosen, while
  they are at least ``min_gain`` of its area, up to ``max_people`` boxes;
* a person hidden behind another is found when enough of them shows above or beside the
  front person; one fully hidden is not (nothing shows);
* the premise is a ground plane: the cover acts only while the image row explains
  ``min_explained`` of the learnt heights' variance, with samples from at least
  ``min_people`` of the detector's objects among the samples it remembers.  In a near view
  (BU-TIV-lab, R^2 0.003) a person's height does not follow the row, and person boxes of
  the row's size would cut people into pieces.  One person is not enough: a person who
  walks towards the camera gives heights on a line in any scene (BU-TIV-lab's first 25
  samples are one person, whose box top stays on one row: R^2 1.0). This gate replaced a
  count of 50 samples, set after that clip: the count waited the same for a crowd as for
  that one person (docs/benchmark_groups.md, "The person cover");
* or one height for every row (``level_tolerance``): the samples' feet span at least one
  person height while their heights stay within the tolerance of one value.  R^2 is 0
  there (nothing varies to explain), yet the size is known best: a queue coming down
  stairs, seen from the front, whose people touch along a diagonal and merge into one
  object, while only the first of them is ever seen alone (benchmarks/bench_queue.py:
  2.3-2.4 -> 4.0 detections a frame for 6-9 people). One person suffices here: walking
  across rows at one height is what a ground plane seen from above never shows (a person
  walking towards the camera grows; BU-TIV-lab never passes: its samples span 0.4-0.8
  heights and scatter by 0.26-0.37).

:func:`cover_people` is the pure step (numpy, one vectorised pass over all candidates per
chosen box); :class:`PersonCover` is the thermal detector's mixin that applies it to a
frame's detections.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import cv2
import numpy as np

from mk_tracker.parameters import parameter

__all__ = ["PersonCoverConfig", "PersonCover", "cover_people", "warm_mask"]


@dataclass(frozen=True)
class PersonCoverConfig:
    """The constants of the person cover (``detector.person_cover.*``)."""

    enabled: bool = parameter(
        True, "replace a detection as wide or tall as several people (at the learnt person "
        "size of its row) by whole-person boxes that cover its warm pixels "
        "(mk_tracker.detection.person_cover; not in the paper; docs/benchmark_groups.md)")
    width_ratio: float = parameter(
        1.4, "a detection wider than this many expected person widths at its bottom row is "
        "a group", minimum=1.0, maximum=10.0)
    height_ratio: float = parameter(
        1.3, "... or taller than this many expected person heights", minimum=1.0,
        maximum=10.0)
    min_fill: float = parameter(
        0.5, "a person box is a candidate when at least this fraction of it is warm",
        minimum=0.0, maximum=1.0)
    min_gain: float = parameter(
        0.25, "a further person is chosen while the warm pixels it holds that no chosen box "
        "holds are at least this fraction of its area", minimum=0.0, maximum=1.0)
    resolution: float = parameter(
        0.1, "candidate feet rows and centre columns every this fraction of the expected "
        "person width at the detection's bottom row (at least 1 px)", minimum=0.01,
        maximum=1.0)
    min_explained: float = parameter(
        0.3, "the cover acts only while the image row explains at least this share of the "
        "learnt person heights' variance (R^2 of the height-per-row fit): a ground plane "
        "seen from above; a near indoor view, where heights do not follow the row, has "
        "none (BU-TIV-lab: 0.003; generated crowds 0.4-0.98)", minimum=0.0, maximum=1.0)
    min_people: int = parameter(
        3, "... and only once the samples come from at least this many of the detector's "
        "objects: one person walking towards the camera gives heights on a line that the "
        "row explains in any scene (BU-TIV-lab: its first 25 samples, R^2 1.0, are one "
        "person, whose box top stays on one row)", minimum=1, maximum=100)
    level_tolerance: float = parameter(
        0.1, "the cover also acts, without min_explained and min_people, while the learnt "
        "heights are one height for every row: their feet rows span at least one person "
        "height and the fit changes, and the samples scatter, by at most this fraction of "
        "the mean height over that span (a queue on stairs, a far or level view: R^2 is 0 "
        "there because nothing varies; BU-TIV-lab: span 0.4-0.8 heights, scatter 0.26-0.37); "
        "0 = off", minimum=0.0, maximum=1.0)
    max_people: int = parameter(10, "most person boxes one detection is replaced by",
                                minimum=1, maximum=100)


def warm_mask(frame: np.ndarray, radius: float) -> np.ndarray:
    """Pixels of ``frame`` warmer than the scene's background level by more than ``radius``
    (same units): the level is the median of a 4x4-subsampled copy (the background covers
    most of a frame)."""
    level = float(np.median(frame[::4, ::4]))
    return frame > level + radius


def _integral(mask: np.ndarray) -> np.ndarray:
    """Summed-area table of a bool mask, one row and column of zeros in front (OpenCV)."""
    return cv2.integral(np.ascontiguousarray(mask).view(np.uint8))


def _sums(table: np.ndarray, x0, y0, x1, y1) -> np.ndarray:
    return table[y1, x1] - table[y0, x1] - table[y1, x0] + table[y0, x0]


def cover_people(warm: np.ndarray, box: tuple[float, float, float, float],
                 expected_heights: Callable[[np.ndarray], np.ndarray | None], aspect: float,
                 config: PersonCoverConfig, step: int = 1
                 ) -> list[tuple[float, float, float, float]]:
    """Whole-person boxes ``(x, y, w, h)`` that cover the warm pixels of ``warm`` (bool
    image) inside ``box``, chosen greedily (module docstring); ``[]`` when no candidate
    qualifies (the caller keeps ``box``).  ``expected_heights(rows)`` are the heights of
    people whose feet are at those rows (an array; None: no size known); ``aspect`` their
    width / height;
    ``step`` the px between candidate feet rows and centre columns."""
    rows, cols = warm.shape
    bx, by, bw, bh = (float(v) for v in box)
    x0, x1 = max(int(np.floor(bx)), 0), min(int(np.ceil(bx + bw)), cols)
    y0, y1 = max(int(np.floor(by)), 0), min(int(np.ceil(by + bh)), rows)
    if x1 - x0 < 2 or y1 - y0 < 2:
        return []
    feet = np.arange(y1, y0, -step, dtype=np.float64)      # feet rows, bottom up
    heights = expected_heights(feet)
    if heights is None:
        return []
    tall = heights >= 4.0
    feet, heights = feet[tall], heights[tall]
    if feet.size == 0:
        return []
    centres = np.arange(x0, x1 + 1, step, dtype=np.float64)
    yb = np.repeat(feet, centres.size)
    hh = np.repeat(heights, centres.size)
    xc = np.tile(centres, feet.size)
    ww = aspect * hh
    # candidate boxes in pixel edges; sums over the part inside the image, in a window
    # that holds every candidate (integral images of the window only), while the fill is
    # measured against the whole box, so a box mostly outside the image does not qualify
    cx0 = np.rint(xc - ww / 2.0).astype(np.int64)
    cx1 = np.rint(xc + ww / 2.0).astype(np.int64)
    cy1 = yb.astype(np.int64)
    cy0 = np.rint(yb - hh).astype(np.int64)
    area = np.maximum((cx1 - cx0) * (cy1 - cy0), 1)
    wx0, wx1 = max(int(cx0.min()), 0), min(int(cx1.max()), cols)
    wy0, wy1 = max(int(cy0.min()), 0), min(int(cy1.max()), rows)
    sx0, sx1 = np.clip(cx0, wx0, wx1) - wx0, np.clip(cx1, wx0, wx1) - wx0
    sy0, sy1 = np.clip(cy0, wy0, wy1) - wy0, np.clip(cy1, wy0, wy1) - wy0
    window = warm[wy0:wy1, wx0:wx1]
    fill = _sums(_integral(window), sx0, sy0, sx1, sy1) / area
    keep = np.flatnonzero(fill >= config.min_fill)
    if keep.size == 0:
        return []
    cx0, cx1, cy0, cy1, area = cx0[keep], cx1[keep], cy0[keep], cy1[keep], area[keep]
    sx0, sx1, sy0, sy1 = sx0[keep], sx1[keep], sy0[keep], sy1[keep]
    residual = window.copy()
    chosen: list[tuple[float, float, float, float]] = []
    for _ in range(config.max_people):
        gain = _sums(_integral(residual), sx0, sy0, sx1, sy1)
        k = int(np.argmax(gain))
        if gain[k] < config.min_gain * area[k]:
            break
        chosen.append((float(cx0[k]), float(cy0[k]), float(cx1[k] - cx0[k]),
                       float(cy1[k] - cy0[k])))
        residual[sy0[k]:sy1[k], sx0[k]:sx1[k]] = False
    return chosen


class PersonCover:
    """``person_cover`` on a frame's detections (mixin of the thermal detector, which
    provides ``config``, ``heights``, ``aspects``, ``sampled_objects``, ``_newest`` and
    ``_raw_radius``)."""

    def _cover_aspect(self) -> float:
        """Width / height of one person: the mean of the learnt size samples (once there
        are about 3), else ``person_aspect``."""
        if self.aspects[0] >= 2.5:
            return float(self.aspects[1] / self.aspects[0])
        return self.config.person_aspect

    def _covered(self, detections: list[Any], make: Callable[[Any, tuple], Any]
                 ) -> list[Any]:
        """``detections`` with each group (module docstring) replaced by ``make(detection,
        box)`` for each of its person boxes; the others as they are."""
        c = self.config.person_cover
        if not c.enabled or not detections:
            return detections
        explained = self.heights.explained()
        ground = explained is not None and explained >= c.min_explained and \
            self.sampled_objects() >= c.min_people
        if not ground and not self.heights.is_level(c.level_tolerance):
            return detections
        aspect = self._cover_aspect()
        warm = None
        out = []
        for d in detections:
            x, y, w, h = d.box
            expected = self.heights.height_at(y + h)
            if expected is None or not (w > c.width_ratio * aspect * expected
                                        or h > c.height_ratio * expected):
                out.append(d)
                continue
            if warm is None:
                warm = warm_mask(self._newest(), self._raw_radius())
            step = max(1, int(round(c.resolution * aspect * expected)))
            boxes = cover_people(warm, d.box, self.heights.heights_at, aspect, c, step)
            out.extend([make(d, b) for b in boxes] if boxes else [d])
        return out
