"""Sparse factorization of kernel covariances by coordinate descent, Schizas et al. Sec. 3.2.

Problem (3.7), with ``R`` columns for several objects (Sec. 3.3)::

    min_M  ||Sigma - M M^T||_F^2 + lambda ||M||_1,      M in R^{p x R}

solved by cyclic coordinate descent (Algorithm 1): starting from ``M = 0``, every entry
``M(j, r) = h`` in turn is set to the exact minimiser of its 1-D cost (3.9), the others
fixed at their latest values (Gauss-Seidel)::

    J(h) = h^4 + c1 h^2 + c2 h + lambda |h|,
    c1 = 2 sum_{mu != j} M(mu, r)^2 - 2 Rr(j, j),   c2 = -4 sum_{mu != j} Rr(j, mu) M(mu, r),

where ``Rr = Sigma - sum_{r' != r} m_r' m_r'^T`` is the residual of the other columns (for
one column ``Rr = Sigma`` and this is exactly (3.9); the supplementary's (10.2) has a stray
``+ phi``).  The minimiser is 0, a positive real root of the cubic (3.10)
``4h^3 + 2 c1 h + c2 + lambda = 0`` or a negative real root of (3.11)
``4h^3 + 2 c1 h + c2 - lambda = 0`` (Appendix A/Sec. 10): we solve both cubics in closed
form (Cardano / trigonometric), polish each root with Newton steps, and keep the candidate of
least ``J`` (0 on ties, then the positive one, as Sec. 11 prescribes).  Because each step is
an exact coordinate minimisation, the cost (3.7) never increases.  Cycles stop after
``kappa`` cycles or once ``||M^k - M^{k-1}||_F <= epsilon`` (Algorithm 1, line 7).

Everything is vectorised over a batch of independent blocks (the divide-and-conquer of
Sec. 5.1): the Python loop runs over the ``p * R`` coordinates of a block, each iteration
updating that coordinate in all blocks at once.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mk_tracker.numba_support import import_numba, register_bit_casts


class FactorizationError(ValueError):
    """Inputs the factorization cannot use (shape, NaN, negative lambda)."""


def zero_factor_threshold(lam: float) -> float:
    """``T(lambda) = 3/2 (lambda/2)^(2/3)``: with all other entries 0, ``h = 0`` minimises
    ``h^4 - 2 s h^2 + lambda |h|`` iff ``s <= T(lambda)``.

    Proof: for ``h > 0`` the cost is ``h (h^3 - 2 s h + lambda)``; the bracket is smallest at
    ``h = sqrt(2s/3)`` where it equals ``lambda - 2 (2s/3)^(3/2)``, non-negative iff
    ``s <= 3/2 (lambda/2)^(2/3)``; ``h < 0`` is symmetric.
    """
    return 1.5 * (max(float(lam), 0.0) / 2.0) ** (2.0 / 3.0)


def coordinate_cost(h: np.ndarray, c1: np.ndarray, c2: np.ndarray, lam: float) -> np.ndarray:
    """The 1-D cost (3.9) ``h^4 + c1 h^2 + c2 h + lambda |h|`` (constants dropped)."""
    h2 = h * h
    return h2 * h2 + c1 * h2 + c2 * h + lam * np.abs(h)


#: Seed of :func:`cube_root`: dividing the bit pattern of a positive double by 3 divides
#: its exponent by 3 (and scales its mantissa bits); the bias ``1023`` then needs
#: ``1023 - 1023 / 3`` added back, less 0.033 (in units of the exponent's lowest bit) to
#: centre the linear mantissa's relative error (at most 3.2 %).  ``(715094163 << 32)`` is
#: ``(1023 - 1023 / 3 - 0.0330624) * 2^52`` rounded to the upper word.
_CUBE_ROOT_SEED = 715094163 << 32
#: Range of :func:`_cube_root`'s own arithmetic: there ``y^3``, ``y (y^3 + 2a)`` (about
#: ``a^(4/3)``) neither overflow nor underflow; beyond it, ``np.cbrt``.
_ROOT_LOW = 2.0 ** -600
_ROOT_HIGH = 2.0 ** 600


def _float_bits(x):
    """The IEEE-754 bit pattern of a double as an int64 (a bit cast when compiled:
    :func:`mk_tracker.numba_support.register_bit_casts`)."""
    return int(np.float64(x).view(np.int64))


def _bits_float(i):
    """The double whose bit pattern is the int64 ``i`` (a bit cast when compiled)."""
    return float(np.int64(i).view(np.float64))


def _cube_root(w):
    """Real cube root of a double, for the Cardano branch of :func:`_root_scalar`.

    The libm ``cbrt`` is an opaque call of about 20 ns, and Algorithm 1 takes one per
    coordinate step that needs a root (docs/profile_thermal_detector.md); this is the same
    root from arithmetic the compiler inlines: a seed from the bit pattern
    (:data:`_CUBE_ROOT_SEED`, relative error <= 3.2 %), then three Halley steps
    ``y <- y (y^3 + 2a) / (2 y^3 + a)`` for ``a = |w|`` (cubic convergence; largest
    relative error over 2e6 inputs 3.2e-2, 2.1e-5, 6.4e-15, 4.4e-16), within 3 units in the
    last place of ``cbrt``.  Cardano's root is then
    polished by a Newton step on the cubic, so these last bits do not matter.  Inputs with
    ``|w|`` outside ``[2^-600, 2^600]`` (where the steps could overflow or underflow; also
    zero, infinities and NaN) go to ``np.cbrt``.  :func:`cube_root` is the same
    arithmetic on arrays (bit for bit)."""
    a = abs(w)
    if not (a >= _ROOT_LOW and a <= _ROOT_HIGH):
        return np.cbrt(w)
    y = _bits_float(_float_bits(a) // 3 + _CUBE_ROOT_SEED)
    y3 = y * y * y
    y = y * (y3 + 2.0 * a) / (2.0 * y3 + a)
    y3 = y * y * y
    y = y * (y3 + 2.0 * a) / (2.0 * y3 + a)
    y3 = y * y * y
    y = y * (y3 + 2.0 * a) / (2.0 * y3 + a)
    return y if w > 0 else -y


def cube_root(w: np.ndarray) -> np.ndarray:
    """:func:`_cube_root` elementwise on a float64 array (the same operations, so the same
    bits as the compiled scalar)."""
    w = np.asarray(w, dtype=np.float64)
    a = np.abs(w)
    normal = (a >= _ROOT_LOW) & (a <= _ROOT_HIGH)
    a = np.where(normal, a, 1.0)
    y = (a.view(np.int64) // 3 + np.int64(_CUBE_ROOT_SEED)).view(np.float64)
    for _ in range(3):
        y3 = y * y * y
        y = y * (y3 + 2.0 * a) / (2.0 * y3 + a)
    y = np.where(w > 0, y, -y)
    with np.errstate(invalid="ignore"):
        return np.where(normal, y, np.cbrt(np.where(normal, 0.0, w)))


def largest_real_root(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Largest real root of ``y^3 + p y + q = 0``, vectorised (float64 arrays of one shape).

    One real root (discriminant ``D = (q/2)^2 + (p/3)^3 > 0``): Cardano in the form
    ``u - p/(3u)`` with ``u = cbrt(-q/2 - sign(q) sqrt(D))``, which avoids cancellation
    (the cube root of :func:`cube_root`, the one the compiled loops use).
    Three real roots (``D <= 0``, so ``p <= 0``): the trigonometric form
    ``2 sqrt(-p/3) cos(arccos(3q/(2p) sqrt(-3/p)) / 3)``.  One Newton step polishes it.
    """
    disc = 0.25 * q * q + (p * p * p) / 27.0
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        sq = np.sqrt(np.abs(disc))
        u = cube_root(np.where(q >= 0, -0.5 * q - sq, -0.5 * q + sq))
        card = np.where(u != 0, u - p / (3.0 * u), 0.0)
        m = np.sqrt(np.maximum(-p / 3.0, 0.0))
        arg = np.where(m > 0, -0.5 * q / (m * m * m), 0.0)
        trig = 2.0 * m * np.cos(np.arccos(np.clip(arg, -1.0, 1.0)) / 3.0)
        y = np.where(disc > 0, card, trig)
        fp = 3.0 * y * y + p
        step = (y * y * y + p * y + q) / fp
        y = np.where(np.abs(fp) > 1e-12 * (1.0 + np.abs(p)), y - step, y)
    return y


