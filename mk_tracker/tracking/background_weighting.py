"""Corrected background-weighted histograms (CBWH) of the kernels' target models.

A colour of the target model ``q_i`` that is also common in the target's surroundings
pulls the mean shift (C.3) towards the background and towards look-alike passers-by.
Comaniciu, Ramesh & Meer (TPAMI 2003, Sec. 6.2) weight the histogram bins by how rare each
colour is in the background; Ning, Zhang, Zhang & Wu ("Robust mean-shift tracking with
corrected background-weighted histogram", IET Computer Vision 2012) showed that weighting
both the target model and the candidate (BWH) cancels in the mean-shift weights, and that
the weights must be applied to the **target model only** (the "corrected" BWH):

* ``o`` is the histogram of a ring of background around the target box (the box grown by
  ``background_ring`` box sizes on every side, minus the box; Ning et al. take a region
  of three times the target's area, ``background_ring`` ~0.37), normalised to sum 1;
* ``v_u = min(o* / o_u, 1)`` with ``o*`` the smallest non-zero ``o_u`` (a colour absent
  from the ring keeps weight 1), here floored at ``background_weight_floor``;
* ``q'_iu = v_u q_iu / sum_u v_u q_iu``: each kernel's model, still a distribution; the
  candidate ``p_i(x)`` is *not* weighted.

With the K-L cost of Appendix C, ``J_i(x) = sum_u q'_iu log(q'_iu / p_iu(x))``, and
``p_iu(x) = C sum_j k(||(z_j - x)/h||^2) delta[b(z_j) - u]`` (Sec. III-A):

    -grad J_i(x) = sum_u (q'_iu / p_iu(x)) grad p_iu(x)
                 = (2 C / h^2) sum_j g_j (q'_{b(z_j)} / p_{b(z_j)}(x)) (z_j - x),

so the mean-shift vector (C.3)-(C.4) keeps its form, ``m(x) = sum z w g / sum w g - x``,
with pixel weights ``w_j = q'_{b(z_j)} / p_{b(z_j)}(x) = v_{b(z_j)} q_{b(z_j)} / (c_i
p_{b(z_j)}(x))`` (``c_i = sum_u v_u q_iu``): the plain weight times the bin's background
weight (``sqrt`` of it with the Bhattacharyya weights of Comaniciu et al.).  A pixel whose
colour is frequent in the ring pulls less; the projected-gradient step (5)/(8) takes ``J_x
= -m`` per kernel as before, so the weighted model only enters through ``q'``
(:class:`~mk_tracker.tracking.search_region.SearchRegion` evaluates either backend
unchanged).

**Similarity scale.**  The weighted model no longer matches the target's own histogram:
on the first box ``J_i = KL(q'_i || q~_i) = J0_i > 0``, so ``exp(-J_i)`` starts below 1
and the absolute levels (``similarity_gate``, ``lost_similarity``, the occlusion level of
the lifecycle, the coarse-to-fine start and re-search levels) would all mean something
else.  Every decision therefore uses the cost *in excess of* the first box's,
``exp(-max(J_i - J0_i, 0))`` (:func:`corrected_costs`): 1 on the target's first-frame
appearance, as the plain model's ``exp(-J_i)`` is (up to the smoothing of ``p~``), and
lower where the target-specific colours are missing.  The ordering of positions by ``J_i``
(what Algorithm 1 minimises) is unchanged by the constant.

**Scale.**  The scale step (9)-(11) is taken with the plain models
(:meth:`~mk_tracker.tracking.multi_kernel.MultiKernelTracker._update_scale`): the weighted
density leaves out the colours the person shares with the background, so its bandwidth
derivative measures the extent of the target-specific colours and shrank the box onto them.

**Re-computing the background** (Ning et al.): after a frame in which the target is seen
(mean corrected similarity above ``similarity_gate``), the ring histogram ``o'`` at the new
box is compared with ``o`` by the Bhattacharyya coefficient; below
``background_update_similarity`` the background has changed enough (a pan, a passer-by in
the ring), so ``o <- o'`` and ``v``, ``q'`` and ``J0`` are derived again from the plain
models (which a model update or the completion of models at the image border change; the
weighted ones are always derived from them).

Where it is used: tracks started by hand (``manual_track.background_weighting`` cbwh, chosen
by the leave-one-clip-out protocol of ``benchmarks/bench_single_target.py``); tracks born
from detections keep the plain models (``multi_kernel.background_weighting`` none: it did
not win held out in ``benchmarks/bench_multi_object.py``).  Both measured in
docs/benchmark_single_target.md, "Findings".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mk_tracker.tracking.kernel_histograms import smoothed

__all__ = ["BACKGROUND_WEIGHTINGS", "BackgroundModel", "ring_region", "ring_histogram",
           "background_weights", "weighted_models", "self_costs", "corrected_costs",
           "histogram_overlap", "background_model", "reweighted"]

#: ``none``: the plain models of Chu et al.; ``cbwh``: Ning et al.'s corrected weighting
BACKGROUND_WEIGHTINGS = ("none", "cbwh")


@dataclass
class BackgroundModel:
    """The background weighting of one target.

    ``plain`` the unweighted kernel models ``q_i`` ``(N, m)``; ``histogram`` the ring's
    ``o`` ``(m,)``; ``weights`` ``v`` ``(m,)``; ``offsets`` ``J0_i`` ``(N,)``, the cost of the
    weighted models on the plain ones; ``updates`` how often ``o`` was re-computed.
    """

    plain: np.ndarray
    histogram: np.ndarray
    weights: np.ndarray
    offsets: np.ndarray
    updates: int = 0


def ring_region(box: tuple[float, float, float, float], ring: float, width: int,
                height: int) -> tuple[int, int, int, int] | None:
    """Integer region ``(x0, y0, x1, y1)`` of ``box`` grown by ``ring`` box sizes on every
    side (``ring * w`` in x, ``ring * h`` in y), clipped to the image; None when empty."""
    x, y, w, h = (float(v) for v in box)
    x0 = max(int(np.floor(x - ring * w)), 0)
    y0 = max(int(np.floor(y - ring * h)), 0)
    x1 = min(int(np.ceil(x + w + ring * w)), int(width))
    y1 = min(int(np.ceil(y + h + ring * h)), int(height))
    if x1 <= x0 or y1 <= y0:
        return None
    return x0, y0, x1, y1


def ring_histogram(bins: np.ndarray, origin: tuple[int, int], stride: int,
                   box: tuple[float, float, float, float], n_bins: int) -> np.ndarray:
    """Histogram ``o`` (sums to 1) of the samples of ``bins`` whose pixel centres lie outside
    ``box``; ``bins[r, c]`` is image pixel ``(ox + c * stride, oy + r * stride)``.  All zero
    when no sample lies outside the box (the box covers the region)."""
    b = np.asarray(bins)
    h, w = b.shape
    st = int(stride)
    xs = origin[0] + st * np.arange(w, dtype=np.float64) + 0.5
    ys = origin[1] + st * np.arange(h, dtype=np.float64) + 0.5
    bx, by, bw, bh = (float(v) for v in box)
    in_x = (xs >= bx) & (xs < bx + bw)
    in_y = (ys >= by) & (ys < by + bh)
    outside = ~(in_y[:, None] & in_x[None, :])
    counts = np.bincount(b[outside].astype(np.int64).reshape(-1), minlength=int(n_bins))
    total = float(counts.sum())
    if total <= 0:
        return np.zeros(int(n_bins))
    return counts[:int(n_bins)] / total


def background_weights(o: np.ndarray, floor: float = 0.0) -> np.ndarray:
    """``v_u = max(min(o* / o_u, 1), floor)`` with ``o*`` the smallest non-zero bin of ``o``;
    1 for a colour absent from the background (and everywhere when ``o`` is all zero)."""
    o = np.asarray(o, dtype=np.float64)
    if np.any(~np.isfinite(o)) or np.any(o < 0):
        raise ValueError("a background histogram needs finite non-negative bins")
    v = np.ones_like(o)
    present = o > 0
    if present.any():
        o_star = float(o[present].min())
        v[present] = np.minimum(o_star / o[present], 1.0)
    return np.maximum(v, float(floor))


def weighted_models(plain: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``q'_iu = v_u q_iu / sum_u v_u q_iu`` per row; a row with no weighted mass (an empty
    model) is returned unchanged."""
    q = np.asarray(plain, dtype=np.float64)
    out = q * np.asarray(v, dtype=np.float64)[None, :]
    totals = out.sum(axis=1)
    ok = totals > 0
    out[ok] /= totals[ok, None]
    out[~ok] = q[~ok]
    return out


