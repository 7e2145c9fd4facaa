"""One object per person in a full-frame pass where people touch (``split_clusters``, issue
#15): the K-means clusters of (3.12)-(3.13) grouped into people by the learnt person size,
instead of the link rule and the footprint merge.

Schizas et al. (2018), Sec. 3.3 split the support into objects by K-means from ``Z = M_up``
clusters, merging while two centroids are closer than ``epsilon_d`` (3.13).  With people
who touch, that rule alone keeps them apart, but the support of one *moving* person is the
area it swept during the window: two bands, where it arrived (its leading edge) and where
it left (its trailing edge), and a band taller than ``sqrt(epsilon_d)`` is itself cut into
several clusters.  The link rule (``link_gap``) and the footprint merge join all of those,
and every person who touches with them (docs/benchmark_groups.md).  Here, within one
*blob* (clusters whose newest-frame footprints share pixels):

1. **Trailing bands are not people.**  A cluster of which fewer than ``trail_fraction`` of
   the support pixels lie in its own newest-frame footprint is where an object *was*: it
   gives no object (its person is found from the leading band).  A blob whose clusters are
   all trailing is one object, as before.
2. **Pieces of one band are one person.**  Leading clusters are joined, closest pairs of
   support boxes first, while the union of their support boxes is no wider than
   ``seed_width_ratio`` and no taller than ``seed_height_ratio`` expected person widths and
   heights (:class:`~mk_tracker.detection.person_size.PersonHeightModel`) at the lowest
   row of the blob's footprint search patches, which lies below its lowest feet (a piece
   ends above its person's feet), plus, with ``motion_slack``, the distance the fastest
   known object inside moved during the window; with ``cut_blobs_whole`` a blob whose
   patches reach the image's bottom row has no size.
   Pieces of one person's band are as tall as the person at most; two people side by side
   are a person width apart, two one above the other are taller than one.  Without a
   learnt size the blob is one object (today's rule).  A blob of one person is the union
   of its clusters' footprints (a footprint searched again from their joined support would
   be found against another local background, and can reach a neighbour).
3. **Cells and slivers.**  The footprint of a blob of several people is shared among the
   joined groups by Voronoi cells of their support centroids (as the tracking passes share
   it among Kalman predictions, (5.2)); a cell narrower than ``sliver_fraction`` expected
   widths, or lower than ``sliver_height_fraction`` expected heights, is a sliver: its group
   is joined to the group it stacks with best (narrowest union) and the cells are drawn
   again.  Then, over all the pass's candidates, a sliver, or a candidate with more than
   ``sliver_overlap`` of its box inside another's, is joined to the candidate with which
   its box still fits one person (narrowest union first): a leg, a head, the two thin
   edge bands of one person whose body was not found.
4. **Previous objects** (Algorithm 2 keeps a Kalman filter per object): at a
   reconfiguration, two groups are never joined in step 2 when each holds the prediction
   of a different object of the last pass inside its support box grown by
   ``window_margin`` (``keep_objects_apart``): two people who walked apart stay two while
   they pass each other.  Only with a learnt size: without one the blob is one object.

With a size check (``size_max_residual`` below 100, not in the paper), the pass uses
these rules only while the learnt height fit explains its samples
(:meth:`~mk_tracker.detection.person_size.PersonHeightModel.valid`); otherwise it runs the
link rule and the footprint merge, as without ``split_clusters``.

The rules of steps 1-3 are pure functions (:func:`leading_clusters`, :func:`join_pieces`,
:func:`is_sliver`); :class:`CrowdSplitting` (a mixin of
:class:`~mk_tracker.detection.thermal_detector.ThermalDetector`) applies them.  None of this is
in the paper; it is off by default (docs/benchmark_groups.md has the figures).
"""

from __future__ import annotations

from typing import Any, Callable, Sequence

import numpy as np

from mk_tracker.detection.block_support import SupportResult
from mk_tracker.detection.footprint import _VoronoiCell, overlapping_footprints
from mk_tracker.detection.footprint_split import _Candidate, _footprint_levels
from mk_tracker.detection.pixel_clustering import describe_pixels