def coordinate_minimizer(c1: np.ndarray, c2: np.ndarray, lam: float) -> np.ndarray:
    """Exact minimiser of (3.9) ``h^4 + c1 h^2 + c2 h + lambda |h|`` for arrays c1, c2.

    Candidates (Appendix A): 0, the positive real roots of (3.10) and the negative real roots
    of (3.11).  Two facts cut them to one root:

    * ``J(h) - J(-h) = 2 c2 h``, so a minimiser has the sign of ``-c2`` (for ``c2 = 0`` both
      signs tie and the positive one is kept, as Sec. 11 prescribes).  With ``a = |c2|`` the
      problem is ``min_{y >= 0} y^4 + c1 y^2 - a y + lambda y`` and ``h = -sign(c2) y``;
    * on ``y > 0`` only the *largest* real root of ``y^3 + (c1/2) y + (lambda - a)/4`` can be
      a minimum: the roots of a depressed cubic sum to zero, so the smallest is <= 0, and the
      middle one is a maximum.

    The root is kept if it beats ``J(0) = 0`` (ties go to 0).  Most coordinates stay 0, and
    that is decided without the root: on ``y > 0``, ``J(y) = y (y^3 + c1 y + lambda - a)``
    and ``y^3 + c1 y`` has its minimum ``-2 t^(3/2)`` at ``y = sqrt(t)``, ``t = max(-c1/3, 0)``,
    so ``J >= 0`` there iff ``lambda - a >= 2 t^(3/2)``.
    """
    c1 = np.asarray(c1, dtype=np.float64)
    c2 = np.asarray(c2, dtype=np.float64)
    a = np.abs(c2)
    t = np.maximum(-c1 / 3.0, 0.0)
    zero = lam - a >= 2.0 * t * np.sqrt(t)
    y = largest_real_root(0.5 * c1, 0.25 * (lam - a))
    y = np.where((y > 0) & ~zero, y, 0.0)
    y2 = y * y
    cost = y2 * y2 + c1 * y2 - a * y + lam * y
    tiny = -1e-15 * (1.0 + np.abs(c1) + a)
    return np.where(cost < tiny, np.where(c2 > 0, -y, y), 0.0)


