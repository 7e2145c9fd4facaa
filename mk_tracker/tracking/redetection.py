"""Failure detection and re-detection of one multiple-kernel target (issue #16, item 3).

Chu, Hwang, Pai & Lan (IEEE TMM 2013) couple the multiple-kernel search with a Kalman filter
(Sec. IV-D): the prediction (4.2) initialises Algorithm 1 and its result is the measurement
(4.1), (4.4).  Algorithm 1 is a local descent -- each kernel's mean-shift vector (C.3) sees
only the pixels under the kernel -- so a target that moved beyond about one kernel
half-axis of the prediction, or that was lost for a while, is not found again.  This module
adds, around that core and for tracks started by hand
(:mod:`mk_tracker.tracking.manual_track`), three things that
:meth:`mk_tracker.tracking.multi_kernel.MultiKernelTracker.refine` calls:

* **Failure detection against the track's own history**
  (:func:`kernel_values`, :func:`relative_similarities`, :func:`update_reference`; off by
  default).  An absolute level does not carry over between videos: on OTB Woman a box
  exactly on her scores ``exp(-J)`` 0.02-0.15 after 20 frames of panning and light change
  (below the 0.4 occlusion level, so the track coasts for the rest of the clip), a box one
  width off ~0.001 (docs/failure_analysis.md).  So each kernel learns the mean ``m_i`` and
  spread ``sd_i`` of a per-kernel value ``v_i`` over the frames in which the track was judged
  seen (exponential weights, rate ``similarity_reference_rate``, prior spread
  ``similarity_spread_prior``) and reports ``s_i = clip(1 - (m_i - v_i) / (k sd_i), 0, 1)``:
  1 at its usual value, 0 at ``k`` (``failure_sigmas``) spreads below it.  ``v_i`` is the
  negated K-L cost ``-J_i`` of Appendix C (``learnt_measure`` ``"kl"``) or the Bhattacharyya
  coefficient ``B_i = sum_u sqrt(p_u q_iu)`` (Comaniciu, Ramesh & Meer 2003).  The track has
  failed when the weighted statistic ``sum_i W_i s_i / N`` of (7)-(8) falls below
  ``recovery_similarity``.  Held out it did not win (docs/benchmark_single_target.md,
  "Findings"): with ``-J`` it brings Woman from 227 to 12 px but lets tracks on TUD follow a
  look-alike neighbour that the absolute level made them coast through; ``B`` separates
  target and background too little (background scores 0.5-0.85 of the target's ``B``).
* **Coarse-to-fine start** (:func:`grid_start`): the whole layout is scored at a grid of
  translations of the predicted start in one batched evaluation; Algorithm 1 runs again from
  the best point when it beats where the search from the prediction ended (a low frame rate,
  a fast walker, a velocity not yet learnt).  The prediction stays the first start and wins
  ties (Sec. IV-D).
* **Re-detection** (:func:`back_projection_peaks`, :func:`redetect`): after a failure, a
  window around the start box -- ``recovery_margin`` box sizes on each side, plus
  ``recovery_growth`` box sizes for every earlier frame of the failure (off by default: it
  lost held out), clipped to the image (so a long failure scans the whole frame) -- is
  back-projected through the target's ratio histogram ``q / (q + p)`` (``q`` the mean of the
  kernel models, ``p`` the window's histogram: the posterior that a pixel of that colour is the target's,
  Swain & Ballard's ratio histogram), averaged over a box of the target's size; the highest
  peaks, a box apart, are candidates.  The layout is evaluated at each, Algorithm 1 refines
  from the best, and the result is kept only when the multiple-kernel similarity confirms it
  (weighted similarity at least ``recovery_similarity`` and above the first search's).

The back-projection looks each pixel's ratio up through the tracker's own bin table
(:func:`~mk_tracker.tracking.kernel_histograms.bin_lookup_tables`: the same bins as
``cv2.calcHist`` over OpenCV's 8-bit HSV ranges), so the scan and the kernels see the same
colours.  ``cv2.calcBackProject`` itself is not used: with a three-channel histogram it
returned all zeros in OpenCV 5.0.0 (measured; one- and two-channel histograms work).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import cv2
import numpy as np

from mk_tracker.tracking.kernel_histograms import (_colour_converted, bin_lookup_tables,
                                                  roi_has_nan)
from mk_tracker.tracking.search_region import SearchRegion
from mk_tracker.tracking.kernel_layouts import kernels_bounding_box

if TYPE_CHECKING:
    from mk_tracker.tracking.multi_kernel import MultiKernelTracker, TargetState

__all__ = ["LEARNT_MEASURES", "kernel_values", "kernel_bhattacharyya", "relative_similarities",
           "update_reference", "grid_start", "back_projection_peaks", "redetect", "scan_margin"]


def kernel_bhattacharyya(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Per row, the Bhattacharyya coefficient ``sum_u sqrt(p_u q_u)`` of two histograms
    (rows summing to 1; 0 for an empty candidate row).  In [0, 1], 1 for identical rows."""
    p = np.asarray(p, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64)
    return np.clip(np.sqrt(np.maximum(p, 0.0) * np.maximum(q, 0.0)).sum(axis=-1), 0.0, 1.0)


