"""Objects followed before they met are kept apart at a full-frame pass (issue #15).
Not in Schizas et al. (2018).

Where groups form.  In a full-frame pass K-means (3.12) with the merge rule (3.13) gives
separate clusters for people who walk close together; the link rule (``link_gap``: support
pixels closer than 4 px are one object) and the footprint merge (``merge_by_footprint``)
join them into one object, and Algorithm 2 keeps that object's Kalman filter (2.1)-(2.3) at
the next passes (docs/benchmark_thermal_gain.md, "Half-frame group objects").  The other
splits cut a group by a person size, which does not hold on the real clip BU-TIV-lab.

The rule (``detector.keep_apart``, :class:`KeepApartConfig`) needs no size: Algorithm 2
already keeps a Kalman filter per object, so two people who were two objects before they
came close are two objects while they pass.  In a full-frame pass, an object whose
newest-frame footprint box holds the Kalman predictions (4.2) of two or more *seeds* is
split: K-means (3.12) of its footprint pixels' coordinates started at those predictions
(centroids fitted on a stride sample, every pixel to its nearest centroid), one candidate
per cluster.  The object is kept whole when a cluster ends nearer another seed than its
own: two filters predicted at one place (one object) leave a cluster empty, K-means
refills it elsewhere and would cut the object into bands (without this check BU-TIV-lab
had tracks taller than the frame).  The candidates are then matched to the filters as any others
(Hungarian matching on predicted-centroid distance), so each seed keeps its id.

A seed is an object found in the newest frame (no missed frame) that was found as an object
of its own, not as a part made by this rule, at ``min_full_passes`` full-frame passes.
Parts made by the rule do not count, so a group never confirms itself; with
``min_full_passes`` >= 2 two pieces of one person found at a single pass do not become a
permanent split.

Tracking passes need nothing more: there Algorithm 2 searches each object in its own (5.2)
window, and where two windows overlap every support and footprint pixel already belongs to
the object whose prediction is nearest (the Voronoi cells of
:mod:`mk_tracker.detection.footprint`), which is the same assignment to the nearest
prediction without the K-means refinement.  A group is made only where the full pass has a
single object for it.

Measured (docs/benchmark_groups.md, "Previous objects kept apart"): off by default.  Held
out it raises MOTA / IDF1 over 8 and 15 people from 0.027 / 0.303 to 0.043 / 0.317, but
on BU-TIV-lab it gives 8 ids against 7 (constant-gain control 8.0 against 7.75); it
cannot split people never seen apart.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from mk_tracker.detection.footprint_split import _Candidate, _footprint_levels
from mk_tracker.detection.pixel_clustering import (_sq_dists, describe_pixels, kmeans,
                                                   stride_sample)
from mk_tracker.parameters import parameter

__all__ = ["KeepApart", "KeepApartConfig", "seeds_inside"]


@dataclass(frozen=True)
class KeepApartConfig:
    """The constants of the rule (``detector.keep_apart.*``)."""

    enabled: bool = parameter(
        False, "full-frame passes: an object whose footprint box holds the Kalman "
        "predictions of two or more confirmed objects is split by K-means (3.12) started at "
        "those predictions, so people followed apart stay apart while they pass "
        "(mk_tracker.detection.keep_apart; not in the paper; needs "
        "current_frame_refinement)")
    min_full_passes: int = parameter(
        2, "keep_apart: an object acts as a seed only when it was found as an object of its "
        "own (not a part made by this rule) at this many full-frame passes and in the "
        "newest frame", minimum=1, maximum=1000)


def seeds_inside(box: tuple[float, float, float, float], points: np.ndarray) -> np.ndarray:
    """Indices of the ``points`` (n, 2) ``(x, y)`` inside ``box`` ``(x, y, w, h)``."""
    if points.size == 0:
        return np.zeros(0, dtype=np.int64)
    x, y, w, h = box
    inside = ((points[:, 0] >= x) & (points[:, 0] <= x + w)
              & (points[:, 1] >= y) & (points[:, 1] <= y + h))
    return np.flatnonzero(inside)


class KeepApart:
    """Mixin of :class:`~mk_tracker.detection.thermal_detector.ThermalDetector`: the rule of
    the module docstring.  Uses the detector's ``config``, ``_tracks``, ``_last_stamp`` and
    ``_footprint``; each ``_Track`` counts ``passes``, the full passes at which it was found
    as an object of its own."""

    def _seed_points(self) -> np.ndarray:
        """The Kalman predictions (4.2) at the newest stamp of the objects that may act as
        seeds, ``(n, 2)``."""
        rule = self.config.keep_apart
        stamp = self._last_stamp
        points = []
        for tr in self._tracks:
            if tr.missed == 0 and tr.passes >= rule.min_full_passes:
                dt = stamp - tr.stamp
                points.append(tr.kf.predicted(dt)[0][:2] if dt > 0 else tr.kf.center)
        return np.array(points, dtype=np.float64).reshape(-1, 2)

    def _apart_parts(self, frame: np.ndarray, result: Any, rows: np.ndarray, cols: np.ndarray,
                     bounds: tuple[int, int, int, int], cand: Any, footprint: Any,
                     seeds: np.ndarray) -> list[Any] | None:
        """Full-frame pass: the parts of candidate ``cand`` (support ``(rows, cols)``, its
        footprint ``footprint`` or ``_UNSET``/None when not at hand) when its box holds two
        or more ``seeds``, else None (keep it whole).

        The footprint's pixel coordinates are clustered by K-means (3.12) started at the
        seeds inside the box; clusters smaller than ``min_object_pixels`` are left out.  The
        object is kept whole when a cluster ends nearer another seed than its own, or when
        fewer than two parts are left."""
        inside = seeds_inside(cand.box, seeds)
        if inside.size < 2:
            return None
        fp = footprint if isinstance(footprint, tuple) else None
        if fp is None:
            fp = self._footprint(frame, result.support, rows, cols, bounds)
        if fp is None:
            return None
        (y0, x0), mask = fp
        fr, fc = np.nonzero(mask)
        # pixel centres, as the centroids (and so the Kalman predictions) are continuous
        points = np.column_stack([fc + x0 + 0.5, fr + y0 + 0.5]).astype(np.float64)
        if points.shape[0] < 2 * self.config.min_object_pixels:
            return None
        sample = stride_sample(points)
        start = seeds[inside]
        centroids, _ = kmeans(sample, init=start)
        # each cluster must stay the one nearest its own seed: seeds in one place (two
        # filters on one object) would otherwise cut it where K-means refills the empty one
        own = np.argmin(_sq_dists(start, centroids), axis=1)
        if centroids.shape[0] != start.shape[0] or np.unique(own).size != own.size:
            return None
        labels = np.argmin(_sq_dists(points, centroids), axis=1)
        levels = _footprint_levels(frame, result.support, fp)
        parts = []
        for k in range(centroids.shape[0]):
            mine = labels == k
            if np.count_nonzero(mine) < self.config.min_object_pixels:
                continue
            part = describe_pixels(fc[mine] + x0, fr[mine] + y0)
            parts.append(_Candidate(part.centroid, part.box, cand.score, part.pixel_count,
                                    *levels))
        return parts if len(parts) >= 2 else None