def factorization_cost(sigma: np.ndarray, m: np.ndarray, lam: float) -> np.ndarray:
    """Cost (3.7) ``||Sigma - M M^T||_F^2 + lambda ||M||_1`` per block.

    ``sigma``: ``(B, p, p)`` or ``(p, p)``; ``m``: ``(B, p, R)``/``(B, p)`` or ``(p, R)``/``(p,)``.
    """
    s = np.asarray(sigma, dtype=np.float64)
    mm = np.asarray(m, dtype=np.float64)
    single = s.ndim == 2
    if single:
        s = s[None]
        mm = mm[None]
    if mm.ndim == 2:
        mm = mm[:, :, None]
    resid = s - mm @ mm.transpose(0, 2, 1)
    cost = (resid ** 2).sum(axis=(1, 2)) + lam * np.abs(mm).sum(axis=(1, 2))
    return cost[0] if single else cost


@dataclass
class FactorizationResult:
    """Output of :func:`sparse_factorize`.

    ``factors``: ``(B, p, R)``; ``cycles``: cycles run per block; ``converged``: whether the
    epsilon rule stopped it; ``cost_history``: ``(B, cycles + 1)`` costs (3.7) when
    requested (NaN after a block stopped), else ``None``.
    """

    factors: np.ndarray
    cycles: np.ndarray
    converged: np.ndarray
    cost_history: np.ndarray | None = None

    def support(self) -> np.ndarray:
        """``(B, p)`` boolean: pixels with a nonzero entry in any column."""
        return np.any(self.factors != 0, axis=2)