__all__ = ["CrowdSplitting", "leading_clusters", "join_pieces", "is_sliver", "union_box"]

Box = tuple[float, float, float, float]          # x0, y0, x1, y1 (exclusive ends)


def union_box(a: Box, b: Box) -> Box:
    """Smallest ``(x0, y0, x1, y1)`` box holding both."""
    return (min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3]))


def _corners(box: tuple[float, float, float, float]) -> Box:
    """``(x, y, w, h)`` as ``(x0, y0, x1, y1)``."""
    return (box[0], box[1], box[0] + box[2], box[1] + box[3])


def _inside_fraction(a: tuple[float, float, float, float],
                     b: tuple[float, float, float, float]) -> float:
    """Fraction of box ``a`` ``(x, y, w, h)`` that lies inside box ``b``."""
    w = min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0])
    h = min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1])
    return max(w, 0.0) * max(h, 0.0) / (a[2] * a[3]) if a[2] * a[3] > 0 else 1.0


def _gap(a: Box, b: Box) -> float:
    """Chebyshev gap between two boxes (0 when they touch or overlap)."""
    return max(a[0] - b[2], b[0] - a[2], a[1] - b[3], b[1] - a[3], 0.0)


def leading_clusters(now_fractions: Sequence[float], trail_fraction: float) -> list[int]:
    """Indices of the clusters that hold an object now: at least ``trail_fraction`` of
    their support pixels in their newest-frame footprint.  When none does (an object that
    moved onto colder ground, or a blob of trailing bands only), all of them."""
    lead = [k for k, f in enumerate(now_fractions) if f >= trail_fraction]
    return lead if lead else list(range(len(now_fractions)))


def join_pieces(boxes: Sequence[Box],
                expected: Callable[[float], tuple[float, float] | None],
                width_ratio: float, height_ratio: float,
                apart: Callable[[int, int], bool] | None = None,
                slack: float = 0.0) -> list[list[int]]:
    """Groups of support boxes ``(x0, y0, x1, y1)`` that are one person's pieces.

    Pairs are tried by increasing gap between their groups' boxes; two groups are joined
    when the union box is at most ``width_ratio`` expected widths wide and ``height_ratio``
    expected heights tall, ``expected(y_bottom)`` giving ``(width, height)`` of a person
    whose feet are at row ``y_bottom`` (``None``: unknown, so everything is one group),
    and ``apart(i, j)`` (boxes ``i`` and ``j`` hold two known objects) does not forbid it.
    ``slack`` (px) is added to both limits (the distance a person moved during the window:
    its support is that much wider or taller than the person).
    Returns the groups (lists of box indices, increasing), ordered by their first index.
    """
    n = len(boxes)
    groups: dict[int, list[int]] = {k: [k] for k in range(n)}
    gbox = {k: tuple(boxes[k]) for k in range(n)}
    while len(groups) > 1:
        best = None
        keys = sorted(groups)
        for ai, a in enumerate(keys):
            for b in keys[ai + 1:]:
                u = union_box(gbox[a], gbox[b])
                size = expected(u[3])
                if size is not None:
                    w, h = size
                    if (u[2] - u[0] > width_ratio * w + slack
                            or u[3] - u[1] > height_ratio * h + slack):
                        continue
                if apart is not None and any(apart(i, j) for i in groups[a]
                                             for j in groups[b]):
                    continue
                gap = _gap(gbox[a], gbox[b])
                if best is None or gap < best[0]:
                    best = (gap, a, b, u)
        if best is None:
            break
        _, a, b, u = best
        groups[a] = sorted(groups[a] + groups.pop(b))
        gbox[a] = u
        del gbox[b]
    return [groups[k] for k in sorted(groups)]


