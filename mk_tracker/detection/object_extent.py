"""A bound on an object's extent: a group of people made into one object far wider than a
person is re-split by K-means, or dropped, instead of being published and carried
(issues #19 and #15).  Not in Schizas et al. (2018), which have no size prior.

Why groups become one object.  In a full-frame pass the support pixels of the sparse
factors (5.1) are clustered by K-means (3.12) with the merge rule (3.13) from ``Z = M_up``;
on the real clip BU-TIV-lab that gives ``M_up = 20`` clusters, none of them larger than half
the frame.  The link rule (``link_gap``: support pixels closer than 4 px are one object,
added so that the default needs no size prior) then joins the clusters of people who touch
into one object of up to 449x448 px (a 512x512 frame): at constant gain 0.93, 8 of the 9
full passes that made a half-frame object made it at the link rule, one at the footprint
merge (``merge_by_footprint``), and ``drop_background_footprints`` dropped none
(benchmarks/diagnose_group_objects.py, docs/benchmark_thermal_gain.md, "Half-frame group
objects").  Algorithm 2 has nothing that
splits an object again: in the tracking passes the object's (5.2) window covers the whole
group, every support pixel in it is the object's, and its footprint is the group's; at the
next full pass the group is found again and matched to the same Kalman filter.

The bound (``detector.extent``, :class:`ObjectExtentConfig`): an object is *oversized*
when its box is wider than ``max_width_fraction`` of the frame's width, or, when a person
size has been learnt (:mod:`mk_tracker.detection.person_size`, with ``split_by_person_size``
or ``split_clusters``), wider than ``max_person_widths`` expected person widths at its
bottom row.  Only the width is bounded: an upright person near the camera can be as tall as
the frame, and people side by side make a group wide.

* Full-frame pass: an oversized object is re-split by K-means (3.12) with more clusters,
  ``Z = 2, 3, ...`` up to ``max_parts``, until no part is oversized: the clusters of the
  column coordinates of its newest-frame footprint's pixels (column ranges: upright
  people side by side).  Parts still oversized at ``max_parts`` are dropped.  The parts
  then go through the tracking passes as any objects, each footprint confined to its
  Voronoi cell.  Objects made by the other splits (``split_by_valleys``, ``split_by_person_size``,
  ``split_clusters``) are not re-split; an oversized one is dropped.
* Tracking pass (``in_tracking``): an object whose footprint grows past the bound (it
  fused with people it touches) keeps the column part of its footprint nearest its Kalman
  prediction, split as above; when that part is still oversized the object is not
  published and its Kalman filter is dropped (it is not carried).  Either way the next
  full-frame pass is brought forward to ``group_recheck_frames`` after the last one, to
  find the others.

Measured (docs/benchmark_thermal_gain.md, "Half-frame group objects"): it removes every
box wider than half the frame on BU-TIV-lab and puts the clip's detections per frame in one
regime, but gives more ids there (6-13 over eight constant gains, against 4-14 without it,
means 9.9 against 7.75), so it is off by default; on the generated crowds it never fires.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from mk_tracker.detection.footprint import _owned_support, _VoronoiCell
from mk_tracker.detection.footprint_split import _Candidate, _footprint_levels
from mk_tracker.detection.pixel_clustering import (_sq_dists, describe_pixels, kmeans,
                                                   stride_sample)
from mk_tracker.parameters import parameter

__all__ = ["ObjectExtent", "ObjectExtentConfig", "oversized_width"]


@dataclass(frozen=True)
class ObjectExtentConfig:
    """The constants of the extent bound (``detector.extent.*``)."""

    bound: bool = parameter(
        False, "an object wider than the bound below (a group) is re-split into column "
        "ranges by K-means (3.12) with more clusters in full-frame passes "
        "(mk_tracker.detection.object_extent; not in the paper; off by default: more ids "
        "on BU-TIV-lab, docs/benchmark_thermal_gain.md)")
    in_tracking: bool = parameter(
        True, "bound, in tracking passes: an object that grows past the bound keeps the "
        "column part nearest its prediction, or is neither published nor carried, and the "
        "next full pass comes group_recheck_frames after the last")
    max_width_fraction: float = parameter(
        0.5, "bound: an object wider than this fraction of the frame's width is oversized "
        "(a group, not a person)", minimum=0.05, maximum=1.0)
    max_person_widths: float = parameter(
        3.0, "bound: ... or wider than this many expected person widths at its bottom row, "
        "once a person size is learnt (split_by_person_size or split_clusters); 0: no such "
        "test", minimum=0.0, maximum=100.0)
    max_parts: int = parameter(
        8, "bound: an oversized object of a full-frame pass is re-split into at most this "
        "many K-means clusters; parts still oversized are dropped", minimum=2, maximum=64)


def oversized_width(width: float, frame_width: float, rule: ObjectExtentConfig,
                    person_width: float | None = None) -> bool:
    """Whether a box ``width`` px wide is wider than the bound: ``max_width_fraction`` of
    ``frame_width``, or ``max_person_widths`` times ``person_width`` (the expected width of
    one person at the box's row) when that is known."""
    if width > rule.max_width_fraction * frame_width:
        return True
    return (person_width is not None and rule.max_person_widths > 0
            and width > rule.max_person_widths * person_width)


class ObjectExtent:
    """Mixin of :class:`~mk_tracker.detection.thermal_detector.ThermalDetector`: the extent
    bound (module docstring).  Uses the detector's ``config``, ``_shape``, ``heights``,
    ``_whole_height`` and ``_footprint``."""

    def _oversized(self, box: tuple[float, float, float, float]) -> bool:
        """Whether a detection box ``(x, y, w, h)`` is wider than the bound."""
        c = self.config
        x, y, w, h = box
        person = None
        if c.extent.max_person_widths > 0 and (c.split_by_person_size or c.split_clusters) \
                and self._whole_height(y, h):
            height = self.heights.height_at(y + h)
            if height is not None:
                person = c.person_aspect * height
        return oversized_width(w, self._shape[1], c.extent, person)

    def _resplit(self, frame: np.ndarray, result: Any, rows: np.ndarray, cols: np.ndarray,
                 bounds: tuple[int, int, int, int]) -> list[Any]:
        """Full-frame pass: the candidates of an oversized object whose support pixels are
        ``(rows, cols)``: its newest-frame footprint split into column ranges
        (:meth:`_column_parts`); the parts still oversized at ``max_parts`` are left out."""
        fp = self._footprint(frame, result.support, rows, cols, bounds)
        if fp is None:
            return []
        score = float(min(1.0, result.variance[rows, cols].mean() / 0.5))
        return [p for p in self._column_parts(frame, result.support, fp, score)
                if not self._oversized(p.box)]

    def _bounded_part(self, frame: np.ndarray, result: Any, regions: list,
                      centres: np.ndarray, k: int, cand: Any) -> Any:
        """Tracking pass: object ``k``'s footprint ``cand`` is wider than the bound (it
        fused with people it touches): the column part of its footprint (inside its
        Voronoi cell) nearest its prediction, or None when that part is still oversized
        (the object is then neither published nor carried).  The next full-frame pass is
        brought forward (``group_recheck_frames``) to find the others."""
        self._oversize_seen = True
        only = [r if j == k else None for j, r in enumerate(regions)]
        _, rows, cols = _owned_support(result.support, only, centres)[k]
        if rows.size < self.config.min_object_pixels:
            return None
        cell = _VoronoiCell(centres, k) if len(centres) > 1 else None
        fp = self._footprint(frame, result.support, rows, cols, regions[k], cell)
        if fp is None:
            return None
        parts = self._column_parts(frame, result.support, fp, cand.score)
        if not parts:
            return None
        px, py = centres[k]
        part = min(parts, key=lambda q: math.dist(q.centroid, (px, py)))
        return None if self._oversized(part.box) else part

    def _column_parts(self, frame: np.ndarray, support: np.ndarray, fp: Any, score: float
                      ) -> list[Any]:
        """A footprint ``((y0, x0), mask)`` split by K-means (3.12) of its pixels' *column*
        coordinates with ``Z = 2, 3, ..., max_parts`` clusters (centroids fitted on a
        stride sample, every pixel to its nearest centroid), one candidate per cluster, a
        column range of the footprint: the first ``Z`` whose parts are all within the
        bound, else those of ``max_parts``.

        Why the footprint and the column: the support of a window is where the group
        *changed* (often its leading edge only, a few pixels wide) while its footprint is
        the group now, and the bound is on the width; K-means of the support's two
        coordinates cut a pair of touching 10x40 px people into seven 16x6 px bands."""
        c = self.config
        (y0, x0), mask = fp
        fr, fc = np.nonzero(mask)
        if fr.size < c.min_object_pixels:
            return []
        levels = _footprint_levels(frame, support, fp)
        points = fc.astype(np.float64)[:, None]
        sample = stride_sample(points)
        parts: list[Any] = []
        for z in range(2, c.extent.max_parts + 1):
            if z > np.unique(sample).size:
                break
            centroids, _ = kmeans(sample, z, seed=0)
            labels = np.argmin(_sq_dists(points, centroids), axis=1)
            parts = []
            for k in range(centroids.shape[0]):
                mine = labels == k
                if np.count_nonzero(mine) < c.min_object_pixels:
                    continue
                part = describe_pixels(fc[mine] + x0, fr[mine] + y0)
                parts.append(_Candidate(part.centroid, part.box, score, part.pixel_count,
                                        *levels))
            if not any(self._oversized(p.box) for p in parts):
                break
        return parts
