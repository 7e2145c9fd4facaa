"""Where an object is in the newest frame: the support pixels it owns and its current-frame
footprint, for the passes of Algorithm 2 (Schizas, Maroulas & Ren 2018, Sec. 5).

The support of a window's factors (5.1) (:mod:`mk_tracker.detection.block_support`) is the
area the objects swept during the window.  This module turns it into objects of the newest
frame (see :mod:`mk_tracker.detection.thermal_detector` for why and what is ours):

* **ownership** (tracking pass): the (5.2) windows of neighbours overlap, so each support
  pixel goes to the object whose Kalman prediction (4.2) is nearest (its Voronoi cell, ties
  to both): :func:`_owned_support`, :class:`_VoronoiCell`;
* **footprint**: the pixels near the support that are dissimilar to the local background in
  the kernel's own sense, ``k(x_t(i), background) < 1/2`` with (3.6) (:func:`_similarity_radius`),
  on the support's side of it, connected to the support: :func:`footprint_mask`.

Each has a numpy reference and a loop compiled with numba (``nogil``) that does the same
arithmetic: :func:`_owned_support` / :func:`_owned_loops`; :func:`footprint_mask` /
:func:`_footprint_loops` (a flood fill) with :func:`_background_level` and
:func:`_sample_median` (the compiled :func:`_median`), called by :func:`_footprint_compiled`;
:func:`_object_loops` does ownership, kernel variances and footprint of one object of a
tracking pass in one compiled call.  ``MK_TRACKER_NO_NUMBA=1`` selects the references;
tests check both give the same detections.  The compiled functions call only functions of
this module, so numba's disk cache (keyed on this file) is never stale.
"""

from __future__ import annotations

import math
from typing import Any, Callable

import cv2
import numpy as np
from scipy.cluster.hierarchy import DisjointSet

from mk_tracker.numba_support import import_numba
from mk_tracker.detection.pixel_clustering import PixelObject

#: "not computed yet" marker for a footprint (``None`` means "computed: nothing there")
_UNSET: Any = object()


def _owned_support(support: np.ndarray, regions: list, centres: np.ndarray
                   ) -> list[tuple[int, np.ndarray, np.ndarray]]:
    """For each object ``k``: the number of support pixels in its (5.2) window
    ``regions[k]`` (``(y0, y1, x0, x1)`` or ``None``) and the rows/columns (frame
    row-major order) of those whose centre is at least as close to its prediction
    ``centres[k]`` as to every other one (ties: to both).  Compiled (one scan of each
    window) when numba is available, else numpy over all support pixels (the reference)."""
    empty = np.zeros(0, dtype=np.int64)
    compiled = _owner_kernel()
    if compiled is not None:
        out = []
        for k, region in enumerate(regions):
            if region is None:
                out.append((0, empty, empty))
                continue
            y0, y1, x0, x1 = region
            rows = np.empty((y1 - y0) * (x1 - x0), dtype=np.int64)
            cols = np.empty_like(rows)
            n_inside, n_mine = compiled(support, y0, y1, x0, x1, centres, k, rows, cols)
            out.append((int(n_inside), rows[:n_mine], cols[:n_mine]))
        return out
    live = [r for r in regions if r is not None]
    if not live:
        return [(0, empty, empty) for _ in regions]
    uy0, uy1 = min(r[0] for r in live), max(r[1] for r in live)
    ux0, ux1 = min(r[2] for r in live), max(r[3] for r in live)
    rows, cols = np.nonzero(support[uy0:uy1, ux0:ux1])
    rows += uy0
    cols += ux0
    px = cols + 0.5
    py = rows + 0.5
    dist = (px[:, None] - centres[None, :, 0]) ** 2 + (py[:, None] - centres[None, :, 1]) ** 2
    bounds = np.array([r if r is not None else (0, 0, 0, 0) for r in regions])
    r, cl = rows[:, None], cols[:, None]
    inside = ((r >= bounds[None, :, 0]) & (r < bounds[None, :, 1])
              & (cl >= bounds[None, :, 2]) & (cl < bounds[None, :, 3]))
    mine = inside & (dist <= dist.min(axis=1)[:, None])
    n_inside = np.count_nonzero(inside, axis=0)
    return [(int(n_inside[k]), rows[mine[:, k]], cols[mine[:, k]]) for k in range(len(regions))]