#: per-kernel values a level can be learnt on: the Bhattacharyya coefficient ``B_i`` or the
#: negated K-L cost ``-J_i`` of Appendix C (both larger = more alike)
LEARNT_MEASURES = ("bhattacharyya", "kl")


def kernel_values(p: np.ndarray, models: np.ndarray, costs: np.ndarray | None,
                  measure: str) -> np.ndarray:
    """``B_i`` (``"bhattacharyya"``) or ``-J_i`` (``"kl"``, from ``costs``; ``-inf`` for a
    kernel without pixels) per row."""
    if measure == "kl":
        if costs is None:
            raise ValueError("the kl measure needs the kernels' costs")
        return -np.asarray(costs, dtype=np.float64)
    if measure != "bhattacharyya":
        raise ValueError(f"measure must be one of {LEARNT_MEASURES}, got {measure!r}")
    return kernel_bhattacharyya(p, models)


def relative_similarities(state: "TargetState", p: np.ndarray, n_layouts: int = 1,
                          sigmas: float = 4.0, spread_floor: float = 0.05,
                          spread_prior: float = 0.0, costs: np.ndarray | None = None,
                          measure: str = "bhattacharyya") -> np.ndarray:
    """The kernels' similarities against the level learnt from the track's history, for
    candidate histograms ``p`` of ``n_layouts`` copies of the state's kernel layout (rows
    ordered layout by layout):

        s_i = clip(1 - (m_i - B_i) / (k sd_i), 0, 1),   sd_i = max(sqrt(v_i), spread_floor)

    with ``B_i`` the kernel's Bhattacharyya coefficient, ``m_i`` and ``v_i`` the exponentially
    weighted mean and variance of ``B_i`` over the frames the track was seen
    (:func:`update_reference`; before any, ``m_i = 1`` -- the model is the first candidate --
    and ``v_i = spread_prior^2``) and ``k = sigmas``: 1 at or above the usual coefficient, 0
    at ``k`` spreads below it (the failure level), linear in between.  With ``measure``
    ``"kl"`` the same is learnt on ``-J_i`` (starting from 0, the cost of the model itself)."""
    models = np.tile(state.models, (n_layouts, 1))
    mean, spread = _reference(state, spread_floor, spread_prior, measure)
    value = kernel_values(p, models, costs, measure)
    drop = np.tile(mean, n_layouts) - value
    with np.errstate(invalid="ignore"):
        out = 1.0 - drop / (float(sigmas) * np.tile(spread, n_layouts))
    return np.clip(np.nan_to_num(out, nan=0.0, neginf=0.0), 0.0, 1.0)


def _reference(state: "TargetState", spread_floor: float, spread_prior: float,
               measure: str = "bhattacharyya") -> tuple[np.ndarray, np.ndarray]:
    """``(m_i, sd_i)``: the learnt mean value and its spread (at least ``spread_floor``);
    before any learning the model's own value (1, or 0 for ``-J``) and ``spread_prior``."""
    mean, var = _learnt(state, spread_prior, measure)
    return mean, np.maximum(np.sqrt(np.maximum(var, 0.0)), max(float(spread_floor), 1e-6))


def _learnt(state: "TargetState", spread_prior: float, measure: str = "bhattacharyya"
            ) -> tuple[np.ndarray, np.ndarray]:
    n = state.num_kernels
    mean = getattr(state, "reference", None)
    var = getattr(state, "reference_var", None)
    start = 0.0 if measure == "kl" else 1.0
    mean = np.full(n, start) if mean is None or np.size(mean) != n else \
        np.asarray(mean, float)
    var = np.full(n, float(spread_prior) ** 2) if var is None or np.size(var) != n else \
        np.asarray(var, float)
    return mean.copy(), var.copy()


