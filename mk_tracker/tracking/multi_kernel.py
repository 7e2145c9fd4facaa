"""Multiple-kernel tracking with projected gradients (Chu, Hwang, Pai, Lan, IEEE TMM 2013).

One target is ``N`` elliptical kernels (layouts in :mod:`mk_tracker.tracking.kernel_layouts`) whose
centres form the state ``x = [x_1 y_1 ... x_N y_N]^T`` (Sec. IV-A).  Each kernel carries a
colour-histogram target model ``q_i`` and has a K-L cost ``J_i(x)`` (Appendix C,
:mod:`mk_tracker.tracking.kernel_histograms`).  Per frame the tracker solves (4)

    min_x  J(x) = sum_i W_i J_i(x)   (3), (7)   subject to  C(x) = 0   (12)-(13)

with the projected-gradient iteration of Algorithm 1 and the step (5)/(8):

    dx_A = alpha (-I + C_x (C_x^T C_x)^+ C_x^T) W J_x,     dx_B = -C_x (C_x^T C_x)^+ C(x)

where ``J_x`` is minus the kernels' mean-shift vectors (C.4).  Afterwards the scale is updated
from the bandwidth derivative of the density estimate (9)-(11), and the models are blended
towards the current candidates, both only when the mean similarity is above a gate (0.3).

Rank deficiency.  ``C_x^T C_x`` is often singular: 4 kernels give 12 constraints in an
8-dimensional state (rank at most 6: the constraints only see pairwise differences), and two
kernels stacked vertically have ``L_x = 0``, so the x-constraint ``(x_1 - x_2)^2`` has a zero
gradient when satisfied.  :func:`projected_gradient_step` therefore

1. scales every constraint gradient (column of ``C_x``) and its value to unit gradient norm
   (so that each row of ``C_x^T dx = -C`` measures a violation in pixels) and drops the
   columns whose gradient is zero;
2. takes the SVD ``U S V^T`` of the scaled ``C_x`` and keeps singular values above
   ``rank_tolerance * s_max``.

``U_r U_r^T`` is then exactly ``C_x (C_x^T C_x)^+ C_x^T``, the orthogonal projector on the
span of the constraint gradients (column scaling does not change that span), and
``dx_B = -U_r S_r^{-1} V_r^T C`` is the minimum-norm least-squares solution of (A.1); when
``C_x`` has full column rank both equal the paper's formulas.  No inverse of a singular
matrix is ever formed, so there is no ``LinAlgError`` and no NaN; a per-kernel step limit of
one bandwidth guards against jumps.  After the column scaling every column of (12)-(13)'s
``C_x`` is ``+-1/sqrt(2)`` on two coordinates, so the scaled matrix is fixed by its sign
pattern; the SVD factors (projector and pseudo-inverse) of each pattern are computed once and
cached (a general matrix is factorised directly).

Speed.  :meth:`MultiKernelTracker.refine` quantises only its search region and evaluates all
kernels of the target per iteration in one call of
:meth:`mk_tracker.tracking.kernel_histograms.SearchRegion.evaluate` (numba-compiled by default, numpy
with ``backend="numpy"`` or ``MK_TRACKER_NO_NUMBA=1``; both give the same results, tested).
The iteration of Algorithm 1 is sensitive to rounding: the two backends (or a first box moved
by 1e-9 px) give the same boxes for the first few to few tens of frames, then can drift apart
by pixels on sequences where the iteration does not settle within ``T`` steps; the benchmark
centre errors of both stay within the spread such 1e-9 px moves cause
(docs/profile_multi_kernel.md).

Constraint thresholds.  The paper sets ``eps_C`` per constraint "in the range 0.05 to 9
depending on the object size".  Here a single pixel tolerance ``e`` (``constraint_tolerance_px``)
is turned into each constraint's threshold ``((L + e)^2 - L^2) / (L^2 + 1)``, i.e. a kernel
pair may be ``e`` pixels off its initial offset, which is size dependent in the same way.

Cost threshold (deviation).  The paper stops Algorithm 1 once ``J < eps_J = 0.7 N``.  With
the K-L cost computed here (smoothed histograms, 512 HSV bins) a well-placed kernel has
``J_i ~ 0.01-0.05`` and a kernel 5-10 px off its target still has ``J_i < 0.3``, so
``0.7 N`` ends the iteration before the first step and the tracker does not follow the target
(docs/benchmark_single_target.md shows the ``eps_J = 0.7N`` row).  The default
``epsilon_j_factor`` is therefore 0 (iterate until ``T`` or until no kernel moves more than
``min_step_px``); :func:`paper_config` returns the paper's 0.7.

Model and scale gates (deviations, measured in docs/benchmark_single_target.md).  The paper
updates model and scale when the mean kernel similarity exceeds 0.3 and gives no blend rate.
Here a kernel's model is blended with rate ``model_update_rate`` (default 0: even 0.02 let
the models absorb background and drift), and only kernels whose own similarity is above the
gate are blended.  The scale (9)-(11) is updated only when the *minimum* kernel similarity
exceeds ``scale_similarity_gate`` = 0.8: with the paper's mean > 0.3, an occluded kernel
(ellipse edge covered by an occluder) biases ``r(h)`` and the box shrank or grew by the
5 %/frame limit until the target was lost.  :func:`paper_config` restores the paper's gates.

State and mutation.  :meth:`MultiKernelTracker.refine` *mutates* the :class:`TargetState` it
is given: on success the kernel centres move to the result; the scale and the models change
only above the gates described above.  When the result is ``lost`` the
state's kernels, scale and models are left as they were (only ``state.lost`` and
``state.similarity`` change).  Use :meth:`TargetState.copy` to refine without side effects.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field, replace
from itertools import combinations

import numpy as np

from mk_tracker.boxes import BoxLike, InvalidBoxError, as_box, clip_box
from mk_tracker.tracking.kernel_histograms import (  # noqa: F401  (evaluate_kernel: re-exported)
    COLOUR_SPACES, PIXEL_WEIGHTINGS, PROFILES, InvalidImageError, KernelBackendError,
    KernelBatch, SearchRegion, check_image, compiled_kernels, evaluate_kernel, number_of_bins,
    quantize_region, resolve_backend)
from mk_tracker.tracking.kernel_layouts import SUPPORTED_KERNEL_COUNTS, kernel_layout, kernels_bounding_box
from mk_tracker.parameters import parameter, validate_config


class TrackingInputError(ValueError):
    """A box or image given to the tracker cannot be used (empty, outside, NaN, uniform)."""


@dataclass(frozen=True)
class MultiKernelConfig:
    """Parameters of the multiple-kernel tracker; defaults are the paper's values (Sec. IV-A)."""

    num_kernels: int = parameter(
        2, "Kernels per target (1 = single-kernel mean shift; 2/4 Fig. 4; 5/6 Fig. 14)",
        choices=SUPPORTED_KERNEL_COUNTS)
    colour_space: str = parameter("hsv", "Colour space of the histograms (Sec. IV-A: HSV)",
                                  choices=COLOUR_SPACES)
    hue_bins: int = parameter(16, "Histogram bins along hue (or blue for bgr)",
                              minimum=1, maximum=180)
    saturation_bins: int = parameter(8, "Histogram bins along saturation (or green)",
                                     minimum=1, maximum=256)
    value_bins: int = parameter(4, "Histogram bins along value (or red)",
                                minimum=1, maximum=256)
    profile: str = parameter("roof", "Kernel profile k: roof (piecewise linear, g constant, "
                             "Sec. V-A) or truncated gaussian", choices=PROFILES)
    pixel_weighting: str = parameter(
        "kl", "Pixel weights of the mean shift: q/p for the K-L cost (Appendix C) or "
        "sqrt(q/p) (Bhattacharyya, Comaniciu et al.)", choices=PIXEL_WEIGHTINGS)
    histogram_epsilon: float = parameter(
        0.01, "Mass eps mixed uniformly into candidate histograms, (1-eps)p + eps/m, so the "
        "K-L cost stays finite", minimum=1e-9, maximum=0.5)
    max_iterations: int = parameter(5, "T, the iteration limit of Algorithm 1",
                                    minimum=1, maximum=100)
    epsilon_j_factor: float = parameter(
        0.0, "eps_J = factor * N: Algorithm 1 stops when J < eps_J and |C| < eps_C (paper: "
        "0.7; with these K-L values that stops before the first step, see module docs)",
        minimum=0.0, maximum=100.0)
    constraint_tolerance_px: float = parameter(
        1.0, "Pixel tolerance e giving each constraint's eps_C = ((L+e)^2-L^2)/(L^2+1)",
        minimum=0.0, maximum=100.0)
    alpha: float = parameter(1.0, "Step size alpha of (5)/(8)", minimum=0.0, maximum=10.0)
    use_projected_gradient: bool = parameter(
        True, "Keep C_x(C_x^T C_x)^+ C_x^T in dx_A; False is the 'without projected "
        "gradient' ablation of Table II")
    adaptive_weights: bool = parameter(
        True, "Weights W_i proportional to sim_i, summing to N (7)-(8); False: W = I")
    scale_update: bool = parameter(True, "Update the scale with (9)-(11)")
    beta: float = parameter(9e3, "beta of (10), gain of the scale change", minimum=0.0)
    similarity_gate: float = parameter(
        0.3, "Model and scale are updated only when the mean kernel similarity exceeds this",
        minimum=0.0, maximum=1.0)
    scale_gate_statistic: str = parameter(
        "min", "Kernel similarity statistic compared with scale_similarity_gate before a scale "
        "update: min (default: no update while any kernel is occluded) or mean (paper)",
        choices=("mean", "min"))
    scale_similarity_gate: float = parameter(
        0.8, "The scale is updated only when the statistic above exceeds this (paper: the "
        "mean above 0.3, which let occluded kernels inflate or shrink the box)",
        minimum=0.0, maximum=1.0)
    verify_scale_step: bool = parameter(
        True, "Keep a scale step of (10)-(11) only if it does not raise the cost (7) (not in "
        "the paper; rejects steps biased by occluded kernel rims)")
    max_scale_change: float = parameter(
        0.05, "Largest |Delta s| per frame (not in the paper; bounds a noisy (10))",
        minimum=0.0, maximum=1.0)
    min_scale: float = parameter(0.25, "Smallest scale relative to the first box",
                                 minimum=0.01, maximum=1.0)
    max_scale: float = parameter(4.0, "Largest scale relative to the first box",
                                 minimum=1.0, maximum=100.0)
    model_update_rate: float = parameter(
        0.0, "Blend rate of a kernel's model towards its current candidate when above the "
        "gate (the paper gives no rate; 0, the default, keeps the first frame's models: "
        "0.02 and 0.1 drifted onto the background in docs/benchmark_single_target.md)",
        minimum=0.0, maximum=1.0)
    lost_similarity: float = parameter(
        0.1, "A result whose mean kernel similarity is below this is reported lost",
        minimum=0.0, maximum=1.0)
    search_margin: float = parameter(
        0.5, "Search region = box at the start position grown by this fraction of its size "
        "on every side; no pixel outside it is read", minimum=0.05, maximum=5.0)
    min_step_px: float = parameter(
        0.25, "Stop iterating when no kernel moves more than this (Comaniciu's epsilon; "
        "0 disables)", minimum=0.0, maximum=10.0)
    max_step_fraction: float = parameter(
        1.0, "Largest move of a kernel per iteration, as a fraction of its half-axes",
        minimum=0.01, maximum=10.0)
    max_kernel_pixels: int = parameter(
        1500, "Kernels covering more pixels are sampled on a regular grid of stride "
        "ceil(sqrt(area / this)) (speed; not in the paper)", minimum=50, maximum=10**7)
    rank_tolerance: float = parameter(
        1e-6, "Singular values of the scaled C_x below this times the largest are dropped",
        minimum=1e-15, maximum=0.1)

    @property
    def bins(self) -> tuple[int, int, int]:
        return (self.hue_bins, self.saturation_bins, self.value_bins)


