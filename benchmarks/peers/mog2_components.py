"""Plain OpenCV background subtraction as a peer detector (issue #13's reference recipe).

OpenCV MOG2 with ``history`` 200 and ``varThreshold`` 16, its shadow test on and shadow
pixels (value 127) dropped, a 5x5 opening then closing, and the bounding boxes of the
connected components that are person-shaped: at least ``min_area`` pixels and taller than
wide (height / width between 1 and 5).  No size learning, no splitting or joining, no
bootstrap: what a user would write in an afternoon, the baseline that
:class:`mk_tracker.detection.background_detector.BackgroundDetector` must beat.
"""

from __future__ import annotations

import cv2
import numpy as np


class Mog2Components:
    """``detect(bgr)`` -> list of ``(x, y, w, h, score)`` boxes, score 1."""

    def __init__(self, *, history: int = 200, var_threshold: float = 16.0,
                 kernel: int = 5, min_area: int = 100,
                 aspect_range: tuple[float, float] = (1.0, 5.0)) -> None:
        self.model = cv2.createBackgroundSubtractorMOG2(history=history,
                                                        varThreshold=var_threshold,
                                                        detectShadows=True)
        self.kernel = cv2.getStructuringElement(cv2.MORPH_RECT, (kernel, kernel))
        self.min_area = min_area
        self.aspect_range = aspect_range

    def detect(self, bgr: np.ndarray) -> list[tuple[float, float, float, float, float]]:
        mask = self.model.apply(bgr)
        mask = np.where(mask == 255, 255, 0).astype(np.uint8)      # shadows (127) dropped
        mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, self.kernel)
        mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, self.kernel)
        n, _, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
        low, high = self.aspect_range
        out = []
        for x, y, w, h, area in stats[1:n]:
            if area >= self.min_area and low <= h / max(w, 1) <= high:
                out.append((float(x), float(y), float(w), float(h), 1.0))
        return out