def update_reference(state: "TargetState", p: np.ndarray, relative: np.ndarray,
                     level: float, rate: float, spread_prior: float = 0.0,
                     costs: np.ndarray | None = None,
                     measure: str = "bhattacharyya") -> None:
    """Learn each seen kernel's coefficient (``s_i >= level``; the caller calls this only in
    frames where the track as a whole is seen): with ``d = B_i - m_i``,
    ``m_i <- m_i + rate d`` and ``v_i <- (1 - rate)(v_i + rate d^2)`` (the exponentially
    weighted mean and variance, starting from 1 and ``spread_prior^2``: the prior weighs
    ``(1 - rate)^n`` after ``n`` learnt frames)."""
    if rate <= 0.0:
        return
    mean, var = _learnt(state, spread_prior, measure)
    d = kernel_values(p, state.models, costs, measure) - mean
    seen = (np.asarray(relative) >= level) & np.isfinite(d)
    mean[seen] += rate * d[seen]
    var[seen] = (1.0 - rate) * (var[seen] + rate * d[seen] ** 2)
    state.reference = mean
    state.reference_var = var


def grid_start(tracker: "MultiKernelTracker", search: "SearchRegion", x: np.ndarray,
               state: "TargetState", box_width: float) -> tuple[np.ndarray | None, float]:
    """The coarse stage of the coarse-to-fine search: the kernel layout at ``x`` translated
    by every point of a ``(2k+1) x (2k+1)`` grid (spacing ``multi_start_radius * w / k``) is
    evaluated in one batch, and the translation with the highest mean similarity (5) (the
    tracker's decision similarity, :meth:`MultiKernelTracker.decision_similarities`) is
    returned as kernel centres with that score; None when that is the untranslated start
    (ties keep it: the Kalman prediction is the prior, Sec. IV-D)."""
    cfg = tracker.config
    k = int(cfg.multi_start_steps)
    spacing = cfg.multi_start_radius * float(box_width) / k
    if not spacing > 0.0:
        return None, 0.0
    steps = np.arange(-k, k + 1, dtype=np.float64) * spacing
    gx, gy = np.meshgrid(steps, steps)
    offsets = np.stack([gx.reshape(-1), gy.reshape(-1)], axis=1)
    centre = int(np.flatnonzero((offsets[:, 0] == 0) & (offsets[:, 1] == 0))[0])
    order = np.r_[centre, np.delete(np.arange(len(offsets)), centre)]
    offsets = offsets[order]                    # the untranslated start first
    n_k, n_o = state.num_kernels, len(offsets)
    centres = (x[None, :, :] + offsets[:, None, :]).reshape(-1, 2)
    axes = np.tile(state.half_axes, (n_o, 1))
    models = np.tile(state.models, (n_o, 1))
    ev = tracker._evaluate(search, axes, centres, models)
    means = tracker.decision_similarities(ev, state, n_o).reshape(n_o, n_k).mean(axis=1)
    best = int(np.argmax(means))                 # first maximum: the prediction on ties
    if best == 0:
        return None, float(means[0])
    return x + offsets[best], float(means[best])


def scan_margin(tracker: "MultiKernelTracker", state: "TargetState") -> float:
    """Box sizes the re-detection window reaches on each side of the start box:
    ``recovery_margin + recovery_growth * failed_frames`` (frames of the failure before this
    one), so the window grows with the time the target has been lost."""
    cfg = tracker.config
    return cfg.recovery_margin + cfg.recovery_growth * max(0, int(state.failed_frames))


def _window_hsv(image: np.ndarray, region: tuple[int, int, int, int], stride: int,
                colour_space: str) -> np.ndarray | None:
    """The strided window as 8-bit channels in the tracker's colour space; None for NaN."""
    x0, y0, x1, y1 = region
    roi = image[y0:y1:stride, x0:x1:stride]
    if roi_has_nan(roi):
        return None
    if roi.dtype != np.uint8:
        roi = np.clip(roi, 0, 255).astype(np.uint8)
    roi = np.ascontiguousarray(roi)
    return _colour_converted(roi, colour_space)