def _owned_loops(support, y0, y1, x0, x1, centres, k, rows, cols):
    """Compiled :func:`_owned_support` of one window: same distances, same order.
    Returns ``(support pixels in the window, owned pixels written to rows/cols)``."""
    n_inside = 0
    n_mine = 0
    for y in range(y0, y1):
        for x in range(x0, x1):
            if not support[y, x]:
                continue
            n_inside += 1
            px = x + 0.5
            py = y + 0.5
            own = (px - centres[k, 0]) ** 2 + (py - centres[k, 1]) ** 2
            nearest = True
            for j in range(centres.shape[0]):
                if j != k and (px - centres[j, 0]) ** 2 + (py - centres[j, 1]) ** 2 < own:
                    nearest = False
                    break
            if nearest:
                rows[n_mine] = y
                cols[n_mine] = x
                n_mine += 1
    return n_inside, n_mine


_OWNER: list = []


def _owner_kernel():
    """:func:`_owned_loops` compiled with numba, or ``None`` (no numba, or
    ``MK_TRACKER_NO_NUMBA`` set)."""
    if not _OWNER:
        try:
            numba = import_numba()
            _OWNER.append(numba.njit(cache=True, nogil=True)(_owned_loops))
        except ImportError:
            _OWNER.append(None)
    return _OWNER[0]


class _VoronoiCell:
    """Pixels whose centre is at least as close to prediction ``k`` as to every other one
    (the (5.2) windows of neighbours overlap; each pixel goes to the nearest prediction)."""

    def __init__(self, centres: np.ndarray, k: int) -> None:
        self.centres = centres
        self.k = k

    def __call__(self, y0: int, y1: int, x0: int, x1: int) -> np.ndarray:
        """Bool mask of the cell over rows ``y0:y1``, columns ``x0:x1``."""
        gx = np.arange(x0, x1) + 0.5
        gy = (np.arange(y0, y1) + 0.5)[:, None]
        cx, cy = self.centres[self.k]
        d_own = (gx - cx) ** 2 + (gy - cy) ** 2
        allowed = np.ones(d_own.shape, dtype=bool)
        # a prediction farther from the patch than the patch's farthest corner is from the
        # own prediction can win no pixel of it (exact skip)
        reach = max(abs(x0 - cx), abs(x1 - cx)) ** 2 + max(abs(y0 - cy), abs(y1 - cy)) ** 2
        for j, (ox, oy) in enumerate(self.centres):
            if j == self.k:
                continue
            dx = max(x0 - ox, 0.0, ox - x1)
            dy = max(y0 - oy, 0.0, oy - y1)
            if dx * dx + dy * dy > reach:
                continue
            allowed &= d_own <= (gx - ox) ** 2 + (gy - oy) ** 2
        return allowed


_NO_CENTRES = np.zeros((0, 2))


def _similarity_radius(sigma2: float) -> float:
    """``|a - b|`` at which the kernel (3.6) equals 1/2: ``sigma sqrt(2 ln 2)``."""
    return math.sqrt(2.0 * sigma2 * math.log(2.0))


def _median(values: np.ndarray) -> np.float32:
    """``np.median`` of a 1-D float32 array (same value: the middle element, or the float32
    mean of the two middle ones), by one partition without numpy's generic reduction."""
    n = values.size
    half = n // 2
    if n % 2:
        return np.float32(np.partition(values, half)[half])
    part = np.partition(values, (half - 1, half))
    return np.float32((part[half - 1] + part[half]) / np.float32(2.0))


