"""A SORT-style tracker (Bewley et al. 2016) as a benchmark peer.

Per track a constant-velocity Kalman filter of the box centre
(:class:`mk_tracker.kalman.ConstantVelocityKalman`) with the box size taken from the last
assigned detection; detections are assigned to predicted boxes by the Hungarian method on
``1 - IoU`` (:func:`mk_tracker.tracking.association.assign`), with SORT's defaults: a match needs
IoU >= 0.3, a track is reported after ``min_hits`` = 3 consecutive hits (or in the first
frames), and deleted after ``max_age`` = 1 frame without a detection.  No appearance, no
re-identification: it is the baseline the multiple-kernel tracker must beat.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mk_tracker.tracking.association import assign
from mk_tracker.boxes import iou_matrix
from mk_tracker.kalman import ConstantVelocityKalman


@dataclass
class _SortTrack:
    id: int
    kf: ConstantVelocityKalman
    size: np.ndarray
    hits: int = 1
    streak: int = 1
    misses: int = 0

    def box(self) -> np.ndarray:
        cx, cy = self.kf.center
        return np.array([cx - self.size[0] / 2, cy - self.size[1] / 2, *self.size])


class SortTracker:
    """SORT-style Kalman + IoU tracker; :meth:`update` once per frame."""

    def __init__(self, *, max_age: int = 1, min_hits: int = 3, iou_threshold: float = 0.3,
                 sigma_u: float = 30.0, sigma_w: float = 4.0) -> None:
        self.max_age, self.min_hits, self.iou_threshold = max_age, min_hits, iou_threshold
        self.sigma_u, self.sigma_w = sigma_u, sigma_w
        self.tracks: list[_SortTrack] = []
        self.next_id = 1
        self.frame_count = 0
        self.last_stamp: float | None = None

    def update(self, stamp: float, detections: list[tuple[float, float, float, float, float]]
               ) -> list[tuple[int, tuple[float, float, float, float]]]:
        self.frame_count += 1
        dt = 0.0 if self.last_stamp is None else stamp - self.last_stamp
        self.last_stamp = stamp
        for t in self.tracks:
            if dt > 0:
                t.kf.predict(dt)
        dets = np.array([d[:4] for d in detections], dtype=np.float64).reshape(-1, 4)
        boxes = np.array([t.box() for t in self.tracks]).reshape(-1, 4)
        cost = 1.0 - iou_matrix(boxes, dets)
        result = assign(cost, max_cost=1.0 - self.iou_threshold)
        for r, k in result.matches:
            t = self.tracks[r]
            x, y, w, h = dets[k]
            t.kf.update((x + w / 2, y + h / 2))
            t.size = np.array([w, h])
            t.hits += 1
            t.streak += 1
            t.misses = 0
        for r in result.unmatched_rows:
            self.tracks[r].misses += 1
            self.tracks[r].streak = 0
        for k in result.unmatched_cols:
            x, y, w, h = dets[k]
            self.tracks.append(_SortTrack(self.next_id, ConstantVelocityKalman(
                (x + w / 2, y + h / 2), sigma_u=self.sigma_u, sigma_w=self.sigma_w),
                np.array([w, h])))
            self.next_id += 1
        self.tracks = [t for t in self.tracks if t.misses <= self.max_age]
        out = []
        for t in self.tracks:
            if t.misses == 0 and (t.streak >= self.min_hits
                                  or self.frame_count <= self.min_hits):
                out.append((t.id, tuple(float(v) for v in t.box())))
        return out