def sparse_factorize(sigma: np.ndarray, lam: float, *, columns: int = 1,
                     max_cycles: int = 10, tol: float = 1e-3,
                     record_cost: bool = False, backend: str = "auto") -> FactorizationResult:
    """Algorithm 1 on a batch of kernel covariances ``(B, p, p)`` (or one ``(p, p)``).

    ``lam`` is lambda of (3.7), ``columns`` the number R of columns of M, ``max_cycles`` kappa,
    ``tol`` epsilon.  Starts from ``M = 0`` as Algorithm 1 does.  ``backend``: ``"numpy"``
    (coordinates in a Python loop, each vectorised over the blocks), ``"compiled"`` (the
    same arithmetic compiled with numba, ~50x faster on small batches) or ``"auto"``
    (compiled when numba is installed and no cost history is requested).
    """
    s = np.asarray(sigma, dtype=np.float64)
    if s.ndim == 2:
        s = s[None]
    if s.ndim != 3 or s.shape[1] != s.shape[2]:
        raise FactorizationError(f"sigma must be (B, p, p), got shape {np.shape(sigma)}")
    if not np.all(np.isfinite(s)):
        raise FactorizationError("sigma holds NaN or infinite values")
    lam = float(lam)
    if not np.isfinite(lam) or lam < 0:
        raise FactorizationError(f"lambda must be a finite non-negative number, got {lam!r}")
    if columns < 1 or max_cycles < 1 or not tol >= 0:
        raise FactorizationError("columns and max_cycles must be >= 1 and tol >= 0")
    if backend not in ("auto", "numpy", "compiled"):
        raise FactorizationError(f"unknown backend {backend!r}")
    if backend == "compiled" and _compiled_kernel() is None:
        raise FactorizationError("the compiled backend needs numba, which is not installed")
    use_compiled = backend == "compiled" or (backend == "auto" and not record_cost
                                             and _compiled_kernel() is not None)
    if use_compiled:
        kernel = _compiled_kernel()
        factors, cycles, converged = kernel(np.ascontiguousarray(s), lam, int(columns),
                                            int(max_cycles), float(tol))
        history = None
        if record_cost:
            history = np.full((s.shape[0], max_cycles + 1), np.nan)
            history[:, 0] = factorization_cost(s, np.zeros_like(factors), lam)
            history[np.arange(s.shape[0]), cycles] = factorization_cost(s, factors, lam)
        return FactorizationResult(factors, cycles, converged.astype(bool), history)
    return _factorize_numpy(s, lam, int(columns), int(max_cycles), float(tol), record_cost)


