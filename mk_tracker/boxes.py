"""Axis-aligned boxes in image coordinates.

Convention used everywhere in mk_tracker: a box is ``(x, y, w, h)`` in pixels, ``(x, y)`` the
top-left corner, ``w``/``h`` the full width and height, as floats.  Pixel ``(c, r)`` covers
``[c, c+1) x [r, r+1)``, so a box ``(0, 0, W, H)`` covers a whole ``W x H`` image.
vision_msgs uses the box *centre* instead; :func:`xywh_to_center` and :func:`center_to_xywh`
convert.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

BoxLike = Sequence[float]


class InvalidBoxError(ValueError):
    """A box is not finite or has a non-positive width or height."""


def as_box(box: BoxLike) -> np.ndarray:
    """Return ``box`` as a float64 array of 4, raising :class:`InvalidBoxError` if unusable."""
    try:
        arr = np.asarray(box, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise InvalidBoxError(f"box {box!r} is not four numbers") from exc
    if arr.shape != (4,):
        raise InvalidBoxError(f"box must have 4 values (x, y, w, h), got {arr.shape[0]}")
    if not np.all(np.isfinite(arr)):
        raise InvalidBoxError(f"box {arr.tolist()} has a NaN or infinite value")
    if arr[2] <= 0 or arr[3] <= 0:
        raise InvalidBoxError(f"box {arr.tolist()} has a non-positive width or height")
    return arr


def is_valid_box(box: BoxLike) -> bool:
    """True when ``box`` is four finite numbers with positive width and height."""
    try:
        as_box(box)
    except InvalidBoxError:
        return False
    return True


def xywh_to_center(box: BoxLike) -> tuple[float, float, float, float]:
    """``(x, y, w, h)`` -> ``(cx, cy, w, h)``."""
    x, y, w, h = (float(v) for v in box)
    return x + w / 2.0, y + h / 2.0, w, h


def center_to_xywh(cx: float, cy: float, w: float, h: float) -> tuple[float, float, float, float]:
    """``(cx, cy, w, h)`` -> ``(x, y, w, h)``."""
    return float(cx) - w / 2.0, float(cy) - h / 2.0, float(w), float(h)


def box_center(box: BoxLike) -> np.ndarray:
    """Centre ``(cx, cy)`` of a box."""
    x, y, w, h = (float(v) for v in box)
    return np.array([x + w / 2.0, y + h / 2.0])


def intersection_area(a: BoxLike, b: BoxLike) -> float:
    """Area of the intersection of two boxes (0 when they do not overlap)."""
    ax, ay, aw, ah = (float(v) for v in a)
    bx, by, bw, bh = (float(v) for v in b)
    iw = min(ax + aw, bx + bw) - max(ax, bx)
    ih = min(ay + ah, by + bh) - max(ay, by)
    if iw <= 0 or ih <= 0:
        return 0.0
    return iw * ih


def iou(a: BoxLike, b: BoxLike) -> float:
    """Intersection over union of two boxes, in [0, 1]; 0 for degenerate boxes."""
    inter = intersection_area(a, b)
    union = float(a[2]) * float(a[3]) + float(b[2]) * float(b[3]) - inter
    if not (union > 0) or not math.isfinite(union):
        return 0.0
    return inter / union


def iou_matrix(boxes_a: np.ndarray, boxes_b: np.ndarray) -> np.ndarray:
    """Pairwise IoU of ``(N, 4)`` and ``(M, 4)`` box arrays, shape ``(N, M)``."""
    a = np.asarray(boxes_a, dtype=np.float64).reshape(-1, 4)
    b = np.asarray(boxes_b, dtype=np.float64).reshape(-1, 4)
    if a.shape[0] == 0 or b.shape[0] == 0:
        return np.zeros((a.shape[0], b.shape[0]))
    ax0, ay0 = a[:, 0:1], a[:, 1:2]
    ax1, ay1 = ax0 + a[:, 2:3], ay0 + a[:, 3:4]
    bx0, by0 = b[:, 0], b[:, 1]
    bx1, by1 = bx0 + b[:, 2], by0 + b[:, 3]
    iw = np.clip(np.minimum(ax1, bx1) - np.maximum(ax0, bx0), 0.0, None)
    ih = np.clip(np.minimum(ay1, by1) - np.maximum(ay0, by0), 0.0, None)
    inter = iw * ih
    union = (a[:, 2:3] * a[:, 3:4]) + (b[:, 2] * b[:, 3]) - inter
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where(union > 0, inter / union, 0.0)
    return np.nan_to_num(out, nan=0.0, posinf=0.0, neginf=0.0)


def clip_box(box: BoxLike, width: int, height: int) -> tuple[float, float, float, float] | None:
    """The part of ``box`` inside a ``width x height`` image, or None if nothing is inside."""
    x, y, w, h = (float(v) for v in box)
    x0, y0 = max(x, 0.0), max(y, 0.0)
    x1, y1 = min(x + w, float(width)), min(y + h, float(height))
    if x1 <= x0 or y1 <= y0:
        return None
    return x0, y0, x1 - x0, y1 - y0


def transform_box(box: BoxLike, homography: np.ndarray) -> tuple[float, float, float, float]:
    """Map a box through a 3x3 homography; returns the axis-aligned hull of its 4 corners.

    Raises :class:`InvalidBoxError` when a corner maps to infinity (a corner on the
    homography's vanishing line) or the result is degenerate.
    """
    x, y, w, h = (float(v) for v in as_box(box))
    corners = np.array([[x, y, 1.0], [x + w, y, 1.0], [x, y + h, 1.0], [x + w, y + h, 1.0]])
    mapped = corners @ np.asarray(homography, dtype=np.float64).T
    z = mapped[:, 2]
    if np.any(np.abs(z) < 1e-12) or not np.all(np.isfinite(mapped)):
        raise InvalidBoxError(f"box {box!r} maps to infinity under the homography")
    pts = mapped[:, :2] / z[:, None]
    x0, y0 = pts.min(axis=0)
    x1, y1 = pts.max(axis=0)
    out = as_box((x0, y0, x1 - x0, y1 - y0))
    return float(out[0]), float(out[1]), float(out[2]), float(out[3])
