"""Distractor-aware kernel models (Possegger, Mauthner & Bischof, CVPR 2015, "In defense of
color-based model-free tracking", DAT, Sec. 3.1).

The corrected background weighting (:mod:`mk_tracker.tracking.background_weighting`) makes
colours of a ring around the box count less; a look-alike that is *not* in the ring when the
weights are computed (a passer-by in the same dark clothes walking up to a person standing
still, TUD-Stadtmitte person 3, docs/failure_analysis.md) is still matched as well as the
target.  DAT separates the object from such *distractors*: regions away from the target that
the tracker itself finds similar to it.  Its object-vs-distractor likelihood per colour bin
``u`` is (DAT, eq. 5, with the counts of the object region ``H_O`` and of the distractor
regions ``H_D``)

    P(x in O | O or D, b_x = u) = H_O(u) / (H_O(u) + H_D(u)).

Here that likelihood weights each kernel's model the way the background weights of Ning et
al. do (only the target model is weighted, never the candidate; ``q'_iu ~ r_iu v_u q_iu``,
normalised per kernel), with, per kernel ``i``:

* ``H_O = q_i``, the kernel's plain model (a histogram summing to 1, i.e. counts in units of
  the kernel's area);
* ``H_D = d_i``, the kernel's distractor histogram: the sum of the candidate histograms
  ``p_i`` (Sec. III-A of Chu et al.) of the *distractor layouts* of a frame, in the same
  units, learnt with DAT's linear interpolation at ``distractor_rate``,
  ``d_i <- (1 - rate) d_i + rate sum_{layouts k in D} p_ki`` (DAT eq. 7) in every frame
  in which the target is seen (an empty sum lets ``d`` decay, so a distractor that has left is
  forgotten at the same rate);
* the distractor layouts of a frame: the kernel layout translated from the located result by
  the eight non-zero points of a 3 x 3 grid with spacing ``distractor_distance`` box widths
  (the same pixels in y), evaluated in one batch on the frame's search region, whose mean
  decision similarity (the tracker's, Sec. III-A) is at least ``distractor_similarity`` times
  the result's: regions away from the target that score nearly as well as it (DAT keeps the
  local maxima of its object vote map above a fraction of the target's; here the candidate
  positions are fixed so that one evaluation suffices).

``r_iu = q_iu / (q_iu + d_iu)`` is 1 for a colour no distractor has and 1/2 for a colour a
distractor has as often as the target; the normalisation of ``q'`` removes any factor common
to all bins.  Every decision level keeps its meaning because the tracker compares costs in
excess of the weighted model's own cost on the plain model (``J0_i``,
:func:`~mk_tracker.tracking.background_weighting.corrected_costs`), re-derived whenever
``d`` changes (:func:`~mk_tracker.tracking.background_weighting.reweighted`).  The scale
step keeps the plain models.

Cost: one batched evaluation of 8 layouts per seen frame on the pixels already quantised for
the search (a region grown to reach the layouts when the search's own does not), and the
re-derivation of the weighted models.
"""

from __future__ import annotations

import numpy as np

__all__ = ["distractor_offsets", "distractor_sum", "blend_distractors", "distractor_weights"]


def distractor_offsets(box_width: float, distance: float) -> np.ndarray:
    """``(8, 2)`` translations of the 3 x 3 grid with spacing ``distance * box_width`` px in
    x and y, without the centre."""
    s = float(distance) * float(box_width)
    steps = np.array([-s, 0.0, s])
    gx, gy = np.meshgrid(steps, steps)
    out = np.stack([gx.reshape(-1), gy.reshape(-1)], axis=1)
    return out[np.any(out != 0.0, axis=1)]


def distractor_sum(p: np.ndarray, similarities: np.ndarray, n_kernels: int, level: float
                   ) -> tuple[np.ndarray, int]:
    """``(sum over distractor layouts of their candidate histograms (N, m), how many)``:
    ``p`` and ``similarities`` hold ``n_layouts`` copies of an ``n_kernels`` layout (rows
    ordered layout by layout); a layout is a distractor when its mean similarity is at
    least ``level`` (and above 0)."""
    p = np.asarray(p, dtype=np.float64)
    n_k, m = int(n_kernels), p.shape[1]
    n_layouts = p.shape[0] // n_k
    s = np.asarray(similarities, dtype=np.float64).reshape(n_layouts, n_k)
    means = np.where(np.isfinite(s), s, 0.0).mean(axis=1)
    hit = (means >= float(level)) & (means > 0.0)
    rows = p.reshape(n_layouts, n_k, m)[hit]
    return (rows.sum(axis=0) if len(rows) else np.zeros((n_k, m))), int(hit.sum())


def blend_distractors(d: np.ndarray | None, observed: np.ndarray, rate: float) -> np.ndarray:
    """DAT's linear interpolation ``(1 - rate) d + rate observed`` (``d`` None = zeros)."""
    obs = np.asarray(observed, dtype=np.float64)
    if d is None:
        return float(rate) * obs
    return (1.0 - float(rate)) * np.asarray(d, dtype=np.float64) + float(rate) * obs


def distractor_weights(plain: np.ndarray, d: np.ndarray | None) -> np.ndarray:
    """``r_iu = q_iu / (q_iu + d_iu)`` (DAT eq. 5 per kernel), 1 where both are 0 or without
    distractors (``d`` None); same shape as ``plain``."""
    q = np.asarray(plain, dtype=np.float64)
    if d is None:
        return np.ones_like(q)
    total = q + np.asarray(d, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(total > 0.0, q / np.where(total > 0.0, total, 1.0), 1.0)