def self_costs(weighted: np.ndarray, plain: np.ndarray, epsilon: float) -> np.ndarray:
    """``J0_i = sum_u q'_iu log(q'_iu / q~_iu)``: the K-L cost (Appendix C) of each weighted
    model against its own plain model as a candidate (smoothed as every candidate is,
    :func:`~mk_tracker.tracking.kernel_histograms.smoothed`)."""
    out = np.zeros(len(weighted))
    for i, (qw, qp) in enumerate(zip(weighted, plain)):
        ps = smoothed(np.asarray(qp, dtype=np.float64), epsilon)
        nz = qw > 0
        out[i] = float(np.sum(qw[nz] * np.log(qw[nz] / ps[nz])))
    return out


def corrected_costs(costs: np.ndarray, background: BackgroundModel | None,
                    n_layouts: int = 1) -> np.ndarray:
    """``J_i - J0_i`` for ``n_layouts`` copies of a target's kernels (rows ordered layout by
    layout); the costs themselves without a background model.  ``inf`` stays ``inf``."""
    c = np.asarray(costs, dtype=np.float64)
    if background is None:
        return c
    return c - np.tile(background.offsets, int(n_layouts))


def histogram_overlap(a: np.ndarray, b: np.ndarray) -> float:
    """Bhattacharyya coefficient ``sum_u sqrt(a_u b_u)`` of two histograms, in [0, 1]."""
    return float(np.clip(np.sqrt(np.maximum(a, 0.0) * np.maximum(b, 0.0)).sum(), 0.0, 1.0))


def background_model(plain: np.ndarray, o: np.ndarray, floor: float, epsilon: float
                     ) -> tuple[BackgroundModel, np.ndarray]:
    """The :class:`BackgroundModel` of plain models ``plain`` and ring histogram ``o``, and
    the weighted models ``q'`` the kernels are matched against."""
    plain = np.array(plain, dtype=np.float64, copy=True)
    v = background_weights(o, floor)
    q = weighted_models(plain, v)
    return BackgroundModel(plain, np.asarray(o, dtype=np.float64).copy(), v,
                           self_costs(q, plain, epsilon)), q


def reweighted(background: BackgroundModel, floor: float, epsilon: float) -> np.ndarray:
    """Derive ``v``, ``J0`` and the weighted models again from ``background.histogram`` and
    ``background.plain`` (after either changed); returns the weighted models."""
    background.weights = background_weights(background.histogram, floor)
    q = weighted_models(background.plain, background.weights)
    background.offsets = self_costs(q, background.plain, epsilon)
    return q
