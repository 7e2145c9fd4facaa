"""Pixel-threshold detector: the baseline of Schizas et al. (2018), Table 1.

Every pixel of the newest frame whose normalised intensity exceeds ``threshold`` is
foreground; 8-connected components of at least ``min_area`` pixels are the objects.  It needs
no history and finds warm objects whether they move or not, which is exactly why it
miscounts scenes with static warm objects or objects cooler than the threshold (Sec. 7).

Normalisation as in :mod:`mk_tracker.detection.thermal_image`: mono8 / 255; other encodings by the
robust range of each frame, or a fixed range.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from mk_tracker.parameters import parameter, validate_config
from mk_tracker.stamps import checked_stamp
from mk_tracker.detection.thermal_detector import ThermalDetection
from mk_tracker.detection.thermal_image import (ThermalInputError, as_thermal_array, normalization_map,
                                      normalize, robust_range)


@dataclass(frozen=True)
class ThresholdDetectorConfig:
    """Constants of the threshold baseline."""

    threshold: float = parameter(0.5, "normalised intensity above which a pixel is an object",
                                 minimum=0.0, maximum=1.0)
    min_area: int = parameter(20, "smallest object, px", minimum=1, maximum=10_000_000)
    normalization: str = parameter("auto", "auto: mono8 / 255, others by each frame's robust "
                                   "range; fixed: range_min..range_max",
                                   choices=("auto", "fixed"))
    range_min: float = parameter(0.0, "raw value mapped to 0 (normalization=fixed)")
    range_max: float = parameter(255.0, "raw value mapped to 1 (normalization=fixed)")


class ThresholdDetector:
    """Stateless per-frame threshold detector with the same output type as the kernel one."""

    def __init__(self, config: ThresholdDetectorConfig | None = None) -> None:
        self.config = config if config is not None else ThresholdDetectorConfig()
        validate_config(self.config)
        if self.config.normalization == "fixed" and \
                not self.config.range_max > self.config.range_min:
            raise ThermalInputError("range_max must be above range_min for fixed normalisation")
        self.last_mode = "frame"

    def reset(self) -> None:
        """Nothing to forget; present for interface parity with the kernel detector."""

    def process(self, frame: Any, stamp: float, encoding: str | None = None
                ) -> list[ThermalDetection]:
        """Objects of one raw frame (``stamp`` is only checked, the detector keeps no time)."""
        raw, enc = as_thermal_array(frame, encoding)
        checked_stamp(stamp, ThermalInputError)
        c = self.config
        if c.normalization == "fixed":
            offset, scale = normalization_map(enc, (c.range_min, c.range_max))
        elif enc == "mono8":
            offset, scale = normalization_map(enc, None)
        else:
            rng = robust_range(raw)
            if rng is None:
                return []
            offset, scale = normalization_map(enc, rng)
        img = normalize(raw, offset, scale)
        mask = np.nan_to_num(img, nan=-np.inf) > np.float32(c.threshold)
        if not mask.any():
            return []
        n, labels, stats, centroids = cv2.connectedComponentsWithStats(
            mask.astype(np.uint8), connectivity=8)
        out = []
        for k in range(1, n):
            x, y, w, h, area = (int(v) for v in stats[k])
            if area < c.min_area:
                continue
            vals = img[labels == k]
            score = float(np.clip(np.nanmean(vals), 0.0, 1.0))
            cx, cy = centroids[k]
            out.append(ThermalDetection(box=(float(x), float(y), float(w), float(h)),
                                        centroid=(float(cx) + 0.5, float(cy) + 0.5),
                                        score=score, pixel_count=area))
        return out
