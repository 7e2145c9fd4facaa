"""What the multi-object tracker reports for one frame (:class:`FrameResult`): every live
track's output, the multiple-kernel targets for drawing, and which tracks a consumer
should draw or score (:meth:`FrameResult.reported`: confirmed ones, coasting ones while
their position is still certain enough, never the hidden twin of a stacked pair), and the
estimate behind the one-level coasting rule (:func:`coast_expected_iou`).

Split from :mod:`mk_tracker.tracking.multi_object_tracker`, which produces it and still
re-exports these names.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mk_tracker.tracking.track import TrackOutput, TrackState

__all__ = ["FrameResult", "TrackKernels", "axis_overlap", "coast_expected_iou",
           "coast_position_std", "track_kernels"]


@dataclass(frozen=True)
class TrackKernels:
    """The multiple-kernel target of one track after this frame (Chu et al. 2013, Sec. III:
    kernel centres and half-axes, (2)-(3); ``similarity`` is the target's mean kernel
    similarity, (5)), in RGB pixels, for drawing."""

    track_id: int
    centres: tuple[tuple[float, float], ...]
    half_axes: tuple[tuple[float, float], ...]
    similarity: float


def track_kernels(track: Any) -> TrackKernels | None:
    """:class:`TrackKernels` of a track whose target has ``centres`` and ``half_axes``
    (N x 2 each), else None (no refiner, no model yet, or a refiner without kernels)."""
    target = track.target
    if target is None:
        return None
    try:
        centres = np.asarray(target.centres, dtype=float).reshape(-1, 2)
        axes = np.asarray(target.half_axes, dtype=float).reshape(-1, 2)
        similarity = float(getattr(target, "similarity", math.nan))
    except (AttributeError, TypeError, ValueError):
        return None
    if centres.shape != axes.shape:
        return None
    return TrackKernels(track.id, tuple((float(x), float(y)) for x, y in centres),
                        tuple((float(a), float(b)) for a, b in axes), similarity)


@dataclass
class FrameResult:
    """Output of one :meth:`MultiObjectTracker.step`.

    ``tracks`` holds every live track (including ``lost`` ones, without a meaningful box);
    :meth:`reported` only those a consumer should draw or score.  ``kernels`` maps a track
    id to its multiple-kernel target (:class:`TrackKernels`) for the tracks that have one.
    Counters are for this frame; :attr:`MultiObjectTracker.totals` accumulates them.
    """

    stamp: float
    tracks: list[TrackOutput] = field(default_factory=list)
    kernels: dict[int, TrackKernels] = field(default_factory=dict)
    deleted_ids: list[int] = field(default_factory=list)
    dropped_stale: int = 0
    skipped_bad_detections: int = 0
    resets: int = 0
    events: list[str] = field(default_factory=list)

    max_reported_coast_time: float = float("inf")
    max_reported_coast_std: float = 0.0
    min_reported_coast_match_iou: float = 0.0
    min_reported_coast_expected_iou: float = 0.0
    #: live tracks stacked on another one of the same person, not reported
    suppressed_ids: set[int] = field(default_factory=set)

    def reported(self) -> list[TrackOutput]:
        """Tracks to draw or score: confirmed ones, and occluded (coasting) ones for at most
        ``max_reported_coast_time`` seconds since their last detection and while their
        position is certain to ``max_reported_coast_std`` of the box
        (:func:`coast_position_std`; 0 = no such bound) and while their prediction met
        their last detection at an IoU of at least ``min_reported_coast_match_iou``
        (``TrackOutput.last_match_iou``; 0 = no such bound) and while the expected IoU of
        their box with the person (:func:`coast_expected_iou`) is at least
        ``min_reported_coast_expected_iou`` (0 = no such bound); always for tracks started
        by hand, which have no detector; never those in ``suppressed_ids``."""
        return [t for t in self.tracks if t.id not in self.suppressed_ids and (
                t.state == TrackState.CONFIRMED.value
                or (t.state == TrackState.OCCLUDED.value
                    and (t.manual or self._report_coasting(t))))]

    def _report_coasting(self, t: TrackOutput) -> bool:
        """The bounds of :meth:`reported` on a coasting track not started by hand."""
        if t.time_since_detection > self.max_reported_coast_time:
            return False
        if self.max_reported_coast_std > 0.0 and \
                not coast_position_std(t) <= self.max_reported_coast_std:
            return False
        if self.min_reported_coast_expected_iou > 0.0 and \
                not coast_expected_iou(t) >= self.min_reported_coast_expected_iou:
            return False
        # NaN match IoU (never produced by the tracker) fails the bound like a low one
        return self.min_reported_coast_match_iou <= 0.0 or \
            t.last_match_iou >= self.min_reported_coast_match_iou


def coast_position_std(output: TrackOutput) -> float:
    """The centre's uncertainty relative to the box: ``max(sqrt(P_xx) / w, sqrt(P_yy) / h)``
    from the position block of the Kalman covariance P(t|t-1) (4.3).

    The IoU of a box with a copy of itself shifted by ``(dx, dy)`` depends only on
    ``dx / w`` and ``dy / h`` (a horizontal shift of w/3 alone brings it to 0.5), so the
    std in these units says how likely a coasting box still overlaps the person enough to
    count, whatever the person's size and the frame rate.  ``inf`` for an empty box."""
    pxx, _, _, pyy = output.position_covariance
    w, h = float(output.box[2]), float(output.box[3])
    if not (w > 0.0 and h > 0.0):
        return math.inf
    return max(math.sqrt(max(pxx, 0.0)) / w, math.sqrt(max(pyy, 0.0)) / h)


