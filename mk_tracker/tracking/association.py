"""Optimal assignment of detections to tracks.

The cost of giving detection ``j`` to track ``i`` combines two cues:

* the overlap of the detection box with the track's predicted box, ``1 - IoU``;
* the Kalman-gated distance of the detection centre from the predicted centre: the squared
  Mahalanobis distance ``d2 = nu^T S^-1 nu`` with the innovation ``nu = z - H s(t|t-1)`` and
  its covariance ``S = H P(t|t-1) H^T + sigma_w^2 I`` (the bracket of (4.5) in Schizas et
  al. 2018).  Under the model (4.1) ``d2`` is chi-square with two degrees of freedom, so
  pairs with ``d2`` above a quantile (``gate``) are impossible and get an infinite cost.

``cost = overlap_weight * (1 - IoU) + (1 - overlap_weight) * d2 / gate`` (the distance term
is in [0, 1] inside the gate), optionally plus an appearance term.  The assignment minimising
the total cost is found with the Hungarian method (``scipy.optimize.linear_sum_assignment``);
pairs whose cost exceeds ``max_cost`` are then left unmatched.

With ``max_height_ratio`` a second validation gate acts on the box height: a detection whose
height differs from the track's smoothed height by more than that factor
(``|ln(h_det / h_track)| > ln(max_height_ratio)``, :func:`height_ratio_exceeded`) is not
assigned to that track (an infinite cost, like a pair outside the distance gate).  DeepSORT
(Wojke et al. 2017, eq. (1)-(2)) gates on the Mahalanobis distance of the whole
(x, y, aspect, height) measurement, and the validation region of Bar-Shalom & Fortmann
(1988) covers every measured component; our filter has the centre only in its state (the
size is smoothed apart), so the size component of the gate is this ratio on the height.
On the TUD clips the public detector gives short upper-body boxes and boxes around two
people whose centres lie off the person (docs/failure_analysis.md, "Why the coasting boxes
sit off the person").  Matching such a detection but not correcting the centre with it was
screened too and lost to forbidding the pair on TUD-Campus, TUD-Stadtmitte and crowd-15
(commit d052bb1 has it; docs/benchmark_multi_object.md).

Everything here is pure numpy on arrays, so the work per frame is one vectorised cost matrix
of size tracks x detections.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from mk_tracker.boxes import iou_matrix
from mk_tracker.parameters import ParameterError, parameter

#: Cost given to impossible pairs before the Hungarian step (any value above every real
#: cost works; inf is not accepted by linear_sum_assignment when a row is all-inf).
_FORBIDDEN = 1e6


class AssociationError(ValueError):
    """Arrays of the wrong shape or with non-finite values were given to the association."""


@dataclass(frozen=True)
class AssociationConfig:
    """Constants of the track-detection cost (see the module docstring)."""

    overlap_weight: float = parameter(
        0.8, "Weight of (1 - IoU) in the cost; the Mahalanobis term gets 1 - this",
        minimum=0.0, maximum=1.0)
    gate: float = parameter(
        13.8, "Chi-square (2 dof) gate on the squared Mahalanobis distance of a detection "
        "centre from a predicted centre; 9.21 = 99%, 13.8 = 99.9%", minimum=0.1, maximum=1e4)
    max_cost: float = parameter(
        0.85, "Pairs with a larger combined cost are not matched", minimum=0.0, maximum=10.0)
    min_iou: float = parameter(
        0.0, "Pairs with less overlap than this are not matched (0 = distance gate only)",
        minimum=0.0, maximum=1.0)
    max_height_ratio: float = parameter(
        0.0, "Size validation gate: a detection whose height differs from the track's "
        "smoothed height by more than this factor (either way) is not assigned to it "
        "(Wojke et al. 2017 gate on the height too); 0 = off, else at least 1",
        minimum=0.0, maximum=100.0)

    def __post_init__(self) -> None:
        # The declared range [0, 100] is what a ROS range can say; a factor in (0, 1) would
        # forbid every pair, so it is refused here instead of being read silently as "off".
        if 0.0 < self.max_height_ratio < 1.0:
            raise ParameterError(
                f"max_height_ratio: {self.max_height_ratio} is a factor below 1; "
                "use 0 (off) or a factor of at least 1")


@dataclass(frozen=True)
class Assignment:
    """Result of :func:`assign`: matched ``(row, col)`` pairs and the unmatched indices."""

    matches: list[tuple[int, int]]
    unmatched_rows: list[int]
    unmatched_cols: list[int]


def mahalanobis_matrix(centers: np.ndarray, innovation_covs: np.ndarray,
                       points: np.ndarray) -> np.ndarray:
    """Squared Mahalanobis distances ``(T, D)`` of ``points (D, 2)`` from ``centers (T, 2)``.

    ``innovation_covs`` is ``(T, 2, 2)``, each ``H P H^T + sigma_w^2 I`` of one track.
    ``points`` may also be ``(T, D, 2)`` when each track sees the detections at a different
    place (detections moved to the frame time with that track's velocity).
    """
    c = np.asarray(centers, dtype=np.float64).reshape(-1, 2)
    s = np.asarray(innovation_covs, dtype=np.float64).reshape(-1, 2, 2)
    p = np.asarray(points, dtype=np.float64)
    if s.shape[0] != c.shape[0]:
        raise AssociationError(f"{c.shape[0]} centres but {s.shape[0]} covariances")
    if p.ndim == 2:
        p = np.broadcast_to(p.reshape(1, -1, 2), (c.shape[0], p.shape[0], 2))
    if p.ndim != 3 or p.shape[0] != c.shape[0] or p.shape[2] != 2:
        raise AssociationError(f"points of shape {p.shape} do not fit {c.shape[0]} tracks")
    if c.shape[0] == 0 or p.shape[1] == 0:
        return np.zeros((c.shape[0], p.shape[1]))
    nu = p - c[:, None, :]                                   # (T, D, 2)
    a, b, d = s[:, 0, 0], s[:, 0, 1], s[:, 1, 1]
    det = a * d - b * b
    if np.any(~np.isfinite(det)) or np.any(det <= 0):
        raise AssociationError("an innovation covariance is not positive definite")
    # Inverse of a symmetric 2x2 [[a, b], [b, d]] is [[d, -b], [-b, a]] / det.
    x, y = nu[..., 0], nu[..., 1]
    return (d[:, None] * x * x - 2.0 * b[:, None] * x * y + a[:, None] * y * y) / det[:, None]


def height_ratio_exceeded(track_heights: np.ndarray, detection_heights: np.ndarray,
                          max_ratio: float) -> np.ndarray:
    """``(T, D)`` booleans: detection heights outside ``[h / max_ratio, h * max_ratio]`` of
    each track height ``h`` (the size component of the validation gate, module docstring).

    ``detection_heights`` is ``(D,)`` or ``(T, D)`` (per-track time-compensated boxes);
    ``max_ratio`` 0 (off) or below 1 gives all False.  A pair in which either height is not
    a positive finite number is outside the gate (True): such a box cannot be a person, and
    one bad box must not stop the frame.
    """
    th = np.asarray(track_heights, dtype=np.float64).reshape(-1)
    dh = np.asarray(detection_heights, dtype=np.float64)
    if dh.ndim == 1:
        dh = np.broadcast_to(dh[None, :], (th.shape[0], dh.shape[0]))
    if dh.ndim != 2 or dh.shape[0] != th.shape[0]:
        raise AssociationError(f"detection heights {dh.shape} do not fit {th.shape[0]} tracks")
    if max_ratio < 1.0 or dh.size == 0:
        return np.zeros(dh.shape, dtype=bool)
    valid = (np.isfinite(th) & (th > 0))[:, None] & np.isfinite(dh) & (dh > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        log_ratio = np.abs(np.log(dh / th[:, None]))
    return ~valid | (log_ratio > math.log(max_ratio))


def association_cost(track_boxes: np.ndarray, detection_boxes: np.ndarray,
                     mahalanobis: np.ndarray, config: AssociationConfig,
                     extra_cost: np.ndarray | None = None) -> np.ndarray:
    """Cost matrix ``(T, D)``; ``inf`` marks pairs outside the gate or below ``min_iou``.

    ``track_boxes (T, 4)`` are the predicted boxes, ``detection_boxes`` ``(D, 4)`` or
    ``(T, D, 4)`` (per-track time-compensated boxes), ``mahalanobis (T, D)`` from
    :func:`mahalanobis_matrix`, ``extra_cost (T, D)`` an optional additive term (for
    instance ``1 - appearance similarity``).
    """
    t = np.asarray(track_boxes, dtype=np.float64).reshape(-1, 4)
    d = np.asarray(detection_boxes, dtype=np.float64)
    m = np.asarray(mahalanobis, dtype=np.float64)
    n_det = d.shape[-2] if d.ndim == 3 else d.reshape(-1, 4).shape[0]
    if m.shape != (t.shape[0], n_det):
        raise AssociationError(f"Mahalanobis matrix {m.shape} does not match "
                               f"{t.shape[0]} tracks x {n_det} detections")
    if d.ndim == 3:
        if d.shape[0] != t.shape[0]:
            raise AssociationError("per-track detection boxes do not match the tracks")
        ious = np.stack([iou_matrix(t[i:i + 1], d[i])[0] for i in range(t.shape[0])]) \
            if t.shape[0] else np.zeros((0, n_det))
    else:
        ious = iou_matrix(t, d.reshape(-1, 4))
    if np.any(np.isnan(m)):
        raise AssociationError("Mahalanobis matrix has NaN values")
    w = config.overlap_weight
    cost = w * (1.0 - ious) + (1.0 - w) * np.minimum(m / config.gate, 1.0)
    if extra_cost is not None:
        e = np.asarray(extra_cost, dtype=np.float64)
        if e.shape != cost.shape:
            raise AssociationError(f"extra cost {e.shape} does not match {cost.shape}")
        cost = cost + e
    forbidden = (m > config.gate) | (ious < config.min_iou)
    if config.max_height_ratio > 0:
        heights = d[..., 3] if d.ndim == 3 else d.reshape(-1, 4)[:, 3]
        forbidden |= height_ratio_exceeded(t[:, 3], heights, config.max_height_ratio)
    cost[forbidden] = np.inf
    return cost


def assign(cost: np.ndarray, max_cost: float) -> Assignment:
    """Hungarian assignment on ``cost`` (``inf`` = impossible); pairs above ``max_cost`` dropped.

    Returns every row and column that is not in an accepted pair as unmatched, in
    increasing order.
    """
    c = np.asarray(cost, dtype=np.float64)
    if c.ndim != 2:
        raise AssociationError(f"cost must be a matrix, got shape {c.shape}")
    if np.any(np.isnan(c)):
        raise AssociationError("cost matrix has NaN values")
    n_rows, n_cols = c.shape
    matches: list[tuple[int, int]] = []
    if n_rows and n_cols:
        finite = np.where(np.isfinite(c), c, _FORBIDDEN)
        rows, cols = linear_sum_assignment(finite)
        for r, k in zip(rows.tolist(), cols.tolist()):
            if np.isfinite(c[r, k]) and c[r, k] <= max_cost:
                matches.append((r, k))
    matched_rows = {r for r, _ in matches}
    matched_cols = {k for _, k in matches}
    return Assignment(matches=matches,
                      unmatched_rows=[r for r in range(n_rows) if r not in matched_rows],
                      unmatched_cols=[k for k in range(n_cols) if k not in matched_cols])