def _factorize_numpy(s: np.ndarray, lam: float, columns: int, max_cycles: int, tol: float,
                     record_cost: bool) -> FactorizationResult:
    """Reference implementation: Python loop over coordinates, numpy over blocks."""
    n_blocks, p, _ = s.shape
    n_cols = int(columns)
    factors = np.zeros((n_blocks, p, n_cols))
    cycles = np.zeros(n_blocks, dtype=np.int64)
    converged = np.zeros(n_blocks, dtype=bool)
    history = np.full((n_blocks, max_cycles + 1), np.nan) if record_cost else None
    if record_cost:
        history[:, 0] = factorization_cost(s, factors, lam)
    if n_blocks == 0 or p == 0:
        return FactorizationResult(factors, cycles, converged, history)

    active = np.arange(n_blocks)
    s_act = s
    diag_all = np.ascontiguousarray(np.diagonal(s, axis1=1, axis2=2))
    off_all = s.copy()
    idx = np.arange(p)
    off_all[:, idx, idx] = 0.0
    off_act = off_all
    diag_act = diag_all
    m = np.zeros((n_cols, n_blocks, p))          # column-major working copy: m[r] is (B, p)
    for cycle in range(1, max_cycles + 1):
        previous = m.copy()
        norms = (m * m).sum(axis=2)               # (R, B): sum_mu M(mu, r)^2
        gram = np.einsum("rbp,sbp->brs", m, m) if n_cols > 1 else None
        for j in range(p):
            row = off_act[:, j, :]                # (B, p) Sigma(j, mu), zero at mu = j
            for r in range(n_cols):
                mr = m[r]
                old = mr[:, j].copy()
                sum_sq = norms[r] - old * old
                rjj = diag_act[:, j].copy()
                cross = np.einsum("bp,bp->b", row, mr)
                if n_cols > 1:
                    for r2 in range(n_cols):
                        if r2 == r:
                            continue
                        mj2 = m[r2][:, j]
                        rjj -= mj2 * mj2
                        cross -= mj2 * (gram[:, r2, r] - mj2 * old)
                c1 = 2.0 * sum_sq - 2.0 * rjj
                c2 = -4.0 * cross
                new = coordinate_minimizer(c1, c2, lam)
                mr[:, j] = new
                norms[r] += new * new - old * old
                if n_cols > 1:
                    delta = new - old
                    for r2 in range(n_cols):
                        if r2 == r:
                            gram[:, r, r] += new * new - old * old
                        else:
                            upd = delta * m[r2][:, j]
                            gram[:, r, r2] += upd
                            gram[:, r2, r] += upd
        change = np.sqrt(((m - previous) ** 2).sum(axis=(0, 2)))
        factors[active] = m.transpose(1, 2, 0)
        cycles[active] = cycle
        if record_cost:
            history[active, cycle] = factorization_cost(s_act, m.transpose(1, 2, 0), lam)
        done = change <= tol
        converged[active[done]] = True
        if done.all():
            break
        keep = ~done
        active = active[keep]
        m = np.ascontiguousarray(m[:, keep, :])
        s_act = s_act[keep]
        off_act = off_act[keep]
        diag_act = diag_act[keep]
    return FactorizationResult(factors, cycles, converged, history)



# --- compiled backend -------------------------------------------------------------------
# Plain-Python scalar versions of largest_real_root / coordinate_minimizer and the cycle
# loop of _factorize_numpy, compiled with numba when it is installed (optional dependency).

def _trigonometric_root(p, q):
    """Largest root ``2 sqrt(-p/3) cos(arccos(3q/(2p) sqrt(-3/p)) / 3)`` of
    ``y^3 + p y + q`` when it has three real roots (before the Newton polish)."""
    m = np.sqrt(max(-p / 3.0, 0.0))
    arg = -0.5 * q / (m * m * m) if m > 0 else 0.0
    arg = min(1.0, max(-1.0, arg))
    return 2.0 * m * np.cos(np.arccos(arg) / 3.0)


def _root_scalar(p, q):
    disc = 0.25 * q * q + p * p * p / 27.0
    if disc > 0:
        sq = np.sqrt(disc)
        u = _cube_root(-0.5 * q - sq) if q >= 0 else _cube_root(-0.5 * q + sq)
        y = u - p / (3.0 * u) if u != 0 else 0.0
    else:
        y = _trigonometric_root(p, q)
    fp = 3.0 * y * y + p
    if abs(fp) > 1e-12 * (1.0 + abs(p)):
        y = y - (y * y * y + p * y + q) / fp
    return y

