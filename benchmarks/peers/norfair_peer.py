"""Adapter running the ``norfair`` tracker (2.1.x) on the same box detections.

Boxes become norfair two-point detections (top-left, bottom-right) compared with norfair's
IoU distance (``1 - IoU``).  ``distance_threshold`` 0.7 (a match needs IoU > 0.3, as for
SORT), ``initialization_delay`` 2 (three hits, as SORT's ``min_hits``) and
``hit_counter_max`` 15 frames of coasting are norfair's documented defaults for this use.
"""

from __future__ import annotations

import numpy as np
from norfair import Detection, Tracker


class NorfairPeer:
    def __init__(self, *, distance_threshold: float = 0.7, hit_counter_max: int = 15,
                 initialization_delay: int = 2) -> None:
        self.tracker = Tracker(distance_function="iou", distance_threshold=distance_threshold,
                               hit_counter_max=hit_counter_max,
                               initialization_delay=initialization_delay)

    def update(self, stamp: float, detections: list[tuple[float, float, float, float, float]]
               ) -> list[tuple[int, tuple[float, float, float, float]]]:
        dets = [Detection(np.array([[x, y], [x + w, y + h]], dtype=np.float64),
                          scores=np.array([s, s], dtype=np.float64))
                for x, y, w, h, s in detections]
        out = []
        for obj in self.tracker.update(detections=dets):
            (x0, y0), (x1, y1) = obj.estimate
            if x1 > x0 and y1 > y0 and obj.id is not None:
                out.append((int(obj.id), (float(x0), float(y0), float(x1 - x0),
                                          float(y1 - y0))))
        return out
