"""Kernel layouts: where the kernels of a multiple-kernel target sit inside its box.

Chu et al. 2013, Sec. IV-A (Fig. 4) and Sec. V-C (Fig. 14).  Each kernel is an ellipse inscribed
in a rectangle of the box; a layout is returned as kernel centres ``(N, 2)`` and half-axes
``(N, 2)`` (``(a_x, a_y)``, the kernel bandwidths along x and y), in image pixels.

The layouts, for a box ``(x, y, w, h)`` (fractions of ``w`` and ``h``, measured from the
top-left corner):

* **1 kernel** -- the whole box (the single-kernel mean shift of Comaniciu et al.).
* **2 kernels** (Fig. 4a) -- the upper 55 % ``[0, 0.55]`` and the lower 55 % ``[0.45, 1]`` of
  the height, full width; they overlap by 10 % of the height, i.e. 18 % of a kernel's area.
* **4 kernels** (Fig. 4b) -- a 2 x 2 grid: columns ``[0, 0.55]`` and ``[0.45, 1]`` of the width,
  rows ``[0, 0.55]`` and ``[0.45, 1]`` of the height.  Side-by-side or stacked neighbours share
  18 % of a kernel's rectangle, diagonal neighbours 3 %.  Occlusion from the left, right,
  top or bottom leaves at least two kernels well observed.
* **6 kernels** (Fig. 14b) -- 3 rows x 2 columns: rows ``[0, 0.38]``, ``[0.31, 0.69]``,
  ``[0.62, 1]`` (head/shoulders, torso, legs), columns as for 4 kernels.  Neighbours share at
  most 18.4 % of a kernel's rectangle.
* **5 kernels** (Fig. 14a) -- the 6-kernel layout with the top row merged into one full-width
  kernel (the head and shoulders are too narrow to split in two).  Overlap is again at most
  18.4 % of the smaller kernel's rectangle.

So for every layout the overlap between any pair of kernels stays below 20 % of the smaller
kernel's rectangle (Sec. V-C: "the overlapping area between any pair of the kernels should be
limited"), which :func:`max_pairwise_overlap` measures and the tests check.
"""

from __future__ import annotations

import numpy as np

from mk_tracker.boxes import BoxLike, InvalidBoxError, as_box

SUPPORTED_KERNEL_COUNTS = (1, 2, 4, 5, 6)

#: Fraction of the box each stacked pair of rows/columns overlaps by in the 2/4 layouts.
_HALF = ((0.0, 0.55), (0.45, 1.0))
#: Three rows for the 5/6 layouts.
_THIRDS = ((0.0, 0.38), (0.31, 0.69), (0.62, 1.0))
_FULL = ((0.0, 1.0),)


def layout_fractions(num_kernels: int) -> np.ndarray:
    """Kernel rectangles as fractions of the box, shape ``(N, 4)``: ``(fx0, fy0, fx1, fy1)``.

    Kernels are ordered top to bottom, then left to right.
    """
    if num_kernels == 1:
        cells = [(c, r) for r in _FULL for c in _FULL]
    elif num_kernels == 2:
        cells = [(c, r) for r in _HALF for c in _FULL]
    elif num_kernels == 4:
        cells = [(c, r) for r in _HALF for c in _HALF]
    elif num_kernels == 5:
        cells = [(_FULL[0], _THIRDS[0])] + [(c, r) for r in _THIRDS[1:] for c in _HALF]
    elif num_kernels == 6:
        cells = [(c, r) for r in _THIRDS for c in _HALF]
    else:
        raise ValueError(f"num_kernels must be one of {SUPPORTED_KERNEL_COUNTS}, "
                         f"got {num_kernels}")
    return np.array([(c[0], r[0], c[1], r[1]) for c, r in cells], dtype=np.float64)


def layout_columns(num_kernels: int) -> np.ndarray:
    """Which column of the box each kernel of the layout covers, shape ``(N,)``: ``0`` the
    left column ``[0, 0.55]``, ``1`` the right column ``[0.45, 1]``, ``-1`` the full width
    (both).  Layouts of 1 and 2 kernels have only full-width kernels (no left/right
    structure).  Raises ``ValueError`` for an unsupported kernel count."""
    frac = layout_fractions(num_kernels)
    full = (frac[:, 0] <= 0.0) & (frac[:, 2] >= 1.0)
    return np.where(full, -1, np.where(frac[:, 0] <= 0.0, 0, 1)).astype(np.int64)


