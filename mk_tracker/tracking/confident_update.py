"""Model update in high-confidence frames only (issue #16 item 3; ``confident_update_rate``,
for tracks started by hand ``manual_track.model_update`` ``confident``).

Chu, Hwang, Pai & Lan (IEEE TMM 2013), Sec. IV, blend the kernel models ``q_i`` towards the
current candidates ``p_i`` when the mean kernel similarity exceeds 0.3, with no rate given.
Here that gated update (``model_update_rate``) is off by default: at 0.02 and 0.1 the models
absorbed background and drifted (docs/benchmark_single_target.md).  Frozen first-frame
models fail the other way: on OTB Woman (camera pans, light changes) her similarity to them
decays to 0.02-0.15 and the track calls her occluded in 99% of her frames.

Correlation trackers update only in frames where the response is confidently on the target:
Wang, Liu & Huang (LMCF, CVPR 2017) when the peak and its sharpness (APCE) are both above
fixed fractions of their historical means; Bolme et al. (MOSSE, CVPR 2010) judge the peak by
its peak-to-sidelobe ratio.  The analogue here, per kernel ``i`` of a result the failure test
calls seen:

* its **contrast** ``c_i`` to a ring of displaced copies of the layout
  (:mod:`mk_tracker.tracking.peak_contrast`) is at least ``confident_contrast`` (the peak is
  distinct from its surroundings: a flat neighbourhood, a kernel half on an occluder that
  extends past it, or a neighbour as similar as the target score low), and
* its **level** ``rho_i = exp(-J_i)`` (above the first box's cost with a background
  weighting) is at least ``confident_level_ratio`` times its running mean ``m_i`` (LMCF's
  beta_1 = 0.7 of the historical mean: a sudden drop, an occluder stepping in front or the
  search jumping to another person, is not learnt, a slow change is);

and the frame as a whole passes both tests on the means over its kernels (one kernel does
not learn while the layout is off the target: on TUD-Stadtmitte person 3 the lower kernel
learnt the passer-by's legs while the upper one had lost her, and the track followed him);
then ``q_i <- (1 - r) q_i + r p_i`` with ``r = confident_update_rate`` (with a background
weighting on the plain model, the weighted model and ``J0`` follow,
:func:`~mk_tracker.tracking.background_weighting.reweighted`).  The absolute gate
``similarity_gate`` is not applied: a target whose level has already faded but whose peak
is distinct and steady is exactly what the update is for.  ``m_i`` is the plain mean of the kernel's levels
over every frame the failure test called seen (LMCF's historical mean; the level of the
first box, 1, is its first sample when the track is refined on its first frame); it is
updated after the decision, so a frame is compared with the frames before it.  (Counting
only the frames that were blended deadlocks: on OTB Woman the level halves between the
first two frames and no frame is ever blended.  A mean that forgets at the model's rate
follows a long occlusion down.)  The failure test itself is unchanged.

Cost: the contrast's one batched evaluation of ``8 N`` kernels per frame (~0.2-0.3 ms).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from mk_tracker.tracking.peak_contrast import peak_contrasts

if TYPE_CHECKING:
    from mk_tracker.tracking.kernel_histograms import KernelBatch
    from mk_tracker.tracking.multi_kernel import MultiKernelTracker, TargetState

__all__ = ["MODEL_UPDATES", "confident_kernels", "update_level_reference", "confident_update"]

#: how a track started by hand updates its kernel models: ``none`` keeps the first frame's
#: (the tracker's ``model_update_rate`` applies), ``confident`` blends them in confident
#: frames only (this module)
MODEL_UPDATES = ("none", "confident")


def confident_kernels(levels: np.ndarray, contrasts: np.ndarray, reference: np.ndarray | None,
                      min_contrast: float, level_ratio: float) -> np.ndarray:
    """Boolean per kernel: the frame is confident (the mean contrast over the kernels is at
    least ``min_contrast`` and the mean level at least ``level_ratio`` times the mean of
    ``reference``) and so is the kernel (``c_i >= min_contrast``,
    ``rho_i >= level_ratio * m_i``, ``rho_i > 0``).  ``reference`` ``m_i`` None = no history
    yet (the level tests pass).  Non-finite values count as 0.  The frame test keeps one
    kernel from learning while the other says the layout is off the target (a passer-by's
    legs under the upper kernel's drop)."""
    rho = np.asarray(levels, dtype=np.float64).reshape(-1)
    c = np.asarray(contrasts, dtype=np.float64).reshape(-1)
    if c.shape != rho.shape:
        raise ValueError(f"{c.size} contrasts for {rho.size} kernel levels")
    rho = np.where(np.isfinite(rho), rho, 0.0)
    c = np.where(np.isfinite(c), c, 0.0)
    m = np.zeros_like(rho)
    if reference is not None:
        m = np.asarray(reference, dtype=np.float64).reshape(-1)
        if m.shape != rho.shape:
            raise ValueError(f"{m.size} reference levels for {rho.size} kernel levels")
        m = np.where(np.isfinite(m), m, 0.0)
    ok = (rho > 0) & (c >= min_contrast) & (rho >= level_ratio * m)
    frame = c.mean() >= min_contrast and rho.mean() >= level_ratio * m.mean()
    return ok & frame


def update_level_reference(state: "TargetState", levels: np.ndarray) -> None:
    """``m_i <- m_i + (rho_i - m_i) / n`` for the ``n``-th frame: the plain mean of the
    kernel's levels over every frame counted so far (LMCF's historical mean); a non-finite
    level leaves its kernel's mean as it was."""
    rho = np.asarray(levels, dtype=np.float64).reshape(-1)
    state.level_frames += 1
    if state.level_reference is None:
        state.level_reference = np.where(np.isfinite(rho), rho, 0.0)
        return
    m = state.level_reference
    state.level_reference = np.where(np.isfinite(rho), m + (rho - m) / state.level_frames, m)


def confident_update(tracker: "MultiKernelTracker", image: np.ndarray, state: "TargetState",
                     centres: np.ndarray, ev: "KernelBatch", levels: np.ndarray,
                     models: np.ndarray) -> int:
    """One frame of the confident update for a result the failure test calls seen: the
    located layout ``centres`` with its evaluation ``ev`` and levels ``levels``
    (``gate_similarities``); ``models`` (the state's plain models) are blended in place for
    the confident kernels with pixels.  Updates the level reference; returns how many kernels
    were blended."""
    cfg = tracker.config
    rate = cfg.confident_update_rate
    contrasts = peak_contrasts(tracker, image, state, centres, ev.costs,
                               cfg.contrast_ring_distance)
    ok = confident_kernels(levels, contrasts, state.level_reference, cfg.confident_contrast,
                           cfg.confident_level_ratio)
    ok &= np.asarray(ev.n_pixels).reshape(-1) > 0
    update_level_reference(state, levels)
    for i in np.flatnonzero(ok):
        models[i] = (1.0 - rate) * models[i] + rate * ev.p[i]
    state.confident_updates += int(ok.sum())
    return int(ok.sum())