_SQRT_2_OVER_PI = math.sqrt(2.0 / math.pi)


def axis_overlap(s: float) -> float:
    """Expected overlap, along one axis, of a box with a copy of itself shifted by a
    zero-mean Gaussian offset whose std is ``s`` times the box side.

    The overlap fraction of a side shifted by ``|z| s`` sides is ``max(0, 1 - |z| s)``
    with ``z ~ N(0, 1)``, so its expectation is

        E = P(|z| < 1/s) - s E[|z|; |z| < 1/s]
          = erf(1 / (s sqrt 2)) - s sqrt(2/pi) (1 - exp(-1 / (2 s^2))).

    1 at ``s = 0``, about ``1 - 0.80 s`` for small ``s`` and ``0.40 / s`` for large ``s``;
    0 for an infinite or NaN ``s``."""
    if not s > 0.0:
        return 1.0 if s == 0.0 else 0.0
    if not math.isfinite(s):
        return 0.0
    return max(0.0, math.erf(1.0 / (s * math.sqrt(2.0)))
               - s * _SQRT_2_OVER_PI * -math.expm1(-0.5 / (s * s)))


def coast_expected_iou(output: TrackOutput) -> float:
    """Expected IoU of a coasting track's box with the person it follows: one number that
    carries both the filter's last miss (``last_match_iou``) and how uncertain its
    prediction has become (the position block of the Kalman covariance P(t|t-1), (4.3)).

    Derivation, for two boxes of the same size (w, h) shifted by (dx, dy): their
    intersection is ``a w h`` with the overlap fraction ``a = (1 - |dx|/w)(1 - |dy|/h)``,
    and their IoU is ``a / (2 - a)``; conversely an IoU ``m`` is an overlap ``2m / (1 + m)``.

    1. At its last detection the prediction (4.2) met the detected box at IoU
       ``m = last_match_iou``: the motion model was off the person by the overlap
       ``a_m = 2m / (1 + m)`` (a bias that coasting keeps: the filter extrapolates the same
       model).
    2. Since then the person may be anywhere the filter's covariance allows: a zero-mean
       Gaussian offset with stds ``sqrt(P_xx)`` and ``sqrt(P_yy)`` costs, in expectation,
       the overlap ``axis_overlap(sqrt(P_xx) / w) * axis_overlap(sqrt(P_yy) / h)``
       (:func:`axis_overlap`, the two axes independent, P_xy ignored).  The covariance
       holds the last detection's uncertainty too (a low detection score or kernel
       similarity widens the measurement std, :func:`mk_tracker.tracking.track.
       measurement_sigma`, so such a track's P is larger from the start).
    3. The two shifts compound to first order as a product of overlaps:
       ``a = a_m * a_x * a_y``, and the estimate is ``a / (2 - a)``.

    Since ``a / (2 - a)`` is convex, this is the IoU of the expected overlap, at most the
    expected IoU (Jensen): a conservative estimate.  Without coasting uncertainty it is
    ``m`` itself; with a perfect last match it falls with the std per box side alone, so a
    level on it is a level on both former bounds (``min_reported_coast_match_iou``,
    ``max_reported_coast_std``) in one physical unit: the IoU the scoring and the consumer
    need.  0 for an empty box or a NaN / non-positive match IoU."""
    m = float(output.last_match_iou)
    w, h = float(output.box[2]), float(output.box[3])
    if not (m > 0.0 and w > 0.0 and h > 0.0):
        return 0.0
    m = min(m, 1.0)
    pxx, _, _, pyy = output.position_covariance
    a = (2.0 * m / (1.0 + m)) * axis_overlap(math.sqrt(max(pxx, 0.0)) / w) \
        * axis_overlap(math.sqrt(max(pyy, 0.0)) / h)
    return a / (2.0 - a)
