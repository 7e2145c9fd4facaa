"""How occluded the annotated people of a ground truth are, from the boxes alone (issue #16).

A ground truth says which people count: a tracker that reports a person the annotators left
out scores a false positive.  Real clips (MOTChallenge TUD-Campus, TUD-Stadtmitte) give only
boxes, so their convention is measured from the boxes: a person is taken to be hidden by
every annotated person whose box's bottom edge is lower in the image (nearer to the camera
on a ground plane), and

* :func:`box_visibility` -- the share of a box inside the image and not covered by the union
  of the nearer boxes (the box analogue of the generator's ``visible_fraction``, which counts
  silhouette pixels);
* :func:`frame_visibilities` -- that share for every box of one frame;
* :func:`identity_gaps` -- the frames in which an identity is absent between its first and
  last annotated frame, each with the box interpolated linearly across the gap: a person the
  annotators dropped while passing behind someone, whose hidden share the interpolated box
  estimates.

The union is exact (coordinate compression over the box edges), so the figures do not depend
on a raster.  No tracker output is involved.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

Box = tuple[float, float, float, float]

__all__ = ["IdentityGap", "box_visibility", "covered_area", "frame_visibilities",
           "identity_gaps"]


def _checked(box: Sequence[float], what: str) -> tuple[float, float, float, float]:
    if len(box) != 4:
        raise ValueError(f"{what} must be (x, y, w, h), got {box!r}")
    x, y, w, h = (float(v) for v in box)
    if not all(np.isfinite((x, y, w, h))) or w <= 0 or h <= 0:
        raise ValueError(f"{what} must be finite with positive width and height, got {box!r}")
    return x, y, w, h


def covered_area(box: Sequence[float], covers: Sequence[Sequence[float]]) -> float:
    """Area of ``box`` (x, y, w, h) inside the union of the ``covers`` boxes.

    Exact: the edges of the covers clipped to ``box`` cut it into cells, each inside or
    outside the union as a whole.  Covers may be degenerate (w or h <= 0: they cover
    nothing); ``box`` may not."""
    x0, y0, w, h = _checked(box, "box")
    x1, y1 = x0 + w, y0 + h
    rects = []
    for c in covers:
        cx, cy, cw, ch = (float(v) for v in c)
        a, b = max(x0, cx), max(y0, cy)
        e, f = min(x1, cx + cw), min(y1, cy + ch)
        if e > a and f > b:
            rects.append((a, b, e, f))
    if not rects:
        return 0.0
    r = np.asarray(rects)
    xs = np.unique(np.concatenate([r[:, 0], r[:, 2]]))
    ys = np.unique(np.concatenate([r[:, 1], r[:, 3]]))
    mx, my = 0.5 * (xs[:-1] + xs[1:]), 0.5 * (ys[:-1] + ys[1:])
    inside = np.zeros((len(my), len(mx)), bool)
    for a, b, e, f in rects:
        inside |= ((my[:, None] > b) & (my[:, None] < f)) & ((mx[None, :] > a) & (mx[None, :] < e))
    cell = np.outer(np.diff(ys), np.diff(xs))
    return float(cell[inside].sum())


def box_visibility(box: Sequence[float], nearer: Sequence[Sequence[float]],
                   image_size: tuple[int, int] | None = None) -> float:
    """Share of ``box``'s area that is inside the image (``image_size`` = (width, height);
    None: no image border) and not covered by the ``nearer`` boxes, in [0, 1]."""
    x, y, w, h = _checked(box, "box")
    area = w * h
    if image_size is not None:
        width, height = image_size
        ix, iy = max(x, 0.0), max(y, 0.0)
        iw, ih = min(x + w, float(width)) - ix, min(y + h, float(height)) - iy
        if iw <= 0 or ih <= 0:
            return 0.0
        free = iw * ih - covered_area((ix, iy, iw, ih), nearer)
    else:
        free = area - covered_area((x, y, w, h), nearer)
    return float(min(1.0, max(0.0, free / area)))   # rounding can leave -1e-16


def frame_visibilities(boxes: Mapping[int, Sequence[float]],
                       image_size: tuple[int, int] | None = None) -> dict[int, float]:
    """``{id: box_visibility}`` for every box of one frame, each hidden by the boxes whose
    bottom edge (y + h) is lower in the image than its own (ties hide nothing: neither is
    nearer)."""
    checked = {i: _checked(b, f"box of id {i}") for i, b in boxes.items()}
    out = {}
    for i, b in checked.items():
        bottom = b[1] + b[3]
        nearer = [c for j, c in checked.items() if j != i and c[1] + c[3] > bottom]
        out[i] = box_visibility(b, nearer, image_size)
    return out


@dataclass(frozen=True)
class IdentityGap:
    """Frame ``frame`` (0-based) in which identity ``id`` is not annotated although it is
    before and after; ``box`` is its box interpolated linearly between the annotated frames
    ``before`` and ``after`` around the gap."""

    id: int
    frame: int
    before: int
    after: int
    box: Box


def identity_gaps(ground_truth: Sequence[Mapping[int, Sequence[float]]]) -> list[IdentityGap]:
    """Every frame in which an identity is missing between two frames that annotate it
    (``ground_truth[k]`` = ``{id: box}`` of frame k), with the interpolated box, in the
    order of (id, frame)."""
    frames_of: dict[int, list[int]] = {}
    for k, frame in enumerate(ground_truth):
        for i in frame:
            frames_of.setdefault(i, []).append(k)
    gaps = []
    for i in sorted(frames_of):
        ks = frames_of[i]
        for a, b in zip(ks[:-1], ks[1:]):
            if b - a < 2:
                continue
            box_a = np.asarray(ground_truth[a][i], float)
            box_b = np.asarray(ground_truth[b][i], float)
            for k in range(a + 1, b):
                t = (k - a) / (b - a)
                box = tuple(float(v) for v in (1 - t) * box_a + t * box_b)
                gaps.append(IdentityGap(i, k, a, b, box))
    return gaps