def is_sliver(box_w: float, box_h: float, width: float, height: float,
              fraction: float, height_fraction: float | None = None) -> bool:
    """Whether a part ``box_w x box_h`` is too narrow or too low to be a person of
    ``width x height``: narrower than ``fraction`` of the width or lower than
    ``height_fraction`` (default: ``fraction``) of the height."""
    hf = fraction if height_fraction is None else height_fraction
    return box_w < fraction * width or box_h < hf * height


class CrowdSplitting:
    """``split_clusters`` in full-frame passes (mixin of the thermal detector)."""

    def _add_aspect(self, width: float, height: float) -> None:
        """One person-size sample's width / height, forgotten as the height model forgets
        (``learn_aspect``)."""
        self.aspects *= self.heights.decay
        self.aspects += (1.0, width / height)

    def _aspect(self) -> float:
        """Width / height of one person: the samples' mean with ``learn_aspect`` (once
        there are about 3), else ``person_aspect``."""
        if self.config.learn_aspect and self.aspects[0] >= 2.5:
            return float(self.aspects[1] / self.aspects[0])
        return self.config.person_aspect

    def _expected_size(self, y_bottom: float) -> tuple[float, float] | None:
        """``(width, height)`` of a person whose feet are at row ``y_bottom``, from the
        learnt height model and :meth:`_aspect`; None before it has samples."""
        h = self.heights.height_at(y_bottom)
        if h is None or not h > 0:
            return None
        return self._aspect() * h, h

    def _crowd_candidates(self, frame: np.ndarray, result: SupportResult, rows: np.ndarray,
                          cols: np.ndarray, groups: list[np.ndarray],
                          bounds: tuple[int, int, int, int]) -> list[Any]:
        """Candidates of a full-frame pass from the K-means clusters ``groups`` (indices
        into ``rows``/``cols``), steps 1-4 of the module docstring."""
        c = self.config
        prints, sets = overlapping_footprints(
            frame.shape, len(groups),
            lambda k: self._footprint(frame, result.support, rows[groups[k]],
                                      cols[groups[k]], bounds))
        now = []
        for k, fp in enumerate(prints):
            if fp is None:
                now.append(0.0)
                continue
            (y0, x0), mask = fp
            g = groups[k]
            now.append(float(mask[rows[g] - y0, cols[g] - x0].mean()))
        # no footprint: a trail, no object (as before); such a cluster is a set of its own
        blobs = [members for members in sets if prints[members[0]] is not None]
        predictions = self._predictions()
        out: list[Any] = []
        for members in blobs:
            if len(members) == 1:
                k = members[0]
                cand = self._candidate(frame, result, rows[groups[k]], cols[groups[k]],
                                       bounds, footprint=prints[k])
                if cand is not None:
                    out.append(cand)
                continue
            lead = [members[i] for i in leading_clusters([now[k] for k in members],
                                                         c.trail_fraction)]
            boxes = [(float(cols[groups[k]].min()), float(rows[groups[k]].min()),
                      float(cols[groups[k]].max() + 1), float(rows[groups[k]].max() + 1))
                     for k in lead]
            # a piece of a band ends above its person's feet: sizes are taken at the lowest
            # row of the blob's footprint search patches (support box grown by
            # window_margin plus half its larger side, clipped to the image), below the
            # lowest feet; the blob's lowest footprint row gave more splits on BU-TIV-lab
            # (4.79 instead of 4.28 detections per frame, docs/benchmark_groups.md)
            bottom = max(prints[k][0][0] + prints[k][1].shape[0] for k in members)
            # cut_blobs_whole: a blob whose patches reach the image's bottom row may hide
            # its feet: no size, one object
            size = (self._expected_size(bottom) if bottom <= self._shape[0] - 1
                    or not c.cut_blobs_whole else None)
            # without a size the blob is one object (today's rule): nothing is kept apart
            apart = (self._apart(boxes, predictions)
                     if c.keep_objects_apart and size is not None else None)
            slack = self._motion_slack(boxes, predictions) if c.motion_slack else 0.0
            parts = join_pieces(boxes, lambda _: size, c.seed_width_ratio,
                                c.seed_height_ratio, apart, slack)
            people = [np.concatenate([groups[lead[i]] for i in p]) for p in parts]
            if len(people) == 1:
                # one person (or no size known yet): the union of its clusters' footprints
                # (a footprint searched again from the union of their support would be
                # found against another local background, and can reach a neighbour)
                cand = self._union_candidate(frame, result, rows, cols, groups, members,
                                             prints)
                if cand is not None:
                    out.append(cand)
                continue
            out.extend(self._cells(frame, result, rows, cols, people, bounds, size))
        return self._without_slivers(out)

    def _union_candidate(self, frame: np.ndarray, result: SupportResult, rows: np.ndarray,
                         cols: np.ndarray, groups: list[np.ndarray], members: list[int],
                         prints: list[Any]) -> Any:
        """One candidate from the footprints ``prints`` of clusters ``members``."""
        y0 = min(prints[k][0][0] for k in members)
        x0 = min(prints[k][0][1] for k in members)
        y1 = max(prints[k][0][0] + prints[k][1].shape[0] for k in members)
        x1 = max(prints[k][0][1] + prints[k][1].shape[1] for k in members)
        mask = np.zeros((y1 - y0, x1 - x0), dtype=bool)
        for k in members:
            (py, px), m = prints[k]
            mask[py - y0:py - y0 + m.shape[0], px - x0:px - x0 + m.shape[1]] |= m
        fr, fc = np.nonzero(mask)
        if fr.size < self.config.min_object_pixels:
            return None
        every = np.concatenate([groups[k] for k in members])
        score = float(min(1.0, result.variance[rows[every], cols[every]].mean() / 0.5))
        now = describe_pixels(fc + x0, fr + y0)
        return _Candidate(now.centroid, now.box, score, now.pixel_count,
                          *_footprint_levels(frame, result.support, ((y0, x0), mask)))

    def _without_slivers(self, cands: list[Any]) -> list[Any]:
        """Slivers joined to a neighbour: a candidate narrower or lower than
        ``sliver_fraction`` of the expected person, whose box joined with another
        candidate's still fits one person (``seed_width_ratio`` x ``seed_height_ratio``),
        is one object with it (a leg, the two thin edge bands of one person whose body
        was not found, a band's end); the narrowest such union first.  The expected size
        is taken at the union's bottom row."""
        c = self.config
        cands = list(cands)
        while len(cands) > 1:
            best = None
            for i, a in enumerate(cands):
                for j, b in enumerate(cands):
                    if j == i:
                        continue
                    u = union_box(_corners(a.box), _corners(b.box))
                    size = self._expected_size(u[3])
                    if size is None:
                        continue
                    if not (is_sliver(a.box[2], a.box[3], size[0], size[1],
                                      c.sliver_fraction, c.sliver_height_fraction)
                            or _inside_fraction(a.box, b.box) > c.sliver_overlap):
                        continue
                    uw, uh = u[2] - u[0], u[3] - u[1]
                    if uw > c.seed_width_ratio * size[0] or uh > c.seed_height_ratio * size[1]:
                        continue
                    if best is None or (uw, uw * uh) < best[0]:
                        best = ((uw, uw * uh), i, j, u)
            if best is None:
                break
            _, i, j, u = best
            a, b = cands[i], cands[j]
            n = a.pixel_count + b.pixel_count
            centroid = ((a.centroid[0] * a.pixel_count + b.centroid[0] * b.pixel_count) / n,
                        (a.centroid[1] * a.pixel_count + b.centroid[1] * b.pixel_count) / n)
            big = a if a.pixel_count >= b.pixel_count else b
            merged = _Candidate(centroid, (u[0], u[1], u[2] - u[0], u[3] - u[1]),
                                max(a.score, b.score), n, big.level, big.local)
            cands = [x for k, x in enumerate(cands) if k not in (i, j)] + [merged]
        return cands

    def _cells(self, frame: np.ndarray, result: SupportResult, rows: np.ndarray,
               cols: np.ndarray, people: list[np.ndarray],
               bounds: tuple[int, int, int, int], size: tuple[float, float] | None
               ) -> list[Any]:
        """One candidate per group of ``people`` (indices into ``rows``/``cols``), its
        footprint restricted to the Voronoi cell of its support centroid; a sliver (against
        the expected person ``size``, ``(width, height)``; None: unknown, no slivers) has
        its group joined to the group it stacks with best and the cells are drawn again."""
        c = self.config
        while True:
            centres = np.array([(cols[p].mean() + 0.5, rows[p].mean() + 0.5) for p in people])
            cands = [self._candidate(frame, result, rows[p], cols[p], bounds,
                                     cell=_VoronoiCell(centres, k))
                     for k, p in enumerate(people)]
            if len(people) == 1 or size is None:       # no size: no slivers either
                return [x for x in cands if x is not None]
            worst = None
            for k, cand in enumerate(cands):
                if cand is None:
                    continue
                w, h = cand.box[2:]
                if is_sliver(w, h, size[0], size[1], c.sliver_fraction,
                                            c.sliver_height_fraction):
                    if worst is None or w * h < worst[0]:
                        worst = (w * h, k)
            if worst is None:
                return [x for x in cands if x is not None]
            k = worst[1]
            # joined to the part it stacks with best (the narrowest union of support
            # boxes: people are upright), nearest centroid among equals
            d = np.hypot(*(centres - centres[k]).T)
            lo, hi = cols[people[k]].min(), cols[people[k]].max()
            widths = np.array([max(hi, cols[p].max()) - min(lo, cols[p].min()) for p in people],
                              dtype=np.float64)
            widths[k] = np.inf
            j = int(np.lexsort((d, widths))[0])
            people[j] = np.concatenate([people[j], people[k]])
            del people[k]

    def _predictions(self) -> np.ndarray:
        """``(x, y, vx, vy)`` predicted, at the newest stamp, for each object of the last
        pass (Kalman state (4.2))."""
        stamp = self._last_stamp
        pts = []
        for tr in self._tracks:
            dt = stamp - tr.stamp
            pts.append(tr.kf.predicted(dt)[0][:4] if dt > 0 else tr.kf.state[:4])
        return np.array(pts, dtype=np.float64).reshape(-1, 4)

    def _motion_slack(self, boxes: list[Box], predictions: np.ndarray) -> float:
        """``motion_slack``: the distance the fastest known object inside the pieces' union
        box moved during the full pass's window (its speed times the window's time span),
        px; 0 without one."""
        if predictions.shape[0] == 0:
            return 0.0
        x0 = min(b[0] for b in boxes)
        y0 = min(b[1] for b in boxes)
        x1 = max(b[2] for b in boxes)
        y1 = max(b[3] for b in boxes)
        inside = ((predictions[:, 0] >= x0) & (predictions[:, 0] <= x1)
                  & (predictions[:, 1] >= y0) & (predictions[:, 1] <= y1))
        if not inside.any():
            return 0.0
        span = self._window.span(self._count(self.config.startup_frames, 2))
        return float(np.hypot(predictions[inside, 2], predictions[inside, 3]).max() * span)

    def _apart(self, boxes: list[Box], predictions: np.ndarray
               ) -> Callable[[int, int], bool] | None:
        """Step 4: ``apart(i, j)``, true when boxes ``i`` and ``j`` (grown by
        ``window_margin``) each hold a prediction the other does not (two known objects)."""
        if predictions.shape[0] < 2:
            return None
        m = self.config.window_margin
        inside = [frozenset(np.flatnonzero(
            (predictions[:, 0] >= b[0] - m) & (predictions[:, 0] <= b[2] + m)
            & (predictions[:, 1] >= b[1] - m) & (predictions[:, 1] <= b[3] + m)).tolist())
            for b in boxes]

        def apart(i: int, j: int) -> bool:
            return bool(inside[i] - inside[j]) and bool(inside[j] - inside[i])
        return apart