def paper_config(**overrides) -> MultiKernelConfig:
    """Every constant as printed in Sec. IV-A: eps_J = 0.7 N, model and scale updated when the
    mean similarity exceeds 0.3 (the model replaced by the current candidate)."""
    base = dict(epsilon_j_factor=0.7, scale_gate_statistic="mean", scale_similarity_gate=0.3,
                model_update_rate=1.0)
    base.update(overrides)
    return MultiKernelConfig(**base)


def mean_shift_baseline_config(**overrides) -> MultiKernelConfig:
    """Single-kernel mean shift of Comaniciu, Ramesh and Meer (the paper's baseline [2]).

    One kernel, Bhattacharyya pixel weights ``sqrt(q/p)``, iterate until the step is below
    ``min_step_px`` (no cost threshold), no adaptive weights (meaningless with one kernel) and
    no scale update.
    """
    base = dict(num_kernels=1, pixel_weighting="bhattacharyya", epsilon_j_factor=0.0,
                max_iterations=20, adaptive_weights=False, scale_update=False)
    base.update(overrides)
    return MultiKernelConfig(**base)


# --------------------------------------------------------------------------------------------
# Constraints (12)-(13) and the projected-gradient step (5)/(8)
# --------------------------------------------------------------------------------------------

def kernel_pairs(num_kernels: int) -> np.ndarray:
    """All pairs ``(i, j)``, ``i < j``, shape ``(N(N-1)/2, 2)``; each gives two constraints."""
    pairs = list(combinations(range(num_kernels), 2))
    return np.array(pairs, dtype=np.int64).reshape(-1, 2)


