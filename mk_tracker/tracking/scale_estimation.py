"""The scale step of the multiple-kernel tracker: eqs. (9)-(11) of Chu et al. 2013 and its checks.

After Algorithm 1 has placed the kernels, Sec. III-E updates the target's scale from the
derivative of the density estimate (1) with respect to the kernel bandwidth ``h``:

    r(h) = grad f(h) / (h f(h))                                   (9)-(10)
    Delta s = beta r(h),     s_t = s_{t-1} (1 + Delta s)          (10), (11)

``r`` is the W-weighted mean of the kernels' ratios
(:func:`mk_tracker.tracking.kernel_histograms.scale_ratio`); it is positive when the
pixels near the kernel rims carry more weight ``q_u / p_u`` than those near the centres, i.e.
when the target looks larger than the kernels.

Why the box of an undetected track runs away on BU-TIV-lab's grey frames (issue #19;
measured with ``benchmarks/diagnose_scale.py``, docs/scale_update.md).  On a grey frame the
HSV histogram holds only the ``value_bins`` intensity bins.  A track's kernels keep the size of
the box they were started on (a model refresh needs an isolated detection), which can be a
large early detection: its model is then mostly wall, and a bigger kernel around the person
matches it *better*, so (10) proposes growth and the cost check confirms it (the kept growing
steps lowered the cost by a median 1 %; none was an exact tie).  The checks below and the
multi-object tracker's ``refiner_size_from_detection`` / ``max_refined_size_ratio`` stop most
of that growth, but cost BU-TIV-lab ids (the large boxes were stopping births), so all ship
off.

The checks here, each a parameter of :class:`ScaleEstimationConfig` (not in the paper
unless said so):

* ``acceptance="lower"``: a step is kept only when it *lowers* the weighted cost (7) by more
  than ``min_relative_gain`` of the cost at the old scale.  A tie, where the image gives no
  evidence about the size, keeps the old scale.
* ``method="three_scale"``: the classic test of Comaniciu, Ramesh & Meer (kernel-based
  object tracking, 2003): the cost is evaluated with kernels of scale ``s (1 - delta)``,
  ``s`` and ``s (1 + delta)``, the best one ``s*`` is taken (a tie keeps ``s``; with
  ``acceptance="lower"`` it must also beat ``s`` by the margin) and the scale is smoothed, ``s_t = s + gamma (s* - s)``.  Unlike
  theirs, the search is not repeated at each scale: the three are compared at the centroid
  Algorithm 1 found, which costs two extra kernel evaluations per frame.
* ``method="checked"``: the step of (10) is kept only when the three-scale test moves the
  same way (a rough check of the sign of (10) by finite differences).

In every method the step is bounded by ``max_scale_change`` and ``[min_scale, max_scale]`` of
:class:`~mk_tracker.tracking.multi_kernel.MultiKernelConfig`.  :func:`scale_step` returns a
:class:`ScaleStep` record of what it saw and did, which the tracker keeps on the target
(``TargetState.scale_step``) for diagnostics (``benchmarks/diagnose_scale.py``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from mk_tracker.parameters import parameter

__all__ = ["SCALE_METHODS", "SCALE_ACCEPTANCE", "ScaleEstimationConfig", "ScaleStep",
           "scale_step", "gated_step", "rescaled_centres"]

SCALE_METHODS = ("gradient", "three_scale", "checked")
SCALE_ACCEPTANCE = ("not_higher", "lower")


@dataclass(frozen=True)
class ScaleEstimationConfig:
    """How the scale step of Sec. III-E is proposed and checked (see the module docstring)."""

    method: str = parameter(
        "gradient", "Scale step: gradient = Delta s = beta r(h) of (9)-(11) (paper); "
        "three_scale = the best of s(1-delta), s, s(1+delta) by the cost (7), smoothed by "
        "gamma (Comaniciu, Ramesh & Meer 2003; not in the paper); checked = (10), kept only "
        "when the three-scale test moves the same way", choices=SCALE_METHODS)
    acceptance: str = parameter(
        "not_higher", "A step is kept when the weighted cost (7) at the new scale is "
        "not_higher than at the old one (ties pass), or lower by more than "
        "min_relative_gain of it (ties keep the old scale); only with verify_scale_step "
        "for the gradient method", choices=SCALE_ACCEPTANCE)
    min_relative_gain: float = parameter(
        0.0, "With acceptance lower: the fraction of the old cost (7) by which a new scale "
        "must lower it (0 = any strict decrease)", minimum=0.0, maximum=1.0)
    delta: float = parameter(
        0.05, "Three-scale test: kernels of scale s(1 - delta) and s(1 + delta) are compared "
        "with s (Comaniciu et al. use 0.1)", minimum=0.005, maximum=0.5)
    gamma: float = parameter(
        0.5, "Three-scale test: s_t = s + gamma (s* - s), the smoothing of the best scale s* "
        "(Comaniciu et al. use 0.1)", minimum=0.0, maximum=1.0)


@dataclass
class ScaleStep:
    """What one scale update saw and did (for diagnostics; the tracker keeps the last one).

    ``reason``: ``"gated"`` (the similarity gate refused the update: ``statistic`` is the gate
    statistic), ``"kept"``, ``"no_step"`` (Delta s rounded to nothing or clipped away),
    ``"higher"`` / ``"not_lower"`` (the acceptance rule refused), ``"disagree"`` (``checked``:
    the three-scale test moved the other way or not at all).  Costs are the weighted cost
    (7) at the old scale and at the proposed one (NaN when not evaluated).
    """

    statistic: float
    reason: str
    r: float = float("nan")
    ds: float = 0.0
    old_scale: float = float("nan")
    new_scale: float = float("nan")
    old_cost: float = float("nan")
    new_cost: float = float("nan")

    @property
    def accepted(self) -> bool:
        return self.reason == "kept"


def gated_step(statistic: float, scale: float) -> ScaleStep:
    """The record of an update the similarity gate refused."""
    return ScaleStep(statistic=float(statistic), reason="gated", old_scale=scale,
                     new_scale=scale)


def rescaled_centres(centres: np.ndarray, centroid: np.ndarray, ratio: float) -> np.ndarray:
    """Kernel centres scaled by ``ratio`` about ``centroid`` (14), so the offsets and the
    distances ``L`` of (12)-(13) follow the scale."""
    return centroid + (centres - centroid) * ratio


def weighted_cost(weights: np.ndarray, costs: np.ndarray) -> float:
    """``sum_i W_i J_i`` of (7), an empty kernel (infinite cost) counting as infinite."""
    return float(np.sum(weights * costs))


def _accept(old_cost: float, new_cost: float, config: ScaleEstimationConfig) -> str:
    """``"kept"`` or why the acceptance rule refuses ``new_cost`` against ``old_cost``."""
    if config.acceptance == "not_higher":
        return "kept" if new_cost <= old_cost else "higher"
    if not np.isfinite(new_cost):
        return "not_lower"
    if not np.isfinite(old_cost):
        return "kept"
    return "kept" if old_cost - new_cost > config.min_relative_gain * old_cost else \
        "not_lower"


def scale_step(evaluate: Callable[..., Any], search: Any, state: Any, weights: np.ndarray,
               ev: Any, mk_config: Any, statistic: float) -> ScaleStep:
    """One scale update of ``state`` after Algorithm 1; returns the :class:`ScaleStep`.

    ``evaluate(search, half_axes, centres, models)`` evaluates kernels (a
    :class:`~mk_tracker.tracking.kernel_histograms.KernelBatch`); ``ev`` is the evaluation at
    the located kernels, ``weights`` their ``W_i`` (7)-(8), ``mk_config`` the
    :class:`~mk_tracker.tracking.multi_kernel.MultiKernelConfig` (``beta``,
    ``max_scale_change``, ``min_scale``, ``max_scale``, ``verify_scale_step`` and its
    ``scale`` section).  On a kept step ``state.scale`` and ``state.centres`` are changed
    (the centres rescaled about the centroid); otherwise ``state`` is left as it was.
    """
    cfg: ScaleEstimationConfig = mk_config.scale
    s0 = float(state.scale)
    n = len(ev.scale_ratios)
    r = float(np.sum(weights * ev.scale_ratios)) / n
    old_cost = weighted_cost(weights, ev.costs)
    rec = ScaleStep(statistic=float(statistic), reason="no_step", r=r, old_scale=s0,
                    new_scale=s0, old_cost=old_cost)
    centroid = state.center

    def bounded(ds: float) -> float:
        ds = float(np.clip(ds, -mk_config.max_scale_change, mk_config.max_scale_change))
        return float(np.clip(s0 * (1.0 + ds), mk_config.min_scale, mk_config.max_scale))

    def cost_at(scale: float) -> float:
        trial = evaluate(search, state.base_half_axes * scale,
                         rescaled_centres(state.centres, centroid, scale / s0), state.models)
        return weighted_cost(weights, trial.costs)

    if cfg.method == "three_scale":
        best, best_cost, best_reason = s0, old_cost, "no_step"
        for factor in (1.0 - cfg.delta, 1.0 + cfg.delta):
            c = cost_at(s0 * factor)
            verdict = _accept(old_cost, c, cfg) if cfg.acceptance == "lower" else \
                ("kept" if c < old_cost else "not_lower")
            if verdict == "kept" and c < best_cost:
                best, best_cost, best_reason = s0 * factor, c, "kept"
            elif best_reason != "kept":
                best_reason = verdict
        rec.new_cost = best_cost if best_reason == "kept" else float("nan")
        if best_reason != "kept":
            rec.reason = best_reason
            return rec
        new_scale = bounded(cfg.gamma * (best - s0) / s0)
        rec.ds = new_scale / s0 - 1.0
    else:
        new_scale = bounded(mk_config.beta * r)
        rec.ds = new_scale / s0 - 1.0
        if not np.isfinite(new_scale) or new_scale == s0:
            return rec
        if cfg.method == "checked":
            up, down = cost_at(s0 * (1.0 + cfg.delta)), cost_at(s0 * (1.0 - cfg.delta))
            rec.new_cost = up if new_scale > s0 else down
            agree = (up < min(down, old_cost)) if new_scale > s0 else \
                (down < min(up, old_cost))
            if not agree:
                rec.reason = "disagree"
                return rec
        if mk_config.verify_scale_step:
            rec.new_cost = cost_at(new_scale)
            verdict = _accept(old_cost, rec.new_cost, cfg)
            if verdict != "kept":
                rec.reason = verdict
                return rec
    if not np.isfinite(new_scale) or new_scale == s0:
        return rec
    state.centres = rescaled_centres(state.centres, centroid, new_scale / s0)
    state.scale = new_scale
    rec.new_scale = new_scale
    rec.reason = "kept"
    return rec


def fit_height(state: Any, low: float, high: float, min_scale: float, max_scale: float
               ) -> bool:
    """Rescale ``state``'s kernels about their centroid (14) so the height of their box lies in
    ``[low, high]`` (the scale stays in ``[min_scale, max_scale]``); True when it changed.

    The multi-object tracker uses it to give the kernels a detection's size
    (``refiner_size_from_detection``) and to bound an undetected track's refinement to its
    last detected size (``max_refined_size_ratio``); not in the paper.
    """
    if state is None or not (np.isfinite(low) and np.isfinite(high)) or low <= 0:
        return False
    height = float(state.box[3])
    if not height > 0 or low <= height <= high:
        return False
    goal = low if height < low else high
    s0 = float(state.scale)
    new_scale = float(np.clip(s0 * goal / height, min_scale, max_scale))
    if new_scale == s0:
        return False
    state.centres = rescaled_centres(state.centres, state.center, new_scale / s0)
    state.scale = new_scale
    return True