def back_projection_peaks(tracker: "MultiKernelTracker", image: np.ndarray,
                          state: "TargetState", box: tuple[float, float, float, float],
                          margin: float) -> tuple[list[np.ndarray], "SearchRegion | None"]:
    """Candidate box centres for the re-detection, best first, and the window's samples as a
    :class:`SearchRegion` (at the scan's stride) to evaluate the kernel layout on.

    The window ``box`` grown by ``margin`` box sizes (clipped to the image) is sampled every
    ``ceil(w / recovery_scan_cells)`` px and back-projected through
    the ratio histogram ``q / (q + p)`` (``q`` the mean of the kernel models ``q_i``,
    Sec. III-A; ``p`` the window's own histogram); the mean over a box of the target's
    size around each sample is the scan score, and its ``recovery_candidates`` highest peaks,
    each at least a box width or height from the others, are returned.
    """
    from mk_tracker.tracking.multi_kernel import _region
    cfg = tracker.config
    height, width = image.shape[:2]
    region = _region(box, margin, width, height)
    if region is None:
        return [], None
    stride = max(1, int(np.ceil(box[2] / cfg.recovery_scan_cells)))
    win = _window_hsv(image, region, stride, cfg.colour_space)
    if win is None or win.size == 0:
        return [], None
    table = bin_lookup_tables(cfg.colour_space, cfg.bins)
    flat = np.ascontiguousarray(table[0][win[..., 0]] + table[1][win[..., 1]]
                                + table[2][win[..., 2]], dtype=np.int32)
    p = np.bincount(flat.reshape(-1), minlength=tracker.n_bins).astype(np.float64) / flat.size
    q = state.models.mean(axis=0)
    ratio = q / np.maximum(q + p, 1e-12)
    weight = ratio[flat].astype(np.float32)          # the back-projection
    kw = max(1, int(round(box[2] / stride)))
    kh = max(1, int(round(box[3] / stride)))
    score = cv2.boxFilter(weight.astype(np.float32), -1, (kw, kh), normalize=True,
                          borderType=cv2.BORDER_CONSTANT)
    out = []
    for _ in range(cfg.recovery_candidates):
        i, j = np.unravel_index(int(np.argmax(score)), score.shape)
        if not score[i, j] > 0.0:
            break
        out.append(np.array([region[0] + j * stride, region[1] + i * stride],
                            dtype=np.float64))
        score[max(0, i - kh + 1):i + kh, max(0, j - kw + 1):j + kw] = -1.0
    scan = SearchRegion(flat, (region[0], region[1]),
                        stride, tracker.n_bins, cfg.profile, tracker.backend)
    return out, scan


def redetect(tracker: "MultiKernelTracker", image: np.ndarray, state: "TargetState",
             start_box: tuple[float, float, float, float], score: float):
    """Re-detection after a failure: the kernel layout is placed at every
    :func:`back_projection_peaks` candidate and evaluated (one batch); from the candidate
    with the highest mean decision similarity, if that already beats ``score`` (the first
    search's), Algorithm 1 runs in its own search region.  Returns ``((x, ev, iterations,
    history), search)`` when the result is confirmed -- weighted decision similarity (7)-(8)
    at least ``recovery_similarity`` and mean above
    ``score`` -- else None."""
    from mk_tracker.tracking.multi_kernel import _region, visibility_similarity
    cfg = tracker.config
    height, width = image.shape[:2]
    axes = state.half_axes
    centroid = np.array([start_box[0] + start_box[2] / 2.0,
                         start_box[1] + start_box[3] / 2.0])
    x0 = state.centres - state.center + centroid
    peaks, scan = back_projection_peaks(tracker, image, state, start_box,
                                        scan_margin(tracker, state))
    if not peaks:
        return None
    n_k, n_p = state.num_kernels, len(peaks)
    layouts = x0[None, :, :] + (np.array(peaks) - centroid)[:, None, :]
    # coarse: the candidates' layouts on the scan's samples, one batch
    ev = tracker._evaluate(scan, np.tile(axes, (n_p, 1)), layouts.reshape(-1, 2),
                           np.tile(state.models, (n_p, 1)))
    means = tracker.decision_similarities(ev, state, n_p).reshape(n_p, n_k).mean(axis=1)
    best = int(np.argmax(means))
    if not means[best] > score:      # no candidate beats the first search even before refining
        return None
    x = layouts[best]
    region = _region(kernels_bounding_box(x, axes), cfg.search_margin, width, height)
    if region is None:
        return None
    search = tracker._search_region(image, region, tracker._stride(axes))
    if search is None:
        return None
    res = tracker._algorithm1(search, region, x, state)
    found = tracker.decision_similarities(res[1], state)
    if visibility_similarity(found, None, "weighted") >= cfg.recovery_similarity \
            and float(found.mean()) > score:
        return res, search
    return None