def pair_distances(centres: np.ndarray, pairs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``L_x`` and ``L_y`` of every pair that make (12)-(13) zero at ``centres``."""
    c = np.asarray(centres, dtype=np.float64)
    d = c[pairs[:, 0]] - c[pairs[:, 1]]
    return np.abs(d[:, 0]), np.abs(d[:, 1])


def _pair_offsets(centres: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """``(x_i - x_j, y_i - y_j)`` of every pair, shape ``(P, 2)``."""
    c = np.asarray(centres, dtype=np.float64)
    return c[pairs[:, 0]] - c[pairs[:, 1]]


def constraint_values(centres: np.ndarray, pairs: np.ndarray, lx: np.ndarray, ly: np.ndarray
                      ) -> np.ndarray:
    """``C(x)``, shape ``(2P,)``: for pair ``p`` entry ``2p`` is (12), ``2p+1`` is (13).

    ``c_1 = ((x_i - x_j)^2 - L_x^2) / (L_x^2 + 1)``, ``c_2`` likewise in y.
    """
    l2 = np.stack([lx, ly], axis=1) ** 2
    return ((_pair_offsets(centres, pairs) ** 2 - l2) / (l2 + 1.0)).reshape(-1)


_JACOBIAN_INDEX: dict = {}


def constraint_jacobian(centres: np.ndarray, pairs: np.ndarray, lx: np.ndarray, ly: np.ndarray
                        ) -> np.ndarray:
    """``C_x``, shape ``(n, m) = (2N, 2P)``: column ``k`` is the gradient of constraint ``k``.

    Column ``2p`` (``2p+1``) holds ``+-2 (x_i - x_j) / (L_x^2 + 1)`` (y likewise) in the rows
    of ``x_i`` and ``x_j`` (``y_i``, ``y_j``).
    """
    n = 2 * np.shape(centres)[0]
    key = (n, pairs.tobytes())
    index = _JACOBIAN_INDEX.get(key)
    if index is None:
        within = np.array([0, 1])
        index = ((2 * pairs[:, 0:1] + within).reshape(-1),
                 (2 * pairs[:, 1:2] + within).reshape(-1), np.arange(2 * len(pairs)))
        if len(_JACOBIAN_INDEX) > 64:
            _JACOBIAN_INDEX.clear()
        _JACOBIAN_INDEX[key] = index
    rows_i, rows_j, cols = index
    grad = (2.0 * _pair_offsets(centres, pairs) /
            (np.stack([lx, ly], axis=1) ** 2 + 1.0)).reshape(-1)
    jac = np.zeros((n, cols.size))
    jac[rows_i, cols] = grad
    jac[rows_j, cols] = -grad
    return jac


def constraint_thresholds(lx: np.ndarray, ly: np.ndarray, tolerance_px: float) -> np.ndarray:
    """``eps_C`` per constraint: the value of (12)/(13) when a pair is ``e`` px off its L."""
    e = float(tolerance_px)
    out = np.empty(2 * len(lx))
    out[0::2] = ((lx + e) ** 2 - lx ** 2) / (lx ** 2 + 1.0)
    out[1::2] = ((ly + e) ** 2 - ly ** 2) / (ly ** 2 + 1.0)
    return out


def constraint_projector(jac: np.ndarray, values: np.ndarray, rank_tolerance: float = 1e-6
                         ) -> tuple[np.ndarray, np.ndarray]:
    """``Pi = C_x (C_x^T C_x)^+ C_x^T`` and ``dx_B = -C_x (C_x^T C_x)^+ C(x)``, rank-safe.

    See the module docstring: columns are scaled to unit norm (zero columns dropped), then
    an SVD with relative tolerance ``rank_tolerance`` gives the projector on their span and
    the minimum-norm least-squares ``dx_B`` of (A.1).
    """
    n = jac.shape[0]
    if jac.size == 0:
        return np.zeros((n, n)), np.zeros(n)
    norms = np.sqrt(np.sum(jac * jac, axis=0))
    scale = max(float(norms.max()), 1.0)
    keep = norms > 1e-12 * scale
    if not np.any(keep):
        return np.zeros((n, n)), np.zeros(n)
    a = jac[:, keep] / norms[keep]
    b = values[keep] / norms[keep]
    proj, pinv = _scaled_factors(a, rank_tolerance)
    return proj, -(pinv @ b)


_FACTORS: dict = {}
_FACTORS_LIMIT = 4096


def _svd_factors(a: np.ndarray, rank_tolerance: float) -> tuple[np.ndarray, np.ndarray]:
    """``(U_r U_r^T, U_r S_r^{-1} V_r^T)`` of ``a``: the projector on its column span and
    ``(a^T)^+``, from the SVD with relative tolerance ``rank_tolerance``."""
    u, s, vt = np.linalg.svd(a, full_matrices=False)
    r = s > rank_tolerance * s[0]
    ur = u[:, r]
    return ur @ ur.T, ur @ (vt[r] / s[r][:, None])


def _scaled_factors(a: np.ndarray, rank_tolerance: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_svd_factors` of the column-scaled ``C_x``, cached.

    Every column of (12)-(13)'s ``C_x`` has two entries ``+-2 d / (L^2 + 1)`` (or one), so
    after scaling to unit norm it is ``+-1/sqrt(2)`` (or ``+-1``) on two (one) coordinates:
    the scaled matrix is fixed by its sign pattern, of which a tracker meets only a handful.
    When ``a`` equals that canonical matrix to rounding, the factors of the canonical matrix
    (computed once by the same SVD) are returned; any other matrix is factorised directly.
    """
    sign = np.sign(a)
    canonical = sign / np.sqrt(np.count_nonzero(sign, axis=0))
    if not np.max(np.abs(a - canonical)) <= 1e-14:
        return _svd_factors(a, rank_tolerance)
    key = (sign.shape, sign.astype(np.int8).tobytes(), float(rank_tolerance))
    factors = _FACTORS.get(key)
    if factors is None:
        if len(_FACTORS) >= _FACTORS_LIMIT:
            _FACTORS.clear()
        factors = _svd_factors(canonical, rank_tolerance)
        for f in factors:
            f.setflags(write=False)
        _FACTORS[key] = factors
    return factors


def projected_gradient_step(jx: np.ndarray, jac: np.ndarray, values: np.ndarray,
                            weights: np.ndarray | None = None, alpha: float = 1.0,
                            use_projected_gradient: bool = True,
                            rank_tolerance: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """``(dx_A, dx_B)`` of (8) (of (5) when ``weights`` is None).

    ``jx`` is ``J_x`` (length ``n = 2N``), ``jac`` is ``C_x`` (``n x m``), ``values`` is
    ``C(x)``, ``weights`` the kernel weights ``W_i`` (length ``N``).  With
    ``use_projected_gradient=False`` the projector is dropped from ``dx_A`` (Table II
    ablation): ``dx_A = -alpha W J_x``; ``dx_B`` is unchanged.
    """
    jx = np.asarray(jx, dtype=np.float64)
    if weights is not None:
        jx = np.repeat(np.asarray(weights, dtype=np.float64), 2) * jx
    proj, dx_b = constraint_projector(jac, values, rank_tolerance)
    if use_projected_gradient:
        dx_a = alpha * (proj @ jx - jx)
    else:
        dx_a = -alpha * jx
    return dx_a, dx_b


def _constrained_step_loops(x, pairs, lx, ly, jx, weights, alpha, use_projected_gradient,
                            values, dx_a, dx_b):
    """``C(x)``, ``dx_A`` and ``dx_B`` of (8) for the constraints (12)-(13) in closed form
    (compiled with numba; :func:`projected_gradient_step` on :func:`constraint_jacobian` is
    the reference and the two agree to rounding, tested).

    The scaled ``C_x`` of :func:`constraint_projector` has, per coordinate axis, one column
    ``+-(e_i - e_j)/sqrt(2)`` for every pair whose gradient is kept: the incidence matrix of a
    graph on the kernels.  The projector on its span is ``I`` minus the averaging over each
    connected component, so ``dx_A = -alpha`` times the component mean of ``W J_x`` (the
    kernels of a component move together); ``dx_B``, the
    minimum-norm least-squares solution of (A.1), solves the graph Laplacian system
    ``L dx = B t`` with per-pair Newton steps ``t = -c / c'`` and zero mean per component
    (``(L + sum_C 1_C 1_C^T) dx = B t``, Cholesky).  Singular values of such a matrix are 0 or
    at least 0.2 times the largest for up to 6 kernels, so ``rank_tolerance <= 0.1`` cuts
    exactly the zero ones, as the SVD does.
    """
    n_k = x.shape[0]
    n_p = pairs.shape[0]
    grad = np.zeros((n_p, 2))
    largest = 0.0
    for p in range(n_p):
        i = pairs[p, 0]
        j = pairs[p, 1]
        for a in range(2):
            length = lx[p] if a == 0 else ly[p]
            l2 = length * length
            d = x[i, a] - x[j, a]
            values[2 * p + a] = (d * d - l2) / (l2 + 1.0)
            g = 2.0 * d / (l2 + 1.0)
            grad[p, a] = g
            largest = max(largest, np.sqrt(g * g + g * g))
    threshold = 1e-12 * max(largest, 1.0)
    label = np.empty(n_k, dtype=np.int64)
    size = np.empty(n_k)
    mean = np.empty(n_k)
    mat = np.empty((n_k, n_k))
    rhs = np.empty(n_k)
    for a in range(2):
        # connected components of the kept pairs (labels by repeated relaxation)
        for i in range(n_k):
            label[i] = i
        changed = True
        while changed:
            changed = False
            for p in range(n_p):
                g = grad[p, a]
                if not np.sqrt(g * g + g * g) > threshold:
                    continue
                i = pairs[p, 0]
                j = pairs[p, 1]
                lo = min(label[i], label[j])
                if label[i] != lo or label[j] != lo:
                    label[i] = lo
                    label[j] = lo
                    changed = True
        for i in range(n_k):
            size[i] = 0.0
            mean[i] = 0.0
        for i in range(n_k):
            size[label[i]] += 1.0
            mean[label[i]] += weights[i] * jx[2 * i + a]
        for i in range(n_k):
            wj = weights[i] * jx[2 * i + a]
            if use_projected_gradient:       # the common translation of the component
                dx_a[2 * i + a] = -alpha * (mean[label[i]] / size[label[i]])
            else:
                dx_a[2 * i + a] = -alpha * wj
        # (L + sum_C 1_C 1_C^T) dx = B t
        for i in range(n_k):
            rhs[i] = 0.0
            for j in range(n_k):
                mat[i, j] = 1.0 if label[i] == label[j] else 0.0
        for p in range(n_p):
            g = grad[p, a]
            if not np.sqrt(g * g + g * g) > threshold:
                continue
            i = pairs[p, 0]
            j = pairs[p, 1]
            t = -values[2 * p + a] / g
            mat[i, i] += 1.0
            mat[j, j] += 1.0
            mat[i, j] -= 1.0
            mat[j, i] -= 1.0
            rhs[i] += t
            rhs[j] -= t
        # Cholesky of the symmetric positive definite matrix, in place (lower triangle)
        for j in range(n_k):
            acc = mat[j, j]
            for k in range(j):
                acc -= mat[j, k] * mat[j, k]
            mat[j, j] = np.sqrt(acc)
            for i in range(j + 1, n_k):
                acc = mat[i, j]
                for k in range(j):
                    acc -= mat[i, k] * mat[j, k]
                mat[i, j] = acc / mat[j, j]
        for i in range(n_k):
            acc = rhs[i]
            for k in range(i):
                acc -= mat[i, k] * rhs[k]
            rhs[i] = acc / mat[i, i]
        for i in range(n_k - 1, -1, -1):
            acc = rhs[i]
            for k in range(i + 1, n_k):
                acc -= mat[k, i] * rhs[k]
            rhs[i] = acc / mat[i, i]
        for i in range(n_k):
            dx_b[2 * i + a] = rhs[i]
    return values


_COMPILED_STEP: list = []


def _compiled_step():
    """:func:`_constrained_step_loops` compiled with numba, or None (no numba, or
    ``MK_TRACKER_NO_NUMBA``; the same switch as :mod:`mk_tracker.tracking.kernel_histograms`)."""
    if not _COMPILED_STEP:
        if compiled_kernels() is None:
            _COMPILED_STEP.append(None)
        else:
            import numba
            step = numba.njit(cache=True, nogil=True)(_constrained_step_loops)
            # compile (or load from the disk cache) now rather than on a node's first frame
            step(np.array([[0.0, 0.0], [1.0, 2.0]]), kernel_pairs(2), np.ones(1), np.ones(1),
                 np.zeros(4), np.ones(2), 1.0, True, np.zeros(2), np.zeros(4), np.zeros(4))
            _COMPILED_STEP.append(step)
    return _COMPILED_STEP[0]


#: Statistics of the kernel similarities that say how well a target is seen (see
#: :func:`visibility_similarity`).
VISIBILITY_STATISTICS = ("mean", "weighted")


def visibility_similarity(similarities: np.ndarray, weights: np.ndarray | None = None,
                          statistic: str = "mean") -> float:
    """How well a target is seen, from its kernel similarities ``rho_i = exp(-J_i)``.

    ``"mean"``: ``sum_i rho_i / N``, the plain mean (the mean similarity of (5)).
    ``"weighted"``: ``sum_i W_i rho_i / N`` with the adaptive weights ``W_i`` of (7)-(8)
    (``W_i = N rho_i / sum_j rho_j``, so this is ``sum rho_i^2 / sum rho_i``); ``weights``
    defaults to those.  One occluded kernel (``rho ~ 0``) halves the plain mean of two
    kernels but hardly changes the weighted one, which follows the kernels that still see
    the target; with every kernel occluded both are low.  NaN similarities count as 0.
    Raises ``ValueError`` for an unknown statistic or mismatched shapes.
    """
    if statistic not in VISIBILITY_STATISTICS:
        raise ValueError(f"visibility statistic must be one of {VISIBILITY_STATISTICS}, "
                         f"got {statistic!r}")
    s = np.asarray(similarities, dtype=np.float64).reshape(-1)
    if s.size == 0:
        raise ValueError("no kernel similarities")
    s = np.where(np.isfinite(s), s, 0.0)
    if statistic == "mean":
        return float(s.mean())
    w = adaptive_weights(s) if weights is None else \
        np.asarray(weights, dtype=np.float64).reshape(-1)
    if w.shape != s.shape:
        raise ValueError(f"{w.size} weights for {s.size} kernel similarities")
    return float(np.sum(w * s) / s.size)


def adaptive_weights(similarities: np.ndarray) -> np.ndarray:
    """``W_i ~ sim_i`` normalised to sum ``N`` (7)-(8); uniform when every sim is 0."""
    s = np.asarray(similarities, dtype=np.float64)
    total = float(s.sum())
    if not total > 0:
        return np.ones_like(s)
    return s * (s.size / total)


# --------------------------------------------------------------------------------------------
# Per-target state and results
# --------------------------------------------------------------------------------------------

@dataclass
class TargetState:
    """Everything one target carries between frames.

    ``centres`` are the kernel centres (N, 2); the kernel half-axes are
    ``base_half_axes * scale``; the pair distances of (12)-(13) are ``base_lx * scale`` and
    ``base_ly * scale``; ``models`` are the target histograms ``q_i`` (N, m).
    """

    centres: np.ndarray
    base_half_axes: np.ndarray
    scale: float
    models: np.ndarray
    base_lx: np.ndarray
    base_ly: np.ndarray
    pairs: np.ndarray
    similarity: float = 1.0
    lost: bool = False
    frames: int = 0

    @property
    def num_kernels(self) -> int:
        return int(self.centres.shape[0])

    @property
    def half_axes(self) -> np.ndarray:
        return self.base_half_axes * self.scale

    @property
    def box(self) -> tuple[float, float, float, float]:
        """Bounding box of the kernels' extremes, eq. (14)."""
        return kernels_bounding_box(self.centres, self.half_axes)

    @property
    def center(self) -> np.ndarray:
        """Centroid ``((x_min + x_max)/2, (y_min + y_max)/2)`` of eq. (14)."""
        x, y, w, h = self.box
        return np.array([x + w / 2.0, y + h / 2.0])

    def copy(self) -> "TargetState":
        return copy.deepcopy(self)


@dataclass
class RefinementResult:
    """Outcome of one :meth:`MultiKernelTracker.refine`.

    ``box`` is (x, y, w, h) from the kernels' extremes (14), ``center`` its centroid;
    ``similarity`` the mean of ``kernel_similarities`` (each ``exp(-J_i)`` in [0, 1]);
    ``weights`` the adaptive W_i (``weighted_similarity`` = ``sum_i W_i rho_i / N``); ``kernel_centres``/``kernel_axes`` the ellipses for drawing;
    ``lost`` with ``reason`` ("" when tracked, else "outside_image", "nan_pixels" or
    "low_similarity").
    """

    box: tuple[float, float, float, float]
    center: tuple[float, float]
    similarity: float
    kernel_similarities: np.ndarray
    weights: np.ndarray
    kernel_centres: np.ndarray
    kernel_axes: np.ndarray
    iterations: int
    lost: bool
    reason: str = ""
    cost: float = float("nan")
    scale: float = 1.0
    cost_history: list = field(default_factory=list)

    @property
    def weighted_similarity(self) -> float:
        """``sum_i W_i rho_i / N`` (:func:`visibility_similarity`, ``"weighted"``)."""
        return visibility_similarity(self.kernel_similarities, self.weights, "weighted")


# --------------------------------------------------------------------------------------------
# The tracker
# --------------------------------------------------------------------------------------------

def _checked_image(image: np.ndarray) -> np.ndarray:
    try:
        return check_image(image)
    except InvalidImageError as exc:
        raise TrackingInputError(str(exc)) from exc


def _region(box: tuple[float, float, float, float], margin: float, width: int, height: int
            ) -> tuple[int, int, int, int] | None:
    """Integer search region ``(x0, y0, x1, y1)`` of ``box`` grown by ``margin``, clipped."""
    x, y, w, h = box
    grown = (x - margin * w, y - margin * h, w * (1 + 2 * margin), h * (1 + 2 * margin))
    clipped = clip_box(grown, width, height)
    if clipped is None:
        return None
    cx, cy, cw, ch = clipped
    x0, y0 = int(np.floor(cx)), int(np.floor(cy))
    x1, y1 = int(np.ceil(cx + cw)), int(np.ceil(cy + ch))
    if x1 <= x0 or y1 <= y0:
        return None
    return x0, y0, x1, y1


class MultiKernelTracker:
    """The projected-gradient multiple-kernel tracker; holds only its configuration.

    Targets are :class:`TargetState` objects created by :meth:`start`, so one tracker serves
    any number of targets.  ``backend`` selects the kernel evaluation: ``"auto"`` (compiled
    when numba is available), ``"compiled"`` or ``"numpy"`` (the reference); an unknown or
    unavailable backend raises :class:`TrackingInputError`.
    """

    def __init__(self, config: MultiKernelConfig | None = None, backend: str = "auto"):
        self.config = config if config is not None else MultiKernelConfig()
        validate_config(self.config)
        self.n_bins = number_of_bins(self.config.bins)
        try:
            self.backend = resolve_backend(backend)
        except KernelBackendError as exc:
            raise TrackingInputError(str(exc)) from exc
        if self.backend == "compiled":
            _compiled_step()        # compiled (or loaded) with the tracker, not on a frame

    # -- helpers ---------------------------------------------------------------------------
    def _stride(self, axes: np.ndarray) -> int:
        """Sampling stride so that no kernel holds much more than ``max_kernel_pixels``."""
        area = float(np.pi * np.max(axes[:, 0] * axes[:, 1]))
        return max(1, int(np.ceil(np.sqrt(area / self.config.max_kernel_pixels))))

    def _search_region(self, image: np.ndarray, region: tuple[int, int, int, int],
                       stride: int) -> SearchRegion | None:
        """The region's bin indices sampled every ``stride`` px on a grid fixed in the image,
        ready for kernel evaluations; None when the region holds NaN pixels."""
        cfg = self.config
        x0, y0, x1, y1 = region
        x0, y0 = (x0 // stride) * stride, (y0 // stride) * stride
        bins = quantize_region(image, (x0, y0, x1, y1), stride, cfg.colour_space, cfg.bins,
                               self.backend)
        if bins is None:
            return None
        return SearchRegion(bins, (x0, y0), stride, self.n_bins, cfg.profile, self.backend)

    def _evaluate(self, region: SearchRegion, axes: np.ndarray, centres: np.ndarray,
                  models: np.ndarray) -> KernelBatch:
        cfg = self.config
        return region.evaluate(axes, centres, models, cfg.histogram_epsilon,
                               cfg.pixel_weighting)

    # -- public API ------------------------------------------------------------------------
    def start(self, image_bgr: np.ndarray, box: BoxLike) -> TargetState:
        """Build a target from ``box`` (x, y, w, h) in ``image_bgr`` (H x W x 3 BGR).

        The kernels of the configured layout are placed in the box, each kernel's model is the
        histogram under it, and ``L_x``, ``L_y`` are set so (12)-(13) hold.  Raises
        :class:`TrackingInputError` for an empty, zero-area, non-finite or out-of-image box,
        a bad image, NaN pixels, a kernel with no pixel, or a uniform-colour target (its
        histogram puts everything in one bin, so there is nothing to track).
        """
        image = _checked_image(image_bgr)
        try:
            b = tuple(float(v) for v in as_box(box))
        except InvalidBoxError as exc:
            raise TrackingInputError(str(exc)) from exc
        height, width = image.shape[:2]
        if clip_box(b, width, height) is None:
            raise TrackingInputError(f"box {b} is entirely outside the {width}x{height} image")
        cfg = self.config
        centres, axes = kernel_layout(b, cfg.num_kernels)
        region = _region(b, 0.0, width, height)
        if region is None:
            raise TrackingInputError(f"box {b} covers no whole pixel of the image")
        stride = self._stride(axes)
        search = self._search_region(image, region, stride)
        if search is None:
            raise TrackingInputError("the target region holds NaN or infinite pixels")
        uniform = np.full((cfg.num_kernels, self.n_bins), 1.0 / self.n_bins)
        batch = self._evaluate(search, axes, centres, uniform)
        for i in np.flatnonzero(batch.n_pixels == 0):
            raise TrackingInputError(
                f"kernel {i} of box {b} has no pixel inside the image (box too small or "
                f"mostly outside)")
        models = batch.p.copy()
        if float(models.mean(axis=0).max()) >= 0.999:
            raise TrackingInputError(
                "the target has a uniform colour (one histogram bin holds all its mass); a "
                "colour-histogram tracker cannot localise it")
        pairs = kernel_pairs(cfg.num_kernels)
        lx, ly = pair_distances(centres, pairs)
        return TargetState(centres=centres, base_half_axes=axes, scale=1.0, models=models,
                           base_lx=lx, base_ly=ly, pairs=pairs, similarity=1.0)

    def refine(self, image_bgr: np.ndarray, state: TargetState,
               predicted_center: tuple[float, float] | np.ndarray | None = None
               ) -> RefinementResult:
        """Run Algorithm 1 on ``image_bgr`` for one target and update ``state``.

        The search starts from the state's kernels, translated so their centroid (14) is at
        ``predicted_center`` when given (Sec. IV-D: the Kalman prediction initialises the
        search; the result is the measurement).  Only pixels of the search region (the start
        box grown by ``search_margin``) are read.  See the module docstring for how the state
        is mutated.  Never raises for a bad frame: a target outside the image, NaN pixels or
        a similarity below ``lost_similarity`` give ``lost=True`` with a ``reason``; a badly
        shaped image raises :class:`TrackingInputError`.
        """
        cfg = self.config
        image = _checked_image(image_bgr)
        height, width = image.shape[:2]
        n_k = state.num_kernels
        axes = state.half_axes
        x = state.centres.astype(np.float64).copy()
        if predicted_center is not None:
            pc = np.asarray(predicted_center, dtype=np.float64).reshape(-1)
            if pc.shape != (2,) or not np.all(np.isfinite(pc)):
                raise TrackingInputError(f"predicted_center {predicted_center!r} is not two "
                                         f"finite numbers")
            x += pc - state.center
        start_box = kernels_bounding_box(x, axes)
        region = _region(start_box, cfg.search_margin, width, height)
        if region is None:
            return self._lost(state, x, axes, "outside_image")
        stride = self._stride(axes)
        search = self._search_region(image, region, stride)
        if search is None:
            return self._lost(state, x, axes, "nan_pixels")
        lo = np.array([region[0], region[1]], dtype=np.float64)
        hi = np.array([region[2], region[3]], dtype=np.float64)

        lx, ly = state.base_lx * state.scale, state.base_ly * state.scale
        eps_c = constraint_thresholds(lx, ly, cfg.constraint_tolerance_px)
        eps_j = cfg.epsilon_j_factor * n_k
        max_step = cfg.max_step_fraction * axes
        models = state.models

        # the compiled closed-form step (same results as the numpy functions, tested)
        step_loops = _compiled_step() if self.backend == "compiled" else None
        if step_loops is not None:
            c = np.empty(2 * len(state.pairs))
            dx_a, dx_b = np.empty(2 * n_k), np.empty(2 * n_k)
        ev = self._evaluate(search, axes, x, models)
        iterations = 0
        history = []
        for _ in range(cfg.max_iterations):
            w = adaptive_weights(ev.similarities) if cfg.adaptive_weights else np.ones(n_k)
            total = _weighted_cost(w, ev.costs)
            history.append(total)
            jx = -ev.mean_shift.reshape(-1)
            if step_loops is not None:
                step_loops(x, state.pairs, lx, ly, jx, w, cfg.alpha,
                           cfg.use_projected_gradient, c, dx_a, dx_b)
            else:
                c = constraint_values(x, state.pairs, lx, ly)
            c_ok = bool(np.all(np.abs(c) < eps_c))
            j_ok = total < eps_j
            if c_ok and j_ok:
                break
            if step_loops is None:
                jac = constraint_jacobian(x, state.pairs, lx, ly)
                dx_a, dx_b = projected_gradient_step(jx, jac, c, w, cfg.alpha,
                                                     cfg.use_projected_gradient,
                                                     cfg.rank_tolerance)
            if c_ok:
                dx = dx_a
            elif j_ok:
                dx = dx_b
            else:
                dx = dx_a + dx_b
            step = np.clip(dx.reshape(n_k, 2), -max_step, max_step)
            step[np.isnan(step)] = 0.0
            x = np.clip(x + step, lo, hi)
            iterations += 1
            ev = self._evaluate(search, axes, x, models)
            if float(np.abs(step).max()) < cfg.min_step_px:
                break

        sims = ev.similarities
        w = adaptive_weights(sims) if cfg.adaptive_weights else np.ones(n_k)
        total = _weighted_cost(w, ev.costs)
        mean_sim = float(sims.mean())
        if not mean_sim >= cfg.lost_similarity or mean_sim == 0.0:
            result = self._lost(state, x, axes, "low_similarity", sims, w)
            result.iterations = iterations
            return result

        state.centres = x
        state.similarity = mean_sim
        state.lost = False
        state.frames += 1
        if mean_sim > cfg.similarity_gate:
            if cfg.model_update_rate > 0:
                rate = cfg.model_update_rate
                for i in range(n_k):
                    if sims[i] > cfg.similarity_gate and ev.n_pixels[i] > 0:
                        state.models[i] = (1.0 - rate) * state.models[i] + rate * ev.p[i]
            scale_sim = mean_sim if cfg.scale_gate_statistic == "mean" else float(sims.min())
            if cfg.scale_update and cfg.beta > 0 and scale_sim > cfg.scale_similarity_gate:
                self._update_scale(search, state, w, ev)
        axes = state.half_axes
        box = kernels_bounding_box(state.centres, axes)
        return RefinementResult(box=box, center=(box[0] + box[2] / 2, box[1] + box[3] / 2),
                                similarity=mean_sim, kernel_similarities=sims, weights=w,
                                kernel_centres=state.centres.copy(), kernel_axes=axes.copy(),
                                iterations=iterations, lost=False, cost=total,
                                scale=state.scale, cost_history=history)

    def _update_scale(self, search: SearchRegion, state: TargetState, weights: np.ndarray,
                      ev: KernelBatch) -> None:
        """Eqs. (9)-(11): ``Delta s = beta r(h)``, ``s_t = s_{t-1}(1 + Delta s)``.

        ``r`` is the W-weighted mean of the kernels' ratios.  The kernels' offsets from the
        centroid (14) and the distances L are rescaled with the scale, so (12)-(13) still hold.
        With ``verify_scale_step`` the new scale is kept only if the weighted cost (7) of the
        rescaled kernels is not higher than at the old scale.
        """
        cfg = self.config
        r = float(np.sum(weights * ev.scale_ratios)) / len(ev.scale_ratios)
        ds = float(np.clip(cfg.beta * r, -cfg.max_scale_change, cfg.max_scale_change))
        new_scale = float(np.clip(state.scale * (1.0 + ds), cfg.min_scale, cfg.max_scale))
        if not np.isfinite(new_scale) or new_scale == state.scale:
            return
        ratio = new_scale / state.scale
        centroid = state.center
        centres = centroid + (state.centres - centroid) * ratio
        if cfg.verify_scale_step:
            trial = self._evaluate(search, state.base_half_axes * new_scale, centres,
                                   state.models)
            old_cost = float(np.sum(weights * ev.costs))
            new_cost = float(np.sum(weights * trial.costs))
            if not new_cost <= old_cost:
                return
        state.centres = centres
        state.scale = new_scale

    def _lost(self, state: TargetState, x: np.ndarray, axes: np.ndarray, reason: str,
              sims: np.ndarray | None = None, weights: np.ndarray | None = None
              ) -> RefinementResult:
        n_k = state.num_kernels
        sims = np.zeros(n_k) if sims is None else sims
        state.lost = True
        state.similarity = float(sims.mean())
        box = kernels_bounding_box(x, axes)
        return RefinementResult(box=box, center=(box[0] + box[2] / 2, box[1] + box[3] / 2),
                                similarity=float(sims.mean()), kernel_similarities=sims,
                                weights=np.ones(n_k) if weights is None else weights,
                                kernel_centres=x.copy(), kernel_axes=axes.copy(),
                                iterations=0, lost=True, reason=reason, scale=state.scale)

    def appearance_similarity(self, image_bgr: np.ndarray, state: TargetState, box: BoxLike
                              ) -> float:
        """Mean over kernels of ``exp(-J_i)`` for the state's layout placed in ``box``.

        In [0, 1]; 0 when the box is outside the image or its pixels are NaN.  Only the
        pixels of ``box`` are read; the state is not changed.  Raises
        :class:`TrackingInputError` for a non-finite or zero-area box or a bad image.
        """
        image = _checked_image(image_bgr)
        try:
            b = tuple(float(v) for v in as_box(box))
        except InvalidBoxError as exc:
            raise TrackingInputError(str(exc)) from exc
        height, width = image.shape[:2]
        region = _region(b, 0.0, width, height)
        if region is None:
            return 0.0
        centres, axes = kernel_layout(b, state.num_kernels)
        stride = self._stride(axes)
        search = self._search_region(image, region, stride)
        if search is None:
            return 0.0
        sims = self._evaluate(search, axes, centres, state.models).similarities
        return float(np.clip(np.mean(sims), 0.0, 1.0))


def _weighted_cost(weights: np.ndarray, costs: np.ndarray) -> float:
    """``J = sum_i W_i J_i`` of (7); a kernel without pixels (infinite cost) adds nothing."""
    return float(np.sum(weights * np.where(np.isfinite(costs), costs, 0.0)))


def with_overrides(config: MultiKernelConfig, **changes) -> MultiKernelConfig:
    """A validated copy of ``config`` with ``changes`` (e.g. ablation switches)."""
    out = replace(config, **changes)
    validate_config(out)
    return out
