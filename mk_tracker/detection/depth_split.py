"""A group's foreground mass cut where its people stand at different depths (issue #13,
real video: a crowd in the middle of the frame stays one foreground region).

Under a camera looking down at a ground plane, a person's feet are lower in the image the
nearer they stand (the same model as :class:`mk_tracker.detection.person_size.PersonHeightModel`,
whose height grows with the row of the feet).  Two people side by side at different depths
make one region whose lowest foreground row per column (the *feet profile*) steps from one
person's feet to the other's.  The width split of :mod:`person_size` cannot see them: it
takes the expected width at the region's lowest row, the nearest person's, so a near
person with one or two smaller people beside or behind them is not wide enough to be split.

:func:`depth_columns` fills the gaps between a person's legs (a morphological closing of
the feet profile over ``window`` columns: the notch between two legs is narrower than a
person) and cuts the region between two columns whose feet rows differ by more than
``step`` times the person height expected at the lower one.  A part narrower than
``min_width(feet row)`` (an arm, a bag, a stride's leg) joins its neighbour with the nearer
feet row.  Not in Chu et al. (2013), whose background subtraction is not described.
"""

from __future__ import annotations

from typing import Callable

import cv2
import numpy as np

__all__ = ["depth_columns", "feet_profile"]


def feet_profile(mask: np.ndarray, window: int) -> np.ndarray:
    """Per column of ``mask`` (2-D, nonzero = foreground) the lowest foreground row, -1 in
    a column without one, closed over ``window`` columns (made odd; notches between legs
    filled, steps kept in place)."""
    mask = mask > 0
    rows = mask.shape[0]
    filled = mask.any(axis=0)
    bottom = np.where(filled, rows - 1 - np.argmax(mask[::-1], axis=0), -1).astype(np.float32)
    if window > 1 and bottom.size > 1:
        kernel = np.ones((1, int(window) | 1), np.uint8)     # odd: centred, no shift
        closed = cv2.morphologyEx(bottom[None, :], cv2.MORPH_CLOSE, kernel,
                                  borderType=cv2.BORDER_REPLICATE)[0]
        bottom = np.where(filled, np.maximum(closed, bottom), -1.0)
    return bottom


def depth_columns(mask: np.ndarray, height_at: Callable[[np.ndarray], np.ndarray],
                  step: float, window: int, min_width: Callable[[float], float]
                  ) -> list[tuple[int, int]]:
    """``(first, end)`` column ranges of ``mask`` (a region's box, rows from its top) that
    stand at different depths; one range (the filled columns) when there is no step.

    ``height_at(rows)``: expected person heights (mask pixels) with feet at ``rows`` of the
    mask (an array in, an array out); ``step``: the smallest feet-row difference cut, as a
    share of that height; ``min_width(row)``: the narrowest part kept with feet at ``row``.
    """
    bottom = feet_profile(mask, window)
    filled = np.flatnonzero(bottom >= 0)
    if filled.size == 0:
        return []
    first, end = int(filled[0]), int(filled[-1]) + 1
    left, right = bottom[first:end - 1], bottom[first + 1:end]
    both = (left >= 0) & (right >= 0)
    expected = np.asarray(height_at(np.maximum(left, right) + 1.0), dtype=np.float64)
    cut = both & (np.abs(right - left) > step * expected)
    edges = [first] + [first + 1 + int(i) for i in np.flatnonzero(cut)] + [end]
    parts = [[a, b] for a, b in zip(edges[:-1], edges[1:])]
    # parts too narrow to be a person join the neighbour whose feet row is nearest theirs
    def feet(part) -> float:
        return float(bottom[part[0]:part[1]].max())
    changed = True
    while changed and len(parts) > 1:
        changed = False
        for i, part in enumerate(parts):
            if part[1] - part[0] >= min_width(feet(part)):
                continue
            if i == 0:
                j = 1
            elif i == len(parts) - 1:
                j = i - 1
            else:
                j = min((i - 1, i + 1), key=lambda k: abs(feet(parts[k]) - feet(part)))
            lo, hi = min(i, j), max(i, j)
            parts[lo] = [parts[lo][0], parts[hi][1]]
            del parts[hi]
            changed = True
            break
    return [(a, b) for a, b in parts]
