"""The contrast of a search's peak to a ring of displaced copies of its kernel layout.

The multiple-kernel search (Chu, Hwang, Pai & Lan, IEEE TMM 2013, Algorithm 1) ends at a
local minimum of the weighted cost (7); its absolute similarity ``rho_i = exp(-J_i)``
(Sec. III-A) says how well the located candidate matches the model, not whether it stands
out from its surroundings.  Correlation trackers judge the peak against its surroundings:
the peak-to-sidelobe ratio of MOSSE (Bolme, Beveridge, Draper & Lui, CVPR 2010) and the
target-versus-surroundings contrast of the distractor-aware model (Possegger, Mauthner &
Bischof, CVPR 2015).  Here the same kernels (same models, axes and evaluation) are placed on
a ring of ``RING_DIRECTIONS`` copies of the located layout, the ``k``-th one moved by
``distance * (w cos t_k, h sin t_k)`` (``w, h`` the box's size, ``t_k = 2 pi k / 8``), and
each kernel's **contrast** is

    c_i = 1 - max_k rho_i(ring k) / rho_i(box) = 1 - exp(-(min_k J_i(ring k) - J_i(box)))

clipped to [0, 1]: the cost the ring's best copy pays above the box, on a 0..1 scale.  A
distinct peak gives ~1 whatever its absolute level; a flat neighbourhood (kernels on uniform
background) or a neighbour as similar as the box gives ~0.  A ring copy with no pixels
(outside the image) is no competitor.  A constant offset of the cost (the background
weighting's ``J0_i``, :mod:`~mk_tracker.tracking.background_weighting`) cancels in the
difference.

Used by ``benchmarks/diagnose_single_target.py --separation`` and, through
:meth:`~mk_tracker.tracking.multi_kernel.MultiKernelTracker.peak_contrast`, by the
multi-object tracker's test of a still undetected track (``lifecycle.still_contrast``: the
geometric mean of level and contrast; off by default, on in the background detector's
tracker profile).  Two other uses tried in the tracker lost in the leave-one-clip-out
protocol and were deleted (docs/benchmark_single_target.md, "Findings"): as the *failure
test* of hand-started tracks (a look-alike passer-by is an equally distinct peak; commit
e43c509), and as the gate of a model update in confident frames only
(``manual_track.model_update`` confident, commit 9024b07).

Cost: one batched evaluation of ``8 N`` kernels on one more search region (the box grown by
``distance`` on every side); ~0.24 ms on OTB Woman.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from mk_tracker.tracking.kernel_layouts import kernels_bounding_box

if TYPE_CHECKING:
    from mk_tracker.tracking.multi_kernel import MultiKernelTracker, TargetState

__all__ = ["RING_DIRECTIONS", "ring_offsets", "kernel_contrasts", "ring_costs",
           "peak_contrasts"]

#: displaced copies of the layout on the ring (every 45 degrees)
RING_DIRECTIONS = 8


def ring_offsets(width: float, height: float, distance: float,
                 directions: int = RING_DIRECTIONS) -> np.ndarray:
    """``(directions, 2)`` translations ``distance * (w cos t_k, h sin t_k)``,
    ``t_k = 2 pi k / directions``.  Raises ``ValueError`` for a non-positive argument."""
    if not (width > 0 and height > 0 and distance > 0 and directions > 0):
        raise ValueError(f"ring needs a positive size, distance and count, got {width}, "
                         f"{height}, {distance}, {directions}")
    t = 2.0 * np.pi * np.arange(directions) / directions
    return np.stack([distance * width * np.cos(t), distance * height * np.sin(t)], axis=1)


def kernel_contrasts(box_costs: np.ndarray, ring: np.ndarray) -> np.ndarray:
    """Per kernel ``clip(1 - exp(-(min_k J_ik - J_i)), 0, 1)`` for the box's costs ``J_i``
    (``(N,)``) and the ring's ``J_ik`` (``(K, N)``).  A kernel without pixels at the box
    (infinite or NaN cost) has contrast 0; ring copies without pixels are ignored (a kernel
    whose whole ring is empty has contrast 1 when it has pixels)."""
    box = np.asarray(box_costs, dtype=np.float64).reshape(-1)
    ring = np.asarray(ring, dtype=np.float64).reshape(-1, box.size)
    ring = np.where(np.isfinite(ring), ring, np.inf)
    nearest = ring.min(axis=0) if ring.shape[0] else np.full(box.size, np.inf)
    with np.errstate(invalid="ignore", over="ignore"):
        out = 1.0 - np.exp(-(nearest - box))
    out = np.where(np.isfinite(box), out, 0.0)
    return np.clip(np.nan_to_num(out, nan=0.0), 0.0, 1.0)


def ring_costs(tracker: "MultiKernelTracker", image: np.ndarray, state: "TargetState",
               centres: np.ndarray, distance: float) -> np.ndarray | None:
    """``(RING_DIRECTIONS, N)`` costs ``J_i`` of the state's layout at ``centres`` moved to
    every ring position (:func:`ring_offsets`), one batched evaluation with the tracker's own
    models, axes and stride; None when the grown region is outside the image or holds NaN
    pixels."""
    from mk_tracker.tracking.multi_kernel import _region
    axes = state.half_axes
    box = kernels_bounding_box(centres, axes)
    height, width = image.shape[:2]
    region = _region(box, distance, width, height)
    if region is None:
        return None
    search = tracker._search_region(image, region, tracker._stride(axes))
    if search is None:
        return None
    offsets = ring_offsets(box[2], box[3], distance)
    n_k, n_o = state.num_kernels, len(offsets)
    layouts = (centres[None, :, :] + offsets[:, None, :]).reshape(-1, 2)
    ev = tracker._evaluate(search, np.tile(axes, (n_o, 1)), layouts,
                           np.tile(state.models, (n_o, 1)))
    return np.asarray(ev.costs, dtype=np.float64).reshape(n_o, n_k)


def peak_contrasts(tracker: "MultiKernelTracker", image: np.ndarray, state: "TargetState",
                   centres: np.ndarray, box_costs: np.ndarray, distance: float) -> np.ndarray:
    """Per-kernel contrast (:func:`kernel_contrasts`) of the layout at ``centres``, whose
    costs are ``box_costs``, to its ring at ``distance`` box sizes; zeros when the ring
    cannot be evaluated (no evidence of a distinct peak)."""
    ring = ring_costs(tracker, image, state, centres, distance)
    if ring is None:
        return np.zeros(state.num_kernels)
    return kernel_contrasts(box_costs, ring)