#: Distance between the centres of the left and the right kernel column (4-6 kernels), as
#: a fraction of the box width: the two columns are equally wide, so their centres are as
#: far apart as their left edges (0.45).
COLUMN_SPACING = _HALF[1][0] - _HALF[0][0]


def column_best(similarities: np.ndarray, num_kernels: int) -> tuple[float, float]:
    """The best kernel similarity ``rho_i`` in the left and in the right column of the box
    (a full-width kernel counts for both; for layouts without columns, 1 and 2 kernels, both
    are the best similarity).  NaN similarities count as 0.  Raises ``ValueError`` when the
    number of similarities is not ``num_kernels``."""
    s = np.asarray(similarities, dtype=np.float64).reshape(-1)
    if s.size != num_kernels:
        raise ValueError(f"{s.size} kernel similarities for a {num_kernels}-kernel layout")
    s = np.where(np.isfinite(s), s, 0.0)
    cols = layout_columns(num_kernels)
    best = []
    for c in (0, 1):
        mine = s[(cols == c) | (cols == -1)]
        best.append(float(mine.max()) if mine.size else 0.0)
    return best[0], best[1]


def has_columns(num_kernels: int) -> bool:
    """Whether the layout has a left and a right kernel column (4, 5 and 6 kernels)."""
    cols = layout_columns(num_kernels)
    return bool(np.any(cols == 0) and np.any(cols == 1))


def column_coverage(similarities: np.ndarray, num_kernels: int) -> float:
    """How well the worse-seen column of a target is seen: the lower of the two
    :func:`column_best` values.  A target whose box lies half on it and half on background
    scores ~0 here however well the kernels of its other column match; for layouts without
    columns (1, 2 kernels) it is the best similarity.  Raises ``ValueError`` when the number
    of similarities is not ``num_kernels``."""
    return min(column_best(similarities, num_kernels))


def kernel_layout(box: BoxLike, num_kernels: int) -> tuple[np.ndarray, np.ndarray]:
    """Centres ``(N, 2)`` and half-axes ``(N, 2)`` of the kernels of ``box``.

    Raises :class:`mk_tracker.boxes.InvalidBoxError` for an unusable box and ``ValueError``
    for an unsupported kernel count.
    """
    x, y, w, h = as_box(box)
    frac = layout_fractions(num_kernels)
    x0 = x + frac[:, 0] * w
    x1 = x + frac[:, 2] * w
    y0 = y + frac[:, 1] * h
    y1 = y + frac[:, 3] * h
    centres = np.stack([(x0 + x1) / 2.0, (y0 + y1) / 2.0], axis=1)
    half_axes = np.stack([(x1 - x0) / 2.0, (y1 - y0) / 2.0], axis=1)
    return centres, half_axes


def kernels_bounding_box(centres: np.ndarray, half_axes: np.ndarray
                         ) -> tuple[float, float, float, float]:
    """Box ``(x, y, w, h)`` spanned by the kernels' extremes (Chu eq. (14)).

    ``x_min``/``x_max``/``y_min``/``y_max`` are the extremes of the kernel ellipses; the
    box centre is ``((x_min + x_max)/2, (y_min + y_max)/2)``, the centroid of eq. (14).
    """
    c = np.asarray(centres, dtype=np.float64).reshape(-1, 2)
    a = np.asarray(half_axes, dtype=np.float64).reshape(-1, 2)
    lo = (c - a).min(axis=0)
    hi = (c + a).max(axis=0)
    if not np.all(np.isfinite(lo)) or not np.all(np.isfinite(hi)):
        raise InvalidBoxError("kernel positions are not finite")
    return float(lo[0]), float(lo[1]), float(hi[0] - lo[0]), float(hi[1] - lo[1])


def max_pairwise_overlap(num_kernels: int) -> float:
    """Largest overlap between two kernel rectangles, as a fraction of the smaller one."""
    frac = layout_fractions(num_kernels)
    worst = 0.0
    for i in range(len(frac)):
        for j in range(i + 1, len(frac)):
            a, b = frac[i], frac[j]
            iw = min(a[2], b[2]) - max(a[0], b[0])
            ih = min(a[3], b[3]) - max(a[1], b[1])
            if iw <= 0 or ih <= 0:
                continue
            smaller = min((a[2] - a[0]) * (a[3] - a[1]), (b[2] - b[0]) * (b[3] - b[1]))
            worst = max(worst, iw * ih / smaller)
    return worst