def footprint_mask(frame: np.ndarray, offset: np.float32, support: np.ndarray, rows: np.ndarray,
                   cols: np.ndarray, bounds: tuple[int, int, int, int], margin: int,
                   radius: np.float32, cell: _VoronoiCell | None = None
                   ) -> tuple[tuple[int, int], np.ndarray] | None:
    """Newest-frame pixels of the object whose support is ``(rows, cols)`` (frame
    coordinates; ``frame`` is the newest frame as stored, window units are
    ``frame - offset``), searched inside ``bounds`` ``(y0, y1, x0, x1)`` (its (5.2)
    window, or the frame).

    Inside the support's bounding box grown by ``margin`` (``window_margin``) plus half its
    larger side (parts of the object that did not move have no support), the pixels
    dissimilar to the local background (kernel (3.6) below 1/2, i.e. farther than
    ``radius`` = :func:`_similarity_radius` in window units; background = median of the
    non-support pixels there) and on the same side of it as most of the support (warmer or
    colder) form connected components; those touching the support are the object.
    ``cell`` (the object's :class:`_VoronoiCell`), when given, restricts them.
    Returns ``((y0, x0), mask)`` in frame coordinates, or ``None`` when there is nothing.

    The thresholding and the components are one compiled flood fill from the support
    pixels (:func:`_footprint_loops`, through :func:`footprint_stats`) when numba is
    available, else numpy and ``cv2.connectedComponents`` (the reference; a test checks
    they agree).
    """
    stats = footprint_stats(frame, offset, support, rows, cols, bounds, margin, radius, cell)
    if stats is not _UNSET:
        if stats is None:
            return None
        return stats[0], stats[1] == 1
    by0, by1, bx0, bx1 = bounds
    r0, r1, c0, c1 = int(rows.min()), int(rows.max()) + 1, int(cols.min()), int(cols.max()) + 1
    m = margin + max(r1 - r0, c1 - c0) // 2       # room for parts that stood still
    y0, y1 = max(r0 - m, by0), min(r1 + m, by1)
    x0, x1 = max(c0 - m, bx0), min(c1 + m, bx1)
    patch = frame[y0:y1, x0:x1] - offset                 # window units
    background = patch[~support[y0:y1, x0:x1]]
    if background.size == 0:
        background = (frame[by0:by1, bx0:bx1] - offset)[~support[by0:by1, bx0:bx1]]
    if background.size == 0:
        return None
    step = max(1, background.size // 2048)     # a stride sample is enough for a median
    level = _median(background[::step])
    diff = patch - level
    at_support = diff[rows - y0, cols - x0]
    at_support = at_support[np.abs(at_support) > radius]
    if at_support.size == 0:
        return None
    # one polarity: a warm person in front of a cold pillar is not one object with it
    polarity = np.float32(1.0 if 2 * np.count_nonzero(at_support > 0) >= at_support.size
                          else -1.0)
    fg = (diff * polarity > radius).astype(np.uint8)
    if cell is not None:
        fg &= cell(y0, y1, x0, x1).astype(np.uint8)
    n, labels = cv2.connectedComponents(fg, connectivity=8)
    if n <= 1:
        return None
    lut = np.zeros(n, dtype=bool)
    lut[labels[rows - y0, cols - x0]] = True
    lut[0] = False
    if not lut.any():
        return None
    return (y0, x0), lut[labels]


def footprint_stats(frame: np.ndarray, offset: np.float32, support: np.ndarray,
                    rows: np.ndarray, cols: np.ndarray, bounds: tuple[int, int, int, int],
                    margin: int, radius: np.float32, cell: _VoronoiCell | None) -> Any:
    """The compiled :func:`footprint_mask` (:func:`_footprint_compiled`):
    ``((y0, x0), state, PixelObject)`` (``state == 1`` marks the footprint) or ``None``
    (nothing); ``_UNSET`` when numba is not available."""
    compiled = _footprint_kernel()
    if compiled is None:
        return _UNSET
    centres, k = (cell.centres, cell.k) if cell is not None else (_NO_CENTRES, -1)
    y0, x0, state, n, sx, sy, xmin, xmax, ymin, ymax = compiled(
        frame, offset, support, bounds[0], bounds[1], bounds[2], bounds[3], rows, cols,
        margin, radius, centres, k)
    if n == 0:
        return None
    # describe_pixels of the footprint: continuous centroid, box, count
    obj = PixelObject(centroid=(sx / n + 0.5, sy / n + 0.5),
                      box=(float(xmin), float(ymin), float(xmax + 1 - xmin),
                           float(ymax + 1 - ymin)), pixel_count=int(n))
    return (y0, x0), state, obj




def overlapping_footprints(shape: tuple[int, int], count: int,
                           footprint: Callable[[int], Any]) -> tuple[list, list[list[int]]]:
    """Footprints of ``count`` clusters and the sets of clusters whose footprints share a
    pixel (transitively): one object whose swept support fell apart into bands.

    ``footprint(k)`` gives cluster ``k``'s ``((y0, x0), mask)`` in a ``shape`` frame, or
    None.  Returns the footprints and the sets as lists of cluster indices, each in
    increasing order, the sets ordered by their first member; a cluster without a
    footprint is a set of its own.  The sets are SciPy's disjoint-set forest."""
    owner = np.full(shape, -1, dtype=np.int64)
    sets = DisjointSet(range(count))
    prints = []
    for k in range(count):
        fp = footprint(k)
        prints.append(fp)
        if fp is None:
            continue
        (y0, x0), mask = fp
        region = owner[y0:y0 + mask.shape[0], x0:x0 + mask.shape[1]]
        for other in np.unique(region[mask & (region >= 0)]):
            sets.merge(int(other), k)
        region[mask] = k
    members: dict[int, list[int]] = {}
    for k in range(count):
        members.setdefault(sets[k], []).append(k)
    return prints, list(members.values())


def _footprint_loops(frame, offset, y0, x0, level, radius, rows, cols, centres, k, state,
                     stats):
    """Compiled footprint of :func:`footprint_mask` over the patch of ``state``
    (``(ph, pw)`` int8 zeros at ``(y0, x0)``; values ``frame - offset``): the polarity from
    the support pixels ``(rows, cols)``, then a flood fill (8-connectivity) from them
    through the pixels with ``polarity * (frame - offset - level) > radius`` that lie in the
    Voronoi cell of ``centres[k]`` (``k < 0``: no cell).  Same arithmetic as the numpy path.
    Marks the object's pixels 1 (others visited 2) and returns their number (0: none);
    ``stats`` (int64, 6) receives their patch-coordinate sums and extremes
    ``(sum_c, sum_r, c_min, c_max, r_min, r_max)``."""
    n_seeds = rows.shape[0]
    valid = 0
    warmer = 0
    for s in range(n_seeds):
        d = (frame[rows[s], cols[s]] - offset) - level
        if abs(d) > radius:
            valid += 1
            if d > 0:
                warmer += 1
    if valid == 0:
        return 0
    polarity = np.float32(1.0) if 2 * warmer >= valid else np.float32(-1.0)
    ph, pw = state.shape
    # A span fill: a popped pixel's row run is extended left and right, then the rows
    # above and below are scanned along the run and one pixel past each end (its
    # 8-neighbours); a run of new pixels found there is marked 3 (in, not yet extended) and
    # only its first pixel is pushed.  Every pixel is tested once, and the pixels tested are
    # those of the plain 8-neighbour fill (the footprint, its 8-neighbours and the seeds),
    # so ``state`` ends the same.  The marks have a one-pixel border marked visited (2):
    # no bounds tests; copied into ``state`` at the end.
    mark = np.zeros((ph + 2, pw + 2), dtype=np.int8)
    mark[0, :] = 2
    mark[ph + 1, :] = 2
    mark[:, 0] = 2
    mark[:, pw + 1] = 2
    stack_r = np.empty(ph * pw, dtype=np.int32)   # every pixel is pushed at most once
    stack_c = np.empty(ph * pw, dtype=np.int32)
    for s in range(n_seeds):
        r0 = rows[s] - y0
        c0 = cols[s] - x0
        if mark[r0 + 1, c0 + 1] != 0:
            continue
        if not _in_footprint(frame, offset, r0 + y0, c0 + x0, level, polarity, radius,
                             centres, k):
            mark[r0 + 1, c0 + 1] = 2
            continue
        mark[r0 + 1, c0 + 1] = 3           # marks in padded coordinates from here on
        stack_r[0] = r0 + 1
        stack_c[0] = c0 + 1
        top = 1
        while top > 0:
            top -= 1
            r = stack_r[top]
            c = stack_c[top]
            if mark[r, c] != 3:
                continue                     # its run was extended from another pixel
            mark[r, c] = 1
            lx = c
            rx = c
            for side in range(2):
                step = -1 if side == 0 else 1
                x = c + step
                while True:
                    v = mark[r, x]
                    if v == 3:
                        mark[r, x] = 1
                    elif v == 0 and _in_footprint(frame, offset, r - 1 + y0, x - 1 + x0,
                                                  level, polarity, radius, centres, k):
                        mark[r, x] = 1
                    else:
                        if v == 0:
                            mark[r, x] = 2
                        break
                    x += step
                if side == 0:
                    lx = x + 1
                else:
                    rx = x - 1
            for rr in (r - 1, r + 1):
                fresh = False                # inside a run of new pixels of row rr
                for x in range(lx - 1, rx + 2):
                    if mark[rr, x] != 0:
                        fresh = False
                        continue
                    if _in_footprint(frame, offset, rr - 1 + y0, x - 1 + x0, level,
                                     polarity, radius, centres, k):
                        mark[rr, x] = 3
                        if not fresh:
                            stack_r[top] = rr
                            stack_c[top] = x
                            top += 1
                            fresh = True
                    else:
                        mark[rr, x] = 2
                        fresh = False
    # the object's pixels (marked 1 once the fill ends), counted in one pass over the patch
    count = 0
    sum_c = 0
    sum_r = 0
    c_min = pw
    c_max = -1
    r_min = ph
    r_max = -1
    for r in range(ph):
        for c in range(pw):
            v = mark[r + 1, c + 1]
            state[r, c] = v
            if v == 1:
                count += 1
                sum_c += c
                sum_r += r
                c_min = min(c_min, c)
                c_max = max(c_max, c)
                r_min = min(r_min, r)
                r_max = max(r_max, r)
    stats[0] = sum_c
    stats[1] = sum_r
    stats[2] = c_min
    stats[3] = c_max
    stats[4] = r_min
    stats[5] = r_max
    return count


def _background_level(frame, offset, support, y0, y1, x0, x1, buf):
    """Median (as :func:`_median`) of a stride sample of at most ~2048 of the non-support
    pixels of ``frame[y0:y1, x0:x1] - offset`` in row-major order, like the numpy path's
    ``patch[~support][::step]``; NaN when there is none."""
    n = 0
    for y in range(y0, y1):
        for x in range(x0, x1):
            if not support[y, x]:
                buf[n] = frame[y, x] - offset
                n += 1
    if n == 0:
        return np.float32(np.nan)
    step = max(1, n // 2048)
    return _sample_median(buf[0:n:step])


def _sample_median(sample):
    """:func:`_median` of a float32 sample, compiled: by counting when the values are
    integers spanning less than 65536 (integer encodings; the same order statistics
    exactly), else by a partition."""
    size = sample.shape[0]
    half = size // 2
    lo = sample[0]
    hi = sample[0]
    integral = True
    for i in range(size):
        v = sample[i]
        if v < lo:
            lo = v
        elif v > hi:
            hi = v
        if v != np.floor(v):
            integral = False
    if integral and hi - lo < 65536:
        counts = np.zeros(int(hi - lo) + 1, dtype=np.int64)
        for i in range(size):
            counts[int(sample[i] - lo)] += 1
        seen = 0
        below = lo
        for level in range(counts.shape[0]):
            seen += counts[level]
            if seen >= half and seen - counts[level] < half:
                below = lo + level                  # element half - 1 (0-based)
            if seen > half:
                middle = np.float32(lo + level)     # element half
                if size % 2:
                    return middle
                return np.float32((np.float32(below) + middle) / np.float32(2.0))
    part = np.partition(sample.copy(), half)
    if size % 2:
        return part[half]
    below = part[0]
    for i in range(1, half):
        if part[i] > below:
            below = part[i]
    return np.float32((below + part[half]) / np.float32(2.0))


def _footprint_compiled(frame, offset, support, by0, by1, bx0, bx1, rows, cols, margin, radius,
                        centres, k):
    """All of :func:`footprint_mask` in one compiled call: the patch, the
    background level, the flood fill (:func:`_footprint_loops`) and the footprint's pixel
    statistics.  Returns ``(y0, x0, state, count, sum_x, sum_y, x_min, x_max, y_min,
    y_max)`` (frame coordinates; ``count`` 0: no footprint)."""
    r0 = rows.min()
    r1 = rows.max() + 1
    c0 = cols.min()
    c1 = cols.max() + 1
    m = margin + max(r1 - r0, c1 - c0) // 2
    y0 = max(r0 - m, by0)
    y1 = min(r1 + m, by1)
    x0 = max(c0 - m, bx0)
    x1 = min(c1 + m, bx1)
    state = np.zeros((y1 - y0, x1 - x0), dtype=np.int8)
    buf = np.empty((by1 - by0) * (bx1 - bx0), dtype=frame.dtype)
    level = _background_level(frame, offset, support, y0, y1, x0, x1, buf)
    if np.isnan(level):
        level = _background_level(frame, offset, support, by0, by1, bx0, bx1, buf)
    if np.isnan(level):
        return y0, x0, state, 0, 0, 0, 0, 0, 0, 0
    stats = np.zeros(6, dtype=np.int64)
    count = _footprint_loops(frame, offset, y0, x0, level, radius, rows, cols, centres, k,
                             state, stats)
    if count == 0:
        return y0, x0, state, 0, 0, 0, x1, -1, y1, -1
    # integer sums: the order in which the fill met the pixels does not matter
    return (y0, x0, state, count, stats[0] + count * x0, stats[1] + count * y0,
            stats[2] + x0, stats[3] + x0, stats[4] + y0, stats[5] + y0)


def _in_footprint(frame, offset, y, x, level, polarity, radius, centres, k):
    """Pixel test of :func:`_footprint_loops`: dissimilar to the background on the object's
    side, and in the Voronoi cell of ``centres[k]`` (ties included) when ``k >= 0``."""
    if not ((frame[y, x] - offset) - level) * polarity > radius:
        return False
    if k < 0:
        return True
    gx = x + 0.5
    gy = y + 0.5
    d_own = (gx - centres[k, 0]) ** 2 + (gy - centres[k, 1]) ** 2
    for j in range(centres.shape[0]):
        if j != k and d_own > (gx - centres[j, 0]) ** 2 + (gy - centres[j, 1]) ** 2:
            return False
    return True


_FOOTPRINT: list = []


def _footprint_kernel():
    """:func:`_footprint_compiled` compiled with numba, or ``None`` (no numba, or
    ``MK_TRACKER_NO_NUMBA`` set)."""
    if not _FOOTPRINT:
        try:
            numba = import_numba()
            global _in_footprint, _footprint_loops, _background_level, _sample_median
            _sample_median = numba.njit(cache=True, nogil=True)(_sample_median)
            _in_footprint = numba.njit(cache=True, nogil=True)(_in_footprint)
            _footprint_loops = numba.njit(cache=True, nogil=True)(_footprint_loops)
            _background_level = numba.njit(cache=True, nogil=True)(_background_level)
            _FOOTPRINT.append(numba.njit(cache=True, nogil=True)(_footprint_compiled))
        except ImportError:
            _FOOTPRINT.append(None)
    return _FOOTPRINT[0]


def _object_loops(frame, offset, support, variance, y0, y1, x0, x1, centres, k, cell_centres,
                  cell_k, min_pixels, margin, radius, values):
    """One object of a tracking pass in one compiled call: its support pixels in its (5.2)
    window ``(y0, y1, x0, x1)`` and those it owns (:func:`_owned_loops`); when both number
    at least ``min_pixels``, the kernel variances of the owned ones (in their order, into
    ``values``, one slot per window pixel) and their footprint (:func:`_footprint_compiled`
    with the Voronoi cell ``cell_centres``, ``cell_k``).  Returns ``(n_inside, n_owned,
    count, sum_x, sum_y, x_min, x_max, y_min, y_max)``; ``count`` 0: no footprint (or not
    searched)."""
    size = (y1 - y0) * (x1 - x0)
    rows = np.empty(size, dtype=np.int64)
    cols = np.empty(size, dtype=np.int64)
    near = _near_centres(centres, k, y0, y1, x0, x1)
    n_inside, n_mine = _owned_loops(support, y0, y1, x0, x1, near, 0, rows, cols)
    if n_inside < min_pixels or n_mine < min_pixels:
        return n_inside, n_mine, 0, 0, 0, 0, 0, 0, 0
    for i in range(n_mine):
        values[i] = variance[rows[i], cols[i]]
    if cell_k >= 0:                 # the footprint patch lies inside the window
        cell_centres = _near_centres(cell_centres, cell_k, y0, y1, x0, x1)
        cell_k = 0
    _, _, _, count, sx, sy, xmin, xmax, ymin, ymax = _footprint_compiled(
        frame, offset, support, y0, y1, x0, x1, rows[:n_mine], cols[:n_mine], margin, radius,
        cell_centres, cell_k)
    return n_inside, n_mine, count, sx, sy, xmin, xmax, ymin, ymax


def _near_centres(centres, k, y0, y1, x0, x1):
    """``centres[k]`` followed by the other centres that can be nearer than it to some pixel
    centre of rows ``y0:y1``, columns ``x0:x1`` -- the Voronoi tests against the others
    always pass there, so leaving them out changes no test.  A centre is left out only when
    its distance to the pixel-centre box exceeds the own centre's distance to the box's
    farthest corner by a wide margin (1e-9 relative, far above the rounding of either)."""
    n = centres.shape[0]
    near = np.empty((n, 2))
    near[0, 0] = centres[k, 0]
    near[0, 1] = centres[k, 1]
    if n == 1:
        return near
    gx0, gx1 = x0 + 0.5, x1 - 0.5
    gy0, gy1 = y0 + 0.5, y1 - 0.5
    cx, cy = centres[k, 0], centres[k, 1]
    far = max((gx0 - cx) ** 2, (gx1 - cx) ** 2) + max((gy0 - cy) ** 2, (gy1 - cy) ** 2)
    bound = far * (1.0 + 1e-9) + 1e-6
    m = 1
    for j in range(n):
        if j == k:
            continue
        dx = max(gx0 - centres[j, 0], 0.0, centres[j, 0] - gx1)
        dy = max(gy0 - centres[j, 1], 0.0, centres[j, 1] - gy1)
        if dx * dx + dy * dy > bound:
            continue
        near[m, 0] = centres[j, 0]
        near[m, 1] = centres[j, 1]
        m += 1
    return near[:m]


_OBJECT: list = []


def _object_kernel():
    """:func:`_object_loops` compiled with numba, or ``None`` (no numba, or
    ``MK_TRACKER_NO_NUMBA`` set)."""
    if not _OBJECT:
        owner, footprint = _owner_kernel(), _footprint_kernel()
        if owner is None or footprint is None:
            _OBJECT.append(None)
        else:
            import numba
            global _owned_loops, _footprint_compiled, _near_centres
            _owned_loops, _footprint_compiled = owner, footprint
            _near_centres = numba.njit(cache=True, nogil=True)(_near_centres)
            _OBJECT.append(numba.njit(cache=True, nogil=True)(_object_loops))
    return _OBJECT[0]
