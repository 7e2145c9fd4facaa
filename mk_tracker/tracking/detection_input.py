"""The detections of one frame as the multi-object tracker consumes them.

A detection reaches the tracker as a :class:`FrameDetection` (a box, a score, its own stamp
and the image plane it is in).  Before association each one is checked and brought into
the RGB plane at the frame's time (:func:`prepare_detections`):

* a box that is not finite or has no area, a score or stamp that is not finite, or an
  unknown plane is skipped and counted (``FrameResult.skipped_bad_detections``);
* a thermal-plane box goes through the homography (thermal px -> RGB px,
  :func:`homography_matrix` checks it once, when the tracker is built);
* a detection whose stamp is more than ``stale_tolerance`` from the frame's is dropped and
  counted (``dropped_stale``); one scored below ``min_detection_score`` is left out;
* the box is clipped to the image; what remains is a :class:`PreparedDetection` that keeps
  its *lag* (frame stamp minus detection stamp).

:func:`detection_geometry` then moves each detection by each track's Kalman velocity times
that lag, so a detection computed on an older frame is compared with where the track is
now (the constant-velocity model (2.1) of both papers).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Iterable, Sequence

import numpy as np

from mk_tracker.boxes import InvalidBoxError, as_box, clip_box, transform_box
from mk_tracker.tracking.frame_result import FrameResult

__all__ = ["PLANES", "TrackerInputError", "FrameDetection", "PreparedDetection",
           "homography_matrix", "prepare_detections", "detection_geometry"]

PLANES = ("rgb", "thermal")


class TrackerInputError(ValueError):
    """An input the tracker cannot use at all (not an image, singular homography, ...)."""


@dataclass(frozen=True)
class FrameDetection:
    """A detection as the tracker consumes it.  ``stamp`` None = the frame's stamp."""

    box: tuple[float, float, float, float]
    score: float = 1.0
    stamp: float | None = None
    plane: str = "rgb"


@dataclass
class PreparedDetection:
    """A checked detection: ``box`` in the RGB plane at the detection's stamp, ``score``,
    and ``lag`` = frame stamp - detection stamp (s)."""

    box: np.ndarray
    score: float
    lag: float


def homography_matrix(values: Sequence[float]) -> np.ndarray:
    """The 3x3 thermal -> RGB homography from 9 row-major numbers; :class:`TrackerInputError`
    for a wrong count, a non-finite value or a singular matrix."""
    try:
        h = np.asarray(values, dtype=np.float64).reshape(3, 3)
    except (TypeError, ValueError) as exc:
        raise TrackerInputError(f"homography must be 9 numbers, got {values!r}") from exc
    if not np.all(np.isfinite(h)):
        raise TrackerInputError("homography has NaN or infinite values")
    scale = max(float(np.abs(h).max()), 1e-300)
    if abs(np.linalg.det(h / scale)) < 1e-12:
        raise TrackerInputError(f"homography {h.tolist()} is singular")
    return h


def prepare_detections(detections: Iterable[Any], stamp: float, width: int, height: int,
                       homography: np.ndarray, stale_tolerance: float,
                       min_detection_score: float, result: FrameResult
                       ) -> list[PreparedDetection]:
    """The usable detections of a ``width x height`` frame stamped ``stamp`` (module
    docstring); skips and drops are counted in ``result`` and said in its ``events``."""
    out: list[PreparedDetection] = []
    for det in detections:
        try:
            box = as_box(getattr(det, "box"))
            score = float(getattr(det, "score", 1.0))
            det_stamp = getattr(det, "stamp", None)
            det_stamp = stamp if det_stamp is None else float(det_stamp)
            plane = str(getattr(det, "plane", "rgb") or "rgb").lower()
            if plane not in PLANES or not math.isfinite(score) \
                    or not math.isfinite(det_stamp):
                raise InvalidBoxError(f"bad plane/score/stamp {plane!r} {score} {det_stamp}")
            if plane == "thermal":
                box = np.asarray(transform_box(box, homography))
        except (InvalidBoxError, AttributeError, TypeError, ValueError):
            result.skipped_bad_detections += 1
            continue
        lag = stamp - det_stamp
        if abs(lag) > stale_tolerance:
            result.dropped_stale += 1
            continue
        if score < min_detection_score:
            continue
        clipped = clip_box(box, width, height)
        if clipped is None:
            result.skipped_bad_detections += 1
            continue
        out.append(PreparedDetection(box=np.asarray(clipped), score=score, lag=lag))
    if result.dropped_stale:
        result.events.append(f"dropped {result.dropped_stale} detection(s) older or newer "
                             f"than {stale_tolerance} s")
    if result.skipped_bad_detections:
        result.events.append(f"skipped {result.skipped_bad_detections} bad detection(s) "
                             "(NaN, non-positive size, bad plane or outside the image)")
    return out


def detection_geometry(velocities: np.ndarray, dets: list[PreparedDetection]
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Detection boxes per track at the frame time ``(T, D, 4)`` and centres ``(T, D, 2)``,
    for tracks with Kalman velocities ``velocities`` ``(T, 2)`` (px/s).

    When every detection has the frame's stamp the boxes are the same for every track and
    ``(D, 4)`` / ``(D, 2)`` are returned instead (one IoU matrix for all tracks).
    """
    boxes = np.array([d.box for d in dets])                        # (D, 4)
    lags = np.array([d.lag for d in dets])                         # (D,)
    if not np.any(lags):
        return boxes, boxes[:, :2] + boxes[:, 2:] / 2.0
    vel = np.asarray(velocities, dtype=np.float64).reshape(-1, 2)  # (T, 2)
    shift = vel[:, None, :] * lags[None, :, None]                  # (T, D, 2)
    per_track = np.broadcast_to(boxes[None], (len(vel),) + boxes.shape).copy()
    per_track[..., :2] += shift
    centres = per_track[..., :2] + per_track[..., 2:] / 2.0
    return per_track, centres
