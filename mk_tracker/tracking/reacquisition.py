"""Re-acquisition of lost tracks from their last detection (issues #15 / #19).

A track that went unseen keeps its Kalman filter running: the constant-velocity prediction
(4.2) of Schizas et al. 2018 carries the last velocity on, and its covariance (4.3) grows as
``q t^3``.  When a person stops, turns or walks back while unseen (or is simply not
detected because the kernel covariance detector finds only what moves), the prediction ends
up far from where the person is found again while the covariance has not grown enough to
cover it: on BU-TIV-lab most re-appearing people were refused by the Kalman gate although
their new detection was within 0.2-0.35 box heights of the old track's last detection
(docs/benchmark_real_thermal.md, "Why new ids are born").

OC-SORT (Cao et al. 2023) names the remedy "observation-centric": trust the last
*observation*, not the drifted estimate.  Here the observation gets its own gate, with a
motion model that makes no claim about the direction: the person is somewhere around the
last detected centre ``c`` with an isotropic spread that grows with the time ``dt`` since
that detection at most at a walking speed ``v`` (box heights per second), on top of a floor
``s0`` (box heights) for the detection's own error:

    d2 = |z - c|^2 / (h^2 (s0^2 + (v dt)^2))

with ``h`` the height of the last detected box.  ``d2`` is compared with the same chi-square
gate as the Kalman distance; a pair passes when either distance is inside it, and the
smaller of the two enters the re-acquisition cost.  Like ByteTrack's ``track_buffer``, the
growing spread lets a lost track be kept longer without claiming far detections early.
"""

from __future__ import annotations

import copy
import math
from typing import Any, Callable, Sequence

import numpy as np

from mk_tracker.boxes import box_center
from mk_tracker.tracking.association import assign

__all__ = ["distinct_best", "last_detection_distance2", "nearer_of_both", "nearest_others",
           "reacquire_check",
           "reacquisition_matches", "reference_similarity"]


