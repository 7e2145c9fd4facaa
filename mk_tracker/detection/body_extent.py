"""Whole-body boxes: a person reported as an upper and a lower part becomes one detection
(issues #15 and #19, "boxes cover half a body").  Not in Schizas et al. (2018).

Why parts happen.  The kernel covariance (3.5) sees only pixels that *changed* during the
window, so the support (5.1) of a person who moves the arms but stands on still legs (or
walks with a still torso in a low-contrast region) is the moving part only, and the K-means
clusters (3.12)-(3.13) of a tall near person can fall apart into a torso band and a leg
band.  Once a full-frame pass has made two objects of them, each keeps its Kalman filter
and its Voronoi cell through the tracking passes (Algorithm 2), so the person is reported
as two stacked boxes until the next full pass; on the real LWIR clip BU-TIV-lab this is
what "boxes cover half a body" is (docs/benchmark_groups.md, "Box quality").

The rule (:func:`join_stacked`), on the detections of one frame, scale-free (no learnt
size):

* two boxes are **stacked** when their column ranges overlap by at least
  ``column_overlap`` of the narrower width, their row ranges overlap by at most
  ``row_overlap`` of the shorter height (one is above the other, not one person in
  front of another, whose rows mostly coincide) and the gap between them is at most
  ``gap`` of the shorter height;
* their union is **one upright person** when its width is at most ``aspect`` times
  its height (a side-by-side pair is wider);
* stacked pairs whose union is one person are joined, the pair with the smallest gap
  first, again until none is left (a head, a torso and legs become one).

The joined detection has the union box, the pixel-weighted mean of the centroids and
scores, the summed pixel count, and the object id, filtered centroid and velocity of the
part with more pixels.  Only the reported detections change: the detector's objects (their
Kalman filters and (5.2) windows) stay as they were.  (Joining the objects themselves was
tried: the joined object's footprint then spread over the people touching it, and on
BU-TIV-lab the tracker held 2.4 tracks a frame for 4-6 visible people.)

``extent_frames`` (0 by default: it did worse on the development seeds): a part of a
joined person that is later reported alone is grown, for that many frames, to the extent
above and below it that its person had at the last join, anchored on the part's own edges.

Measured (docs/benchmark_groups.md, "Box quality"): off by default.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Callable, Sequence

from mk_tracker.detection.person_size import is_person_shaped
from mk_tracker.parameters import parameter

__all__ = ["BodyExtent", "BodyExtentConfig", "is_stacked", "join_stacked"]


@dataclass(frozen=True)
class BodyExtentConfig:
    """The constants of :func:`join_stacked` (``detector.body_extent.*``)."""

    join_stacked: bool = parameter(
        False, "join a person's stacked parts (an upper and a lower box whose union is one "
        "upright person) into one detection; not in the paper")
    column_overlap: float = parameter(
        0.5, "join_stacked: the parts' column ranges overlap by at least this fraction of "
        "the narrower width", minimum=0.0, maximum=1.0)
    row_overlap: float = parameter(
        0.3, "join_stacked: ... their row ranges by at most this fraction of the shorter "
        "height (one above the other, not one person in front of another)", minimum=0.0,
        maximum=1.0)
    gap: float = parameter(
        0.25, "join_stacked: ... and the rows between them are at most this fraction of the "
        "shorter height", minimum=0.0, maximum=10.0)
    aspect: float = parameter(
        0.6, "join_stacked: the union is one upright person when its width is at most this "
        "times its height", minimum=0.05, maximum=10.0)
    height_ratio: float = parameter(
        0.0, "join_stacked: the union is at most this many learnt person heights at its "
        "bottom row (mk_tracker.detection.person_size, learnt from the reported "
        "person-shaped boxes); no test while no height is learnt or when the union "
        "touches the image's top or bottom row; 0: no test", minimum=0.0, maximum=10.0)
    extent_frames: int = parameter(
        0, "join_stacked: for this many frames after its last join, a part reported alone "
        "is grown to the extent above and below it that its person had then (0: never)",
        minimum=0, maximum=100000)


def _union(a: Sequence[float], b: Sequence[float]) -> tuple[float, float, float, float]:
    x0, y0 = min(a[0], b[0]), min(a[1], b[1])
    x1, y1 = max(a[0] + a[2], b[0] + b[2]), max(a[1] + a[3], b[1] + b[3])
    return (x0, y0, x1 - x0, y1 - y0)


def is_stacked(a: Sequence[float], b: Sequence[float], rule: BodyExtentConfig,
               fits: Callable[[tuple], bool] | None = None) -> float | None:
    """The vertical gap (px, negative when the row ranges overlap) between boxes ``a`` and
    ``b`` ``(x, y, w, h)`` when one is stacked on the other and their union is one upright
    person under ``rule`` (and ``fits(union)``, when given); None otherwise."""
    columns = min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0])
    if columns < rule.column_overlap * min(a[2], b[2]):
        return None
    upper, lower = (a, b) if a[1] <= b[1] else (b, a)
    gap = lower[1] - (upper[1] + upper[3])
    shorter = min(a[3], b[3])
    rows = min(upper[1] + upper[3], lower[1] + lower[3]) - lower[1]
    if rows > rule.row_overlap * shorter or gap > rule.gap * shorter:
        return None
    union = _union(a, b)
    if union[2] > rule.aspect * union[3] or (fits is not None and not fits(union)):
        return None
    return float(gap)


def _joined(a: Any, b: Any) -> Any:
    """One detection from parts ``a`` and ``b`` (see the module docstring)."""
    na, nb = max(a.pixel_count, 1), max(b.pixel_count, 1)
    n = na + nb
    major = a if na >= nb else b
    centroid = ((a.centroid[0] * na + b.centroid[0] * nb) / n,
                (a.centroid[1] * na + b.centroid[1] * nb) / n)
    return dataclasses.replace(major, box=_union(a.box, b.box), centroid=centroid,
                               score=(a.score * na + b.score * nb) / n,
                               pixel_count=a.pixel_count + b.pixel_count)


def join_stacked(detections: list[Any], rule: BodyExtentConfig,
                 members: list[list[int]] | None = None,
                 fits: Callable[[tuple], bool] | None = None) -> list[Any]:
    """``detections`` (dataclasses with ``box``, ``centroid``, ``score``, ``pixel_count``)
    with every stacked pair whose union is one upright person joined, smallest gap first,
    until none is left.  The order of the others is kept; a joined detection takes the
    place of its first part.  ``members``, when given, receives for each returned
    detection the indices (into ``detections``) of its parts; ``fits`` is an extra test of
    a union box (:func:`is_stacked`)."""
    out = list(detections)
    groups = [[i] for i in range(len(out))]
    while len(out) > 1:
        best = None
        for i in range(len(out)):
            for j in range(i + 1, len(out)):
                gap = is_stacked(out[i].box, out[j].box, rule, fits)
                if gap is not None and (best is None or gap < best[0]):
                    best = (gap, i, j)
        if best is None:
            break
        _, i, j = best
        out[i] = _joined(out[i], out[j])
        groups[i] += groups.pop(j)
        del out[j]
    if members is not None:
        members[:] = groups
    return out


def _grown(box: Sequence[float], extent: Sequence[float], height: float
           ) -> tuple[float, float, float, float]:
    """``box`` grown up by ``extent[0]`` and down by ``extent[1]`` times its own height,
    clipped to rows ``0 .. height``."""
    x, y, w, h = box
    top = max(0.0, y - extent[0] * h)
    bottom = min(float(height), y + h + extent[1] * h)
    return (x, top, w, max(bottom - top, h))


class BodyExtent:
    """The detector's side (mixin of
    :class:`~mk_tracker.detection.thermal_detector.ThermalDetector`, which keeps
    ``self._extents`` and clears it on a reset).  The reported detections of a frame are
    joined by :func:`join_stacked`; each part of a joined person remembers how far the
    person reached above and below its own box (in units of its own height), and for the
    next ``extent_frames`` frames in which that object is reported alone its box is grown
    by that much, anchored on the part's own edges (a torso seen without its legs keeps
    its legs).  The detector's objects (Kalman filters, (5.2) windows) are unchanged."""

    def _whole_bodies(self, detections: list[Any]) -> list[Any]:
        c = self.config.body_extent
        if not c.join_stacked:
            return detections
        members: list[list[int]] = []
        joined = join_stacked(detections, c, members,
                              self._fits_height if c.height_ratio > 0 else None)
        memory = self._extents
        seen = set()
        out = []
        for d, parts in zip(joined, members):
            if len(parts) > 1:
                x0, y0, w0, h0 = d.box
                for k in parts:
                    x, y, w, h = detections[k].box
                    oid = detections[k].object_id
                    if h > 0:
                        memory[oid] = [(y - y0) / h, (y0 + h0 - y - h) / h, c.extent_frames]
                        seen.add(oid)
            elif d.object_id in memory and memory[d.object_id][2] > 0:
                extent = memory[d.object_id]
                d = dataclasses.replace(d, box=_grown(d.box, extent, self._shape[0]))
                extent[2] -= 1
                seen.add(d.object_id)
            out.append(d)
        for oid in [k for k, v in memory.items() if k not in seen or v[2] <= 0]:
            del memory[oid]
        d = self.config
        if c.height_ratio > 0 and not (d.split_by_person_size or (
                d.split_clusters and d.current_frame_refinement)):   # else learnt there
            for det in out:
                x, y, w, h = det.box
                if self._whole_height(y, h) and is_person_shaped(w, h, d.person_aspect):
                    self.heights.add(y + h, h)
        return out

    def _fits_height(self, box: tuple) -> bool:
        """``height_ratio``: whether a union ``box`` is at most that many learnt person
        heights at its bottom row (True while no height is known there)."""
        x, y, w, h = box
        if not self._whole_height(y, h):
            return True
        expected = self.heights.height_at(y + h)
        return expected is None or h <= self.config.body_extent.height_ratio * expected
