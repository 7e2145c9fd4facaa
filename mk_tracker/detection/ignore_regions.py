"""Ignore regions: image boxes where nothing is detected (issue #19).

Real cameras have pixels that change without a person in them: a burned-in clock or frame
counter, a heater, a screen, a reflection.  The kernel covariance detector (Schizas et al.
2018) finds what *changes* between frames, so an overlay that changes every frame is found
as an object in most frames.  An ignore region removes it at the source, for every detector
method, in both nodes and offline (the same :func:`mask_regions` runs everywhere):

* before detection the region's pixels are set to the coldest value of the image's type
  (0): constant over time, so no change is seen there, and cold, so no threshold fires;
* after detection, a box whose centre lies inside a region is dropped (a blob of a person
  next to the region can still reach into it; its centre cannot).

Regions are given as a flat list ``[x, y, w, h, x, y, w, h, ...]`` in pixels (top-left
corner, as ``vision_msgs`` boxes are after conversion), which a ROS double-array parameter
can hold.  A quadruple with ``w == 0`` or ``h == 0`` is a placeholder and ignored, so the
default ``[0, 0, 0, 0]`` means "no region" (an empty array has no type in ROS 2).
"""

from __future__ import annotations

import math
from typing import Any, Iterable, Sequence

import numpy as np

Region = tuple[float, float, float, float]


def parse_regions(flat: Sequence[float]) -> tuple[Region, ...]:
    """The regions of a flat ``[x, y, w, h, ...]`` list, placeholders left out.

    Raises ValueError for a length that is not a multiple of 4, a non-finite value, or a
    negative width/height."""
    values = [float(v) for v in flat]
    if len(values) % 4:
        raise ValueError(f"ignore_regions needs groups of 4 values [x, y, w, h, ...], got "
                         f"{len(values)} values")
    regions = []
    for k in range(0, len(values), 4):
        x, y, w, h = values[k:k + 4]
        if not all(math.isfinite(v) for v in (x, y, w, h)):
            raise ValueError(f"ignore_regions: region {k // 4} {values[k:k + 4]} is not finite")
        if w < 0 or h < 0:
            raise ValueError(f"ignore_regions: region {k // 4} has a negative size")
        if w > 0 and h > 0:
            regions.append((x, y, w, h))
    return tuple(regions)


def _pixel_span(x: float, w: float, size: int) -> slice:
    """The pixel indices covered by ``[x, x + w)``: every pixel the box touches."""
    lo = max(0, int(math.floor(x)))
    hi = min(size, int(math.ceil(x + w)))
    return slice(lo, max(lo, hi))


def mask_regions(frame: np.ndarray, regions: Iterable[Region]) -> np.ndarray:
    """A copy of ``frame`` with every region's pixels set to 0 (the original when there is
    no region).  Works for any image shape ``HxW`` or ``HxWxC``."""
    regions = tuple(regions)
    if not regions:
        return frame
    out = np.array(frame, copy=True)
    height, width = out.shape[:2]
    for x, y, w, h in regions:
        out[_pixel_span(y, h, height), _pixel_span(x, w, width)] = 0
    return out


def centre_inside(box: Sequence[float], regions: Iterable[Region]) -> bool:
    """Whether the centre of ``box`` ``(x, y, w, h)`` lies in one of ``regions``."""
    cx, cy = float(box[0]) + float(box[2]) / 2.0, float(box[1]) + float(box[3]) / 2.0
    return any(x <= cx < x + w and y <= cy < y + h for x, y, w, h in regions)


class MaskedDetector:
    """A detector that sees its frames with the ignore regions masked and reports no box
    centred in one.  Every other attribute is the wrapped detector's."""

    def __init__(self, detector: Any, regions: Sequence[Region]) -> None:
        self.detector = detector
        self.regions = tuple(regions)

    def process(self, frame: np.ndarray, *args: Any, **kwargs: Any) -> list:
        found = self.detector.process(mask_regions(frame, self.regions), *args, **kwargs)
        return [d for d in found if not centre_inside(_box_of(d), self.regions)]

    def __getattr__(self, name: str) -> Any:
        return getattr(self.detector, name)


def _box_of(detection: Any) -> Sequence[float]:
    box = getattr(detection, "box", detection)
    return tuple(box)
