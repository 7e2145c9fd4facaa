"""What the multi-object tracker reports for one frame (:class:`FrameResult`): every live
track's output, the multiple-kernel targets for drawing, and which tracks a consumer
should draw or score (:meth:`FrameResult.reported`: confirmed ones, coasting ones while
their position is still certain enough, never the hidden twin of a stacked pair).

Split from :mod:`mk_tracker.tracking.multi_object_tracker`, which produces it and still
re-exports these names.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mk_tracker.tracking.track import TrackOutput, TrackState

__all__ = ["FrameResult", "TrackKernels", "coast_position_std", "track_kernels"]


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
    #: live tracks stacked on another one of the same person, not reported
    suppressed_ids: set[int] = field(default_factory=set)

    def reported(self) -> list[TrackOutput]:
        """Tracks to draw or score: confirmed ones, and occluded (coasting) ones for at most
        ``max_reported_coast_time`` seconds since their last detection and while their
        position is certain to ``max_reported_coast_std`` of the box
        (:func:`coast_position_std`; 0 = no such bound) and while their prediction met
        their last detection at an IoU of at least ``min_reported_coast_match_iou``
        (``TrackOutput.last_match_iou``; 0 = no such bound); always for tracks started
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