def _minimizer_scalar(c1, c2, lam):
    a = abs(c2)
    # J >= 0 = J(0) on y > 0 iff lam - a >= 2 t^(3/2), t = max(-c1/3, 0): no root needed
    if c1 >= 0.0:                             # t = 0 (the same comparison, without sqrt)
        if lam - a >= 0.0:
            return 0.0
    else:
        t = -c1 / 3.0
        if lam - a >= 2.0 * t * np.sqrt(t):
            return 0.0
    y = _root_scalar(0.5 * c1, 0.25 * (lam - a))
    if y <= 0:
        return 0.0
    y2 = y * y
    cost = y2 * y2 + c1 * y2 - a * y + lam * y
    if cost < -1e-15 * (1.0 + abs(c1) + a):
        return -y if c2 > 0 else y
    return 0.0


def _factorize_block(cols, m, sv, norms, gram, lam, n_cols, max_cycles, tol):
    """Algorithm 1 on one block.  ``cols`` ``(p, p)`` holds the *columns* of Sigma as rows
    (``cols[j, mu] = Sigma(mu, j)``, i.e. Sigma transposed; a symmetric Sigma can be passed
    as it is); factor ``m`` ``(p, R)`` (zeros on entry, the result on exit); ``sv``
    (``(R, p)``), ``norms``, ``gram`` are scratch arrays.  Returns ``(cycles, converged)``.
    The detector's fused per-block loop calls it as well.

    ``sv[r] = (Sigma M)[:, r]`` is kept up to date (a column update when an entry changes;
    most stay 0), so the sum ``sum_mu Sigma(j, mu) M(mu, r)`` of (3.9) is read, not
    recomputed.  Each update reads a column of Sigma, i.e. a contiguous row of ``cols``
    (same products and sums as reading Sigma column-wise, so the same values)."""
    if n_cols == 1:
        return _factorize_block_one_column(cols, m, sv, lam, max_cycles, tol)
    p = cols.shape[0]
    cycles = 0
    sv[:, :] = 0.0
    for cycle in range(1, max_cycles + 1):
        change = 0.0               # ||M^k - M^(k-1)||^2, summed as the entries change
        for r in range(n_cols):
            for r2 in range(n_cols):
                acc = 0.0
                for mu in range(p):
                    acc += m[mu, r] * m[mu, r2]
                gram[r, r2] = acc
            norms[r] = gram[r, r]
        for j in range(p):
            col = cols[j]
            sjj = col[j]
            for r in range(n_cols):
                old = m[j, r]
                rjj = sjj
                cross = sv[r, j] - sjj * old
                for r2 in range(n_cols):
                    if r2 != r:
                        mj2 = m[j, r2]
                        rjj -= mj2 * mj2
                        cross -= mj2 * (gram[r2, r] - mj2 * old)
                c1 = 2.0 * (norms[r] - old * old) - 2.0 * rjj
                c2 = -4.0 * cross
                new = _minimizer_scalar(c1, c2, lam)
                change += (new - old) * (new - old)
                if new != old:
                    m[j, r] = new
                    delta = new - old
                    svr = sv[r]
                    for mu in range(p):
                        svr[mu] += col[mu] * delta
                    norms[r] += new * new - old * old
                    gram[r, r] = norms[r]
                    for r2 in range(n_cols):
                        if r2 != r:
                            upd = (new - old) * m[j, r2]
                            gram[r, r2] += upd
                            gram[r2, r] += upd
        cycles = cycle
        if np.sqrt(change) <= tol:
            return cycles, True
    return cycles, False


def _factorize_block_one_column(cols, m, sv, lam, max_cycles, tol):
    """:func:`_factorize_block` for ``R = 1`` (the default): the same operations in the same
    order with the loops over other columns removed (they do nothing for one column)."""
    p = cols.shape[0]
    sv[:, :] = 0.0
    svr = sv[0]
    for cycle in range(1, max_cycles + 1):
        change = 0.0
        norm = 0.0
        for mu in range(p):
            norm += m[mu, 0] * m[mu, 0]
        for j in range(p):
            col = cols[j]
            sjj = col[j]
            old = m[j, 0]
            c1 = 2.0 * (norm - old * old) - 2.0 * sjj
            c2 = -4.0 * (svr[j] - sjj * old)
            new = _minimizer_scalar(c1, c2, lam)
            change += (new - old) * (new - old)
            if new != old:
                m[j, 0] = new
                delta = new - old
                for mu in range(p):
                    svr[mu] += col[mu] * delta
                norm += new * new - old * old
        if np.sqrt(change) <= tol:
            return cycle, True
    return max_cycles, False


