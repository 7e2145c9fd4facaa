"""Constraints (12)-(13) of the kernel layout and the projected-gradient step (5)/(8) of
Chu, Hwang, Pai & Lan (IEEE TMM 2013), Sec. IV and Appendix A.

The ``N`` kernel centres of a target form ``x = [x_1 y_1 ... x_N y_N]^T``; every pair
``(i, j)`` keeps its initial offsets ``L_x``, ``L_y`` through the constraints (12)-(13)
(:func:`constraint_values`, gradients :func:`constraint_jacobian`).  One iteration of
Algorithm 1 moves ``x`` by

    dx_A = alpha (-I + C_x (C_x^T C_x)^+ C_x^T) W J_x,     dx_B = -C_x (C_x^T C_x)^+ C(x)

(:func:`projected_gradient_step`; (5) without the kernel weights ``W``, (8) with them):
``dx_A`` descends the cost along the constraint surface, ``dx_B`` (A.1) returns to it.
:mod:`mk_tracker.tracking.multi_kernel` runs the iteration.

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
matrix is ever formed, so there is no ``LinAlgError`` and no NaN (the tracker's
per-kernel step limit of one bandwidth guards against jumps).  After the column scaling
every column of (12)-(13)'s ``C_x`` is ``+-1/sqrt(2)`` on two coordinates, so the scaled
matrix is fixed by its sign pattern; the SVD factors (projector and pseudo-inverse) of each
pattern are computed once and cached (a general matrix is factorised directly).

Speed: :func:`_constrained_step_loops` computes ``C(x)``, ``dx_A`` and ``dx_B`` in closed form
for these constraints, compiled with numba (``nogil``) by :func:`_compiled_step` (same
switch as :mod:`mk_tracker.tracking.search_region`); the SVD path above is the
reference, and the two agree to rounding (tested).
"""

from __future__ import annotations

from itertools import combinations

import numpy as np

from mk_tracker.tracking.search_region import compiled_kernels

__all__ = ["kernel_pairs", "pair_distances", "constraint_values", "constraint_jacobian",
           "constraint_thresholds", "constraint_projector", "projected_gradient_step"]


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
    ``MK_TRACKER_NO_NUMBA``; the same switch as :mod:`mk_tracker.tracking.search_region`)."""
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