def last_detection_distance2(points: np.ndarray, centre: np.ndarray, height: float,
                             elapsed: float, floor: float, speed: float) -> np.ndarray:
    """Squared normalised distances ``(D,)`` of ``points (D, 2)`` from the last detected
    ``centre`` of a box of ``height`` px, ``elapsed`` s after that detection (module
    docstring): ``|z - c|^2 / (height^2 (floor^2 + (speed elapsed)^2))``.

    ``floor`` and ``speed`` are in box heights and box heights per second.  Returns ``inf``
    everywhere when the spread is zero (``floor`` and ``speed`` 0: the gate is off) or the
    height is not positive; a negative ``elapsed`` counts as 0.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    c = np.asarray(centre, dtype=np.float64).reshape(2)
    spread2 = float(height) ** 2 * (floor ** 2 + (speed * max(float(elapsed), 0.0)) ** 2)
    if not (float(height) > 0.0 and spread2 > 0.0 and np.isfinite(spread2)):
        return np.full(p.shape[0], np.inf)
    return np.sum((p - c) ** 2, axis=1) / spread2


def nearer_of_both(kalman_d2: np.ndarray, points: np.ndarray, detected_boxes: np.ndarray,
                   elapsed: np.ndarray, floor: float, speed: float) -> np.ndarray:
    """Per lost track and detection ``(T, D)``, the smaller of the Kalman distance
    ``kalman_d2`` and :func:`last_detection_distance2` from each track's last detected box.

    ``points`` are the detection centres, ``(D, 2)`` or ``(T, D, 2)`` (per track, moved to
    the frame time with its velocity); ``detected_boxes (T, 4)`` ``(x, y, w, h)``;
    ``elapsed (T,)`` seconds since each track's last detection.  ``floor`` and ``speed``
    both 0: a copy of ``kalman_d2`` (the gate is off).
    """
    out = np.array(kalman_d2, dtype=np.float64, copy=True)
    if floor <= 0.0 and speed <= 0.0:
        return out
    p = np.asarray(points, dtype=np.float64)
    if p.ndim == 2:
        p = np.broadcast_to(p, (out.shape[0],) + p.shape)
    boxes = np.asarray(detected_boxes, dtype=np.float64).reshape(-1, 4)
    for i, b in enumerate(boxes):
        d2 = last_detection_distance2(p[i], b[:2] + b[2:] / 2.0, float(b[3]),
                                      float(elapsed[i]), floor, speed)
        out[i] = np.minimum(out[i], d2)
    return out


def reacquire_check(track: Any, box: np.ndarray, d2: float, image: np.ndarray, config: Any,
                    refiner: Any) -> tuple[str | None, float, int | None]:
    """The checks of one lost ``track`` against one detection ``box`` ``(x, y, w, h)``, in
    order: ``"gate"`` (``d2``, the squared gated distance, above ``config.reacquire_gate``),
    ``"size"`` (height ratio beyond ``reacquire_max_size_ratio``), ``"appearance"`` (best
    similarity of the track's frozen references, by ``refiner.appearance_similarity``,
    below ``reacquire_similarity``).  Returns ``(first failed check or None, appearance
    similarity, index of the best reference or None)``; the similarity is 1 without a
    refiner or references, NaN when not reached."""
    if d2 > config.reacquire_gate:
        return "gate", math.nan, None
    ratio = box[3] / max(track.size[1], 1e-9)
    ratio_max = config.reacquire_max_size_ratio
    if not (1.0 / ratio_max <= ratio <= ratio_max):
        return "size", math.nan, None
    sim, k = reference_similarity(track, box, image, refiner)
    if not math.isfinite(sim) or sim < config.reacquire_similarity:
        return "appearance", sim, None
    return None, sim, k


def reference_similarity(track: Any, box: Sequence[float], image: np.ndarray,
                         refiner: Any) -> tuple[float, int | None]:
    """Best appearance similarity of ``track``'s frozen reference models at ``box``
    (``refiner.appearance_similarity``) and the index of that reference: ``(1, None)``
    without a refiner or references, ``(nan, None)`` when the refiner refuses the box."""
    if refiner is None or not track.references:
        return 1.0, None
    try:
        sims = [float(refiner.appearance_similarity(image, ref, tuple(box)))
                for ref in track.references]
    except ValueError:
        return math.nan, None
    return max(sims), int(np.argmax(sims))


def distinct_best(sims: np.ndarray, margin: float) -> np.ndarray:
    """Per pair ``(T, D)``: does ``sims[i, j]`` beat every other finite entry of its row
    (track ``i``'s similarity at the other detections it could take) and of its column (the
    other tracks' similarities at detection ``j``) by at least ``margin``?  NaN entries (not
    a candidate: outside the gate or of another size) never compete and are never distinct.

    This is the ratio test of feature matching (Lowe, IJCV 2004, Sec. 7.1: a match is
    kept only when the nearest neighbour is clearly nearer than the second nearest) as a
    difference of similarities, applied both ways: an appearance that several candidates
    share identifies none of them, so among look-alike people a lost id is not given back
    by appearance (issue #16's unseen B, ``benchmarks/bench_small_far.py --alike``)."""
    s = np.asarray(sims, dtype=np.float64)
    out = np.zeros(s.shape, dtype=bool)
    filled = np.where(np.isfinite(s), s, -np.inf)
    for i, j in zip(*np.nonzero(np.isfinite(s))):
        row = np.delete(filled[i], j)
        col = np.delete(filled[:, j], i)
        rival = max(row.max(initial=-np.inf), col.max(initial=-np.inf))
        out[i, j] = s[i, j] - rival >= margin
    return out


def nearest_others(box: np.ndarray, boxes: np.ndarray, count: int) -> np.ndarray:
    """The ``count`` boxes of ``boxes (N, 4)`` whose centres are nearest to ``box``'s,
    ``box`` itself (an identical row) left out."""
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    b = b[~np.all(np.isclose(b, box), axis=1)]
    if count <= 0 or not len(b):
        return b[:0]
    d = np.sum((b[:, :2] + b[:, 2:] / 2.0 - box_center(box)) ** 2, axis=1)
    return b[np.argsort(d, kind="stable")[:count]]


def reacquisition_matches(lost: Sequence[Any], dets: Sequence[Any], maha: np.ndarray,
                          gated: np.ndarray, image: np.ndarray, config: Any,
                          check: Callable[..., tuple[str | None, float, int | None]],
                          rival_similarity: Callable[[Any, np.ndarray], float] | None = None,
                          frame_boxes: np.ndarray | None = None
                          ) -> tuple[list[tuple[int, int]], set[int]]:
    """Matches ``(lost index, det index)`` of lost tracks and detections, and the detections
    inside some lost track's Kalman gate.

    ``maha (T, D)`` are the Kalman distances, ``gated`` the distances that gate (the nearer
    of both, :func:`nearer_of_both`); ``check(track, det, d2, image)`` is
    :func:`reacquire_check` for one pair.  The cost of a pair that passes is
    ``(1 - similarity) + reacquire_distance_weight * d2 / reacquire_gate``, assigned
    one-to-one; with ``reacquire_margin`` >= 0 only pairs that are a distinct best match
    both ways (:func:`distinct_best`, over the pairs inside the gate at a plausible size)
    may be assigned; with ``reacquire_rivals`` > 0 the rivals of a pair also include the
    track's similarity (``rival_similarity(track, box)``) at the boxes of that many other
    people of this frame nearest to the detection (``frame_boxes``, every detection of the
    frame): a model that scores the people around as high as the candidate does not tell
    them apart, whether or not they are candidates themselves.  A matched track restarts
    its working target from the frozen reference that matched: its models were blended
    while the person disappeared.  A detection counts as
    contested when it is inside a track's *Kalman* gate at a plausible size (whatever its
    appearance)."""
    cost = np.full(np.shape(maha), np.inf)
    sims = np.full(np.shape(maha), np.nan)
    contested: set[int] = set()
    best_reference: dict[tuple[int, int], int] = {}
    for i, t in enumerate(lost):
        for j, d in enumerate(dets):
            refused, sim, k = check(t, d, float(gated[i, j]), image)
            if refused in (None, "appearance") and maha[i, j] <= config.reacquire_gate:
                contested.add(j)
            if refused in (None, "appearance"):
                sims[i, j] = sim
            if refused is not None:
                continue
            if k is not None:
                best_reference[(i, j)] = k
            cost[i, j] = (1.0 - sim) + config.reacquire_distance_weight * \
                gated[i, j] / config.reacquire_gate
    margin = config.reacquire_margin
    if margin >= 0.0:
        rivals = int(config.reacquire_rivals)
        outside = np.full(np.shape(maha), -np.inf)
        if rivals > 0 and rival_similarity is not None and frame_boxes is not None:
            for i, j in zip(*np.nonzero(np.isfinite(cost))):
                near = nearest_others(np.asarray(dets[j].box, dtype=np.float64),
                                      frame_boxes, rivals)
                scores = [rival_similarity(lost[i], b) for b in near]
                outside[i, j] = max((v for v in scores if math.isfinite(v)), default=-np.inf)
        keep = distinct_best(sims, margin) & (sims - outside >= margin)
        cost[~keep] = np.inf
    matches = assign(cost, math.inf).matches
    for i, j in matches:
        k = best_reference.get((i, j))
        if k is not None:
            lost[i].target = copy.deepcopy(lost[i].references[k])
    return matches, contested