def _factorize_blocks_one_column(cols, m, sv, n, lam, max_cycles, tol, norm, change, live,
                                 coef):
    """:func:`_factorize_block_one_column` on the first ``n`` blocks of ``cols`` ``(B, p, p)``
    at once, in lock step: coordinate ``j`` of every block not yet converged, then ``j + 1``.
    ``m`` ``(B, p)`` holds the factors (zeros on entry, the results on exit); ``sv``
    ``(B, p)``, ``norm``, ``change`` (``(B,)`` float), ``live`` (``(B,)`` int64) and ``coef``
    (``(5, B)`` float) are scratch arrays.

    Each block goes through exactly the operations of the one-block loop, in the same order
    (its own ``norm``, ``change`` and stopping test per cycle), so its factor is the same to
    the last bit; only the blocks are interleaved.  One block's coordinate descent is a
    chain of dependent steps (a coordinate's ``c1``, ``c2`` need the previous coordinate's
    root); the steps of independent blocks side by side let the processor overlap those
    latencies (docs/profile_thermal_detector.md, "Lock-step factorisation").  To let it,
    a coordinate step of the live blocks is cut into three short loops without calls or
    hard-to-predict branches in the common path: the coefficients of (3.9), the zero test
    and Cardano's radicand of :func:`_minimizer_scalar` / :func:`_root_scalar`; the cube
    roots (:func:`_cube_root`); the root's polish, the choice of the minimiser and the
    update.  The trigonometric case of the root (three real roots, about 1 % of the
    steps) stays a branch of the last loop."""
    p = cols.shape[1]
    c1s = coef[0]
    c2s = coef[1]
    roots = coef[2]                  # Cardano's radicand, then its cube root
    discs = coef[3]
    zeros = coef[4]                  # 1.0 where (3.9) is decided 0 without a root
    n_live = 0
    for k in range(n):
        live[n_live] = k
        n_live += 1
        for mu in range(p):
            sv[k, mu] = 0.0
    for _ in range(max_cycles):
        for i in range(n_live):
            k = live[i]
            change[k] = 0.0
            acc = 0.0
            for mu in range(p):
                acc += m[k, mu] * m[k, mu]
            norm[k] = acc
        for j in range(p):
            for i in range(n_live):
                k = live[i]
                sjj = cols[k, j, j]
                old = m[k, j]
                c1 = 2.0 * (norm[k] - old * old) - 2.0 * sjj
                c2 = -4.0 * (sv[k, j] - sjj * old)
                c1s[i] = c1
                c2s[i] = c2
                gap = lam - abs(c2)
                t = -c1 / 3.0
                if c1 >= 0.0:
                    zeros[i] = 1.0 if gap >= 0.0 else 0.0
                else:
                    zeros[i] = 1.0 if gap >= 2.0 * t * np.sqrt(t) else 0.0
                pk = 0.5 * c1
                qk = 0.25 * gap
                disc = 0.25 * qk * qk + pk * pk * pk / 27.0
                discs[i] = disc
                sq = np.sqrt(abs(disc))               # used only where disc > 0
                roots[i] = -0.5 * qk - sq if qk >= 0 else -0.5 * qk + sq
            for i in range(n_live):
                roots[i] = _cube_root(roots[i])
            for i in range(n_live):
                k = live[i]
                old = m[k, j]
                new = 0.0
                if zeros[i] == 0.0:
                    c1 = c1s[i]
                    c2 = c2s[i]
                    a = abs(c2)
                    pk = 0.5 * c1
                    qk = 0.25 * (lam - a)
                    if discs[i] > 0:
                        u = roots[i]
                        y = u - pk / (3.0 * u) if u != 0 else 0.0
                    else:
                        y = _trigonometric_root(pk, qk)
                    fp = 3.0 * y * y + pk
                    if abs(fp) > 1e-12 * (1.0 + abs(pk)):
                        y = y - (y * y * y + pk * y + qk) / fp
                    if y > 0:
                        y2 = y * y
                        cost = y2 * y2 + c1 * y2 - a * y + lam * y
                        if cost < -1e-15 * (1.0 + abs(c1) + a):
                            new = -y if c2 > 0 else y
                change[k] += (new - old) * (new - old)
                if new != old:
                    m[k, j] = new
                    delta = new - old
                    col = cols[k, j]
                    svk = sv[k]
                    for mu in range(p):
                        svk[mu] += col[mu] * delta
                    norm[k] += new * new - old * old
        kept = 0
        for i in range(n_live):
            k = live[i]
            if not np.sqrt(change[k]) <= tol:
                live[kept] = k
                kept += 1
        n_live = kept
        if n_live == 0:
            break


def _factorize_loops(s, lam, n_cols, max_cycles, tol):
    n_blocks, p, _ = s.shape
    out = np.zeros((n_blocks, p, n_cols))
    cycles = np.zeros(n_blocks, dtype=np.int64)
    converged = np.zeros(n_blocks, dtype=np.bool_)
    cols = np.zeros((p, p))
    sv = np.zeros((n_cols, p))
    norms = np.zeros(n_cols)
    gram = np.zeros((n_cols, n_cols))
    for b in range(n_blocks):
        sb = s[b]
        for i in range(p):
            for j in range(p):
                cols[j, i] = sb[i, j]
        cycles[b], converged[b] = _factorize_block(cols, out[b], sv, norms, gram, lam,
                                                   n_cols, max_cycles, tol)
    return out, cycles, converged


_COMPILED: list = []


def _compiled_kernel():
    """The numba-compiled coordinate descent, or ``None`` without numba or with the
    environment variable ``MK_TRACKER_NO_NUMBA`` set (compiled once, cached on disk)."""
    if _COMPILED:
        return _COMPILED[0]
    try:
        numba = import_numba()
    except ImportError:
        _COMPILED.append(None)
        return None
    global _root_scalar, _minimizer_scalar, _factorize_block, _factorize_block_one_column
    global _factorize_blocks_one_column, _cube_root, _trigonometric_root
    register_bit_casts(_float_bits, _bits_float)
    _cube_root = numba.njit(cache=True, nogil=True)(_cube_root)
    _trigonometric_root = numba.njit(cache=True, nogil=True)(_trigonometric_root)
    _root_scalar = numba.njit(cache=True, nogil=True)(_root_scalar)
    _minimizer_scalar = numba.njit(cache=True, nogil=True)(_minimizer_scalar)
    _factorize_block_one_column = numba.njit(cache=True, nogil=True)(_factorize_block_one_column)
    _factorize_blocks_one_column = numba.njit(cache=True, nogil=True)(
        _factorize_blocks_one_column)
    _factorize_block = numba.njit(cache=True, nogil=True)(_factorize_block)
    kernel = numba.njit(cache=True, nogil=True)(_factorize_loops)
    _COMPILED.append(kernel)
    return kernel


def compiled_block_factorizer():
    """The numba-compiled :func:`_factorize_block` (one block, scratch arrays passed in), or
    ``None`` when the compiled backend is unavailable."""
    return _factorize_block if _compiled_kernel() is not None else None


def compiled_lockstep_factorizer():
    """The numba-compiled :func:`_factorize_blocks_one_column` (several one-column blocks in
    lock step, scratch arrays passed in), or ``None`` when the compiled backend is
    unavailable."""
    return _factorize_blocks_one_column if _compiled_kernel() is not None else None
