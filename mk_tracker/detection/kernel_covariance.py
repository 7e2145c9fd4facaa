"""Kernel covariance of a window of thermal frames, Schizas et al. (3.1)-(3.6).

For a window of ``F`` frames and pixels ``i, j`` of a block, with the Gaussian RBF kernel
(3.6) ``k(a, b) = exp(-(a - b)^2 / (2 sigma^2))`` on scalar intensities, (3.5) reads::

    Sigma(i, j) = 1/F   sum_tau        k(x_tau(i), x_tau(j))
                - 1/F^2 sum_tau,tau'   k(x_tau(i), x_tau'(j))

It is the covariance over the window of the feature vectors ``phi(x_tau(i))`` (3.1): the
second term is ``<phi_bar(i), phi_bar(j)>`` of the window means (3.3)-(3.4).

Why static pixels and static blocks cost nothing (exactly)
-------------------------------------------------------------
*A pixel that does not change over the window has a zero row and column.*  If
``x_tau(i) = a`` for every ``tau`` then for every ``j``::

    Sigma(i, j) = 1/F sum_tau k(a, x_tau(j)) - 1/F^2 sum_tau' sum_tau k(a, x_tau(j)) = 0,

because the inner sum of the second term does not depend on ``tau'``.  (It is the
covariance of a constant feature vector.)  A block whose pixels all stay constant therefore
has ``Sigma = 0``; the cost (3.7) is then ``||M||_F^4 + lambda ||M||_1``, minimised only by
``M = 0``: the block's factor is zero and it contributes no support pixel.

*More generally, the factor of a block is exactly zero whenever every diagonal entry is
small.*  Algorithm 1 starts from ``M = 0``.  While all other entries are zero the 1-D cost
(3.9) of entry ``j`` is ``h^4 - 2 Sigma(j, j) h^2 + lambda |h|``, which is >= 0 = J(0) for all
``h`` iff ``Sigma(j, j) <= T(lambda) := 3/2 (lambda / 2)^(2/3)``
(:func:`mk_tracker.detection.sparse_factorization.zero_factor_threshold`).  If that holds for every
pixel of a block, the first cycle leaves every entry at 0, the stopping rule
``||M^1 - M^0|| = 0 <= epsilon`` fires, and Algorithm 1 returns ``M = 0`` -- the same result
as running it.  Skipping such blocks is thus exact, not an approximation.  The diagonal is
cheap (:func:`pixel_kernel_variance`), and a free bound rules out most pixels first: if a
pixel's values span a range ``r`` over the window every kernel value is
``>= exp(-r^2 / (2 sigma^2))``, so ``Sigma(j, j) <= 1 - exp(-r^2 / (2 sigma^2))``
(:func:`variance_bound_from_range`).

The fast path (:func:`block_kernel_covariance`) evaluates (3.5) for a batch of blocks
with one ``exp`` per unordered frame pair ``tau <= tau'`` and pixel pair, using the symmetry
``k(x_tau(i), x_tau'(j)) = k(x_tau'(j), x_tau(i))``.
"""

from __future__ import annotations


import numpy as np

from mk_tracker.numba_support import import_numba


class KernelCovarianceError(ValueError):
    """A window or block array the kernel covariance cannot be computed from."""


def rbf_kernel(a: np.ndarray, b: np.ndarray, sigma2: float) -> np.ndarray:
    """Gaussian RBF kernel (3.6) ``exp(-(a - b)^2 / (2 sigma^2))``, elementwise."""
    d = np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)
    return np.exp(-(d * d) / (2.0 * sigma2))


def _check_sigma2(sigma2: float) -> float:
    s = float(sigma2)
    if not np.isfinite(s) or s <= 0:
        raise KernelCovarianceError(f"kernel variance sigma^2 must be positive, got {sigma2!r}")
    return s


def block_kernel_covariance(blocks: np.ndarray, sigma2: float,
                            dtype: type = np.float32) -> np.ndarray:
    """Kernel covariance (3.5) of each block: ``(B, F, p)`` values -> ``(B, p, p)``.

    ``blocks[b, tau, i]`` is pixel ``i`` of block ``b`` in frame ``tau`` of the window, on
    the unit intensity scale.  ``dtype`` is the working precision (float32 is ~3x faster;
    float64 for reference checks).  Returns a symmetric array of that dtype.
    """
    x = np.asarray(blocks)
    if x.ndim != 3:
        raise KernelCovarianceError(f"blocks must be (B, F, p), got shape {x.shape}")
    n_blocks, n_frames, p = x.shape
    if n_frames < 1:
        raise KernelCovarianceError("the window holds no frame")
    s2 = _check_sigma2(sigma2)
    x = x.astype(dtype, copy=False)
    if not np.all(np.isfinite(x)):
        raise KernelCovarianceError("blocks hold NaN or infinite values; fill missing pixels")
    neg_inv = dtype(-1.0 / (2.0 * s2))
    same = np.zeros((n_blocks, p, p), dtype=dtype)      # sum_tau k(x_tau(i), x_tau(j))
    cross = np.zeros((n_blocks, p, p), dtype=dtype)     # sum_{tau != tau'} ...
    for a in range(n_frames):
        for b in range(a, n_frames):
            d = x[:, a, :, None] - x[:, b, None, :]
            np.multiply(d, d, out=d)
            d *= neg_inv
            np.exp(d, out=d)
            if a == b:
                same += d
            else:
                cross += d
                cross += d.transpose(0, 2, 1)
    f = dtype(n_frames)
    # (3.5): 1/F sum_same - 1/F^2 (sum_same + sum_cross)
    sigma = same * (dtype(1.0) / f - dtype(1.0) / (f * f)) - cross * (dtype(1.0) / (f * f))
    return sigma


def pixel_kernel_variance(window: np.ndarray, sigma2: float,
                          mask: np.ndarray | None = None) -> np.ndarray:
    """Diagonal ``Sigma(j, j)`` of (3.5) for every pixel of a ``(F, ...)`` window.

    ``Sigma(j, j) = 2/F^2 sum_{tau < tau'} (1 - k(x_tau(j), x_tau'(j)))``.  With ``mask``
    (shape of one frame) only the masked pixels are computed; the others are 0.
    """
    x = np.asarray(window, dtype=np.float32)
    if x.ndim < 2:
        raise KernelCovarianceError(f"window must be (F, ...), got shape {x.shape}")
    s2 = _check_sigma2(sigma2)
    n_frames = x.shape[0]
    out = np.zeros(x.shape[1:], dtype=np.float32)
    if mask is not None:
        sel = x[:, mask]
    else:
        sel = x.reshape(n_frames, -1)
    acc = np.zeros(sel.shape[1], dtype=np.float32)
    neg_inv = np.float32(-1.0 / (2.0 * s2))
    for a in range(n_frames):
        for b in range(a + 1, n_frames):
            d = sel[a] - sel[b]
            np.multiply(d, d, out=d)
            d *= neg_inv
            np.exp(d, out=d)
            acc += np.float32(1.0) - d
    acc *= np.float32(2.0 / (n_frames * n_frames))
    if mask is not None:
        out[mask] = acc
    else:
        out = acc.reshape(x.shape[1:])
    return out


def variance_bound_from_range(value_range: np.ndarray, sigma2: float) -> np.ndarray:
    """Upper bound ``1 - exp(-r^2 / (2 sigma^2))`` of ``Sigma(j, j)`` from a pixel's range r."""
    r = np.asarray(value_range, dtype=np.float32)
    return np.float32(1.0) - np.exp(-(r * r) / np.float32(2.0 * _check_sigma2(sigma2)))


def range_for_variance(threshold: float, sigma2: float) -> float:
    """Largest temporal range ``r`` whose bound :func:`variance_bound_from_range` is <= threshold."""
    s2 = _check_sigma2(sigma2)
    if threshold >= 1.0:
        return float("inf")
    if threshold <= 0.0:
        return 0.0
    return float(np.sqrt(-2.0 * s2 * np.log1p(-threshold)))


def active_pixels(window: np.ndarray, sigma2: float, threshold: float) -> np.ndarray:
    """Boolean map of pixels with ``Sigma(j, j) > threshold`` over a ``(F, H, W)`` window.

    Pixels whose temporal range already bounds their variance below ``threshold`` are
    decided without any kernel evaluation (see the module docstring).
    """
    x = np.asarray(window, dtype=np.float32)
    if x.ndim != 3:
        raise KernelCovarianceError(f"window must be (F, H, W), got shape {x.shape}")
    spread = x.max(axis=0) - x.min(axis=0)
    r0 = range_for_variance(threshold, sigma2)
    candidates = spread > np.float32(r0)
    if not candidates.any():
        return candidates
    var = pixel_kernel_variance(x, sigma2, mask=candidates)
    return var > np.float32(threshold)


def frame_blocks(window: np.ndarray, rho: int) -> tuple[np.ndarray, tuple[int, int]]:
    """Split a ``(F, H, W)`` window with ``H, W`` multiples of ``rho`` into (5.1) blocks.

    Returns ``((nby * nbx, F, rho * rho) array, (nby, nbx))``; block ``b = by * nbx + bx``
    holds rows ``by*rho ...`` and columns ``bx*rho ...``, pixels in row-major order.
    """
    x = np.asarray(window)
    n_frames, h, w = x.shape
    if h % rho or w % rho:
        raise KernelCovarianceError(f"window {h}x{w} is not a multiple of the block size {rho}")
    nby, nbx = h // rho, w // rho
    blocks = (x.reshape(n_frames, nby, rho, nbx, rho)
               .transpose(1, 3, 0, 2, 4)
               .reshape(nby * nbx, n_frames, rho * rho))
    return blocks, (nby, nbx)


def kernel_table(max_level: int, scale: float, sigma2: float) -> np.ndarray:
    """``table[d] = k(0, d * scale)`` of (3.6) for integer level differences ``d``.

    For integer-valued frames (mono8 levels with ``scale = 1/255``) the kernel of two pixels
    depends only on ``|level_i - level_j|``, so a table evaluates (3.6) exactly.
    """
    d = np.arange(int(max_level) + 1, dtype=np.float64) * float(scale)
    return np.exp(-(d * d) / (2.0 * _check_sigma2(sigma2)))


#: lanes of :func:`_gather_add` (one AVX-512 register of doubles)
_LANES = 8


def _gather_add(table, row, level, out, j):
    """``out[j + l] += table[|level - row[j + l]|]`` for the ``_LANES`` lanes ``l``: each
    lane its own look-up and its own addition, so the values are those of a scalar loop.
    Plain Python; in compiled code it is one vector gather (:func:`_register_gather_add`:
    numba does not vectorise the look-ups itself, as it cannot rule out that ``out``
    overlaps ``table``)."""
    for lane in range(j, j + _LANES):
        out[lane] += table[abs(level - row[lane])]


def _levels_block_covariance(x, table, same, cross, o):
    """(3.5) of one block of integer levels ``x`` ``(F, p)`` into ``o`` ``(p, p)``.

    ``same`` and ``cross`` are ``(p, p)`` scratch arrays.  Plain Python, compiled with numba
    (see :func:`compiled_level_kernels`); the batch function and the detector's fused
    per-block loop both call it, so there is one implementation.  The look-ups of a row
    go ``_LANES`` at a time (:func:`_gather_add`), each entry still summed over the frame
    pairs in the same order; ``same`` is summed from the lane group holding the entry right
    of the diagonal (only those entries are read).
    """
    n_frames, p = x.shape
    inv_f = 1.0 / n_frames
    inv_f2 = inv_f * inv_f
    same[:, :] = 0.0
    cross[:, :] = 0.0
    vector_end = p - p % _LANES
    for a in range(n_frames):
        xa = x[a]
        for i in range(p):
            xi = xa[i]
            row = same[i]
            # only the entries right of the diagonal are read: start at the lane group
            # that holds i + 1
            for j in range(((i + 1) // _LANES) * _LANES, vector_end, _LANES):
                _gather_add(table, xa, xi, row, j)
            for j in range(max(vector_end, i + 1), p):
                row[j] += table[abs(xi - xa[j])]
        for c in range(a + 1, n_frames):
            xc = x[c]
            for i in range(p):
                xi = xa[i]
                row = cross[i]
                for j in range(0, vector_end, _LANES):
                    _gather_add(table, xc, xi, row, j)
                for j in range(vector_end, p):
                    row[j] += table[abs(xi - xc[j])]
    for i in range(p):
        # diagonal: same-frame kernel is 1 for each of the F frames
        o[i, i] = (n_frames * (inv_f - inv_f2)) - (cross[i, i] + cross[i, i]) * inv_f2
        for j in range(i + 1, p):
            v = same[i, j] * (inv_f - inv_f2) - (cross[i, j] + cross[j, i]) * inv_f2
            o[i, j] = v
            o[j, i] = v


def _gather_one_minus(table, first, second, out, j):
    """``out[j + l] += 1 - table[|first[j + l] - second[j + l]|]`` for the ``_LANES`` lanes
    ``l`` (as :func:`_gather_add`: plain Python; one vector gather in compiled code)."""
    for lane in range(j, j + _LANES):
        out[lane] += 1.0 - table[abs(first[lane] - second[lane])]


def _levels_block_variance(x, table, out):
    """Diagonal of (3.5) of one block of integer levels ``x`` ``(F, p)`` into ``out`` ``(p,)``:
    ``2/F^2 sum_{tau < tau'} (1 - table[|x_tau(j) - x_tau'(j)|])``.  ``_LANES`` pixels at a
    time (:func:`_gather_one_minus`), each summed in ``out`` from 0 over the frame pairs in
    the same order as the scalar loop of the rest."""
    n_frames, p = x.shape
    scale = 2.0 / (n_frames * n_frames)
    vector_end = p - p % _LANES
    for j in range(0, vector_end, _LANES):
        for i in range(j, j + _LANES):
            out[i] = 0.0
        for a in range(n_frames):
            for c in range(a + 1, n_frames):
                _gather_one_minus(table, x[a], x[c], out, j)
        for i in range(j, j + _LANES):
            out[i] = out[i] * scale
    for i in range(vector_end, p):
        acc = 0.0
        for a in range(n_frames):
            xa = x[a, i]
            for c in range(a + 1, n_frames):
                acc += 1.0 - table[abs(xa - x[c, i])]
        out[i] = acc * scale


def _levels_covariance_loops(levels, table, out):
    n_blocks, n_frames, p = levels.shape
    same = np.zeros((p, p))
    cross = np.zeros((p, p))
    for b in range(n_blocks):
        _levels_block_covariance(levels[b], table, same, cross, out[b])
    return out


def _levels_variance_loops(levels, table, out):
    for b in range(levels.shape[0]):
        _levels_block_variance(levels[b], table, out[b])
    return out


_LEVEL_KERNELS: list = []


_GATHER_ADD: list = []


def _register_gather_add() -> None:
    """Compiled code's :func:`_gather_add` and :func:`_gather_one_minus` (numba
    overloads; Python keeps the plain functions): the ``_LANES`` levels of ``row``
    loaded as one vector, ``|level - row|`` (or ``|first - second|``) per lane, one
    ``llvm.masked.gather`` of the table entries (all lanes on), one vector addition (of
    ``1 - entry``) into ``out`` and one store -- IEEE operations per lane, so the values of
    the scalar loop.  For aligned C-contiguous ``table`` (float64), ``row`` (int32) and
    ``out`` (float64), with ``j + _LANES <= len(row), len(out)`` (the callers' loops; not
    checked); other arrays get the scalar loop.  Once per process; needs numba."""
    if _GATHER_ADD:
        return
    from llvmlite import ir
    from numba.core import cgutils, types
    from numba.extending import intrinsic, overload

    def gathered(context, builder, table_type, table, index32):
        """The table entries at the ``_LANES`` int32 indices ``index32`` (one gather)."""
        tab_a = context.make_array(table_type)(context, builder, table)
        i1, i32, i64, f64 = ir.IntType(1), ir.IntType(32), ir.IntType(64), ir.DoubleType()
        vi32, vi64 = ir.VectorType(i32, _LANES), ir.VectorType(i64, _LANES)
        vf64, vptr = ir.VectorType(f64, _LANES), ir.VectorType(f64.as_pointer(), _LANES)
        base = builder.insert_element(ir.Constant(vi64, None),
                                      builder.ptrtoint(tab_a.data, i64), ir.Constant(i32, 0))
        base = builder.shuffle_vector(base, ir.Constant(vi64, None),
                                      ir.Constant(vi32, [0] * _LANES))
        addresses = builder.add(base, builder.mul(builder.sext(index32, vi64),
                                                  ir.Constant(vi64, [8] * _LANES)))
        gather = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(vf64, [vptr, i32, ir.VectorType(i1, _LANES), vf64]),
            f"llvm.masked.gather.v{_LANES}f64.v{_LANES}p0f64")
        return builder.call(gather, [builder.inttoptr(addresses, vptr), ir.Constant(i32, 8),
                                     ir.Constant(ir.VectorType(i1, _LANES), [1] * _LANES),
                                     ir.Constant(vf64, None)])

    def lanes(context, builder, array_type, array, start, element):
        """Pointer to ``_LANES`` elements of a C-contiguous 1-D array from ``start``."""
        data = context.make_array(array_type)(context, builder, array).data
        return builder.bitcast(builder.gep(data, [start]),
                               ir.VectorType(element, _LANES).as_pointer())

    def absolute(builder, diff):
        zero = ir.Constant(diff.type, [0] * _LANES)
        return builder.select(builder.icmp_signed("<", diff, zero), builder.neg(diff), diff)

    @intrinsic
    def vector_gather_add(typingctx, table, row, level, out, j):
        sig = types.void(table, row, level, out, j)

        def codegen(context, builder, signature, args):
            i32, f64 = ir.IntType(32), ir.DoubleType()
            vi32 = ir.VectorType(i32, _LANES)
            start = context.cast(builder, args[4], signature.args[4], types.intp)
            lvl = context.cast(builder, args[2], signature.args[2], types.int32)
            lvl = builder.insert_element(ir.Constant(vi32, None), lvl, ir.Constant(i32, 0))
            lvl = builder.shuffle_vector(lvl, ir.Constant(vi32, None),
                                         ir.Constant(vi32, [0] * _LANES))
            levels = builder.load(lanes(context, builder, signature.args[1], args[1], start,
                                        i32), align=4)
            values = gathered(context, builder, signature.args[0], args[0],
                              absolute(builder, builder.sub(lvl, levels)))
            target = lanes(context, builder, signature.args[3], args[3], start, f64)
            builder.store(builder.fadd(builder.load(target, align=8), values), target,
                          align=8)
            return context.get_dummy_value()

        return sig, codegen

    @intrinsic
    def vector_gather_one_minus(typingctx, table, first, second, out, j):
        sig = types.void(table, first, second, out, j)

        def codegen(context, builder, signature, args):
            i32, f64 = ir.IntType(32), ir.DoubleType()
            start = context.cast(builder, args[4], signature.args[4], types.intp)
            a = builder.load(lanes(context, builder, signature.args[1], args[1], start, i32),
                             align=4)
            b = builder.load(lanes(context, builder, signature.args[2], args[2], start, i32),
                             align=4)
            values = gathered(context, builder, signature.args[0], args[0],
                              absolute(builder, builder.sub(a, b)))
            ones = ir.Constant(ir.VectorType(f64, _LANES), [1.0] * _LANES)
            target = lanes(context, builder, signature.args[3], args[3], start, f64)
            builder.store(builder.fadd(builder.load(target, align=8),
                                       builder.fsub(ones, values)), target, align=8)
            return context.get_dummy_value()

        return sig, codegen

    def vectorisable(table, rows, out, level=None):
        arrays = [(table, types.float64), (out, types.float64)] + \
            [(row, types.int32) for row in rows]
        return all(isinstance(arg, types.Array) and arg.ndim == 1 and arg.layout == "C"
                   and arg.aligned and arg.dtype == dtype for arg, dtype in arrays) and \
            (level is None or isinstance(level, types.Integer))

    @overload(_gather_one_minus, inline="always")
    def _gather_one_minus_compiled(table, first, second, out, j):
        if vectorisable(table, (first, second), out) and isinstance(j, types.Integer):
            def impl(table, first, second, out, j):
                vector_gather_one_minus(table, first, second, out, j)
            return impl

        def scalar(table, first, second, out, j):
            for lane in range(j, j + _LANES):
                out[lane] += 1.0 - table[abs(first[lane] - second[lane])]
        return scalar

    @overload(_gather_add, inline="always")
    def _gather_add_compiled(table, row, level, out, j):
        if vectorisable(table, (row,), out, level) and isinstance(j, types.Integer):
            def impl(table, row, level, out, j):
                vector_gather_add(table, row, level, out, j)
            return impl

        def scalar(table, row, level, out, j):
            for lane in range(j, j + _LANES):
                out[lane] += table[abs(level - row[lane])]
        return scalar

    _GATHER_ADD.append(vector_gather_add)


def compiled_level_kernels() -> dict | None:
    """The numba-compiled level kernels (``block_covariance``, ``block_variance``,
    ``covariance``, ``variance``), or ``None`` without numba or with the environment variable
    ``MK_TRACKER_NO_NUMBA`` set.  Compiled once per process, cached on disk."""
    if _LEVEL_KERNELS:
        return _LEVEL_KERNELS[0]
    try:
        numba = import_numba()
    except ImportError:
        _LEVEL_KERNELS.append(None)
        return None
    global _levels_block_covariance, _levels_block_variance
    _register_gather_add()
    _levels_block_covariance = numba.njit(cache=True, nogil=True)(_levels_block_covariance)
    _levels_block_variance = numba.njit(cache=True, nogil=True)(_levels_block_variance)
    kernels = {"block_covariance": _levels_block_covariance,
               "block_variance": _levels_block_variance,
               "covariance": numba.njit(cache=True, nogil=True)(_levels_covariance_loops),
               "variance": numba.njit(cache=True, nogil=True)(_levels_variance_loops)}
    _LEVEL_KERNELS.append(kernels)
    return kernels


def block_kernel_covariance_levels(levels: np.ndarray, table: np.ndarray) -> np.ndarray:
    """(3.5) for blocks of integer levels ``(B, F, p)`` with a :func:`kernel_table`; float64.

    Same result as :func:`block_kernel_covariance` on ``levels * scale`` (to rounding), with
    table look-ups instead of exponentials; compiled with numba when it is installed.
    """
    lv = np.ascontiguousarray(levels, dtype=np.int32)
    if lv.ndim != 3 or lv.shape[1] < 1:
        raise KernelCovarianceError(f"levels must be (B, F, p), got shape {lv.shape}")
    tab = np.ascontiguousarray(table, dtype=np.float64)
    if lv.size and int(lv.max()) - int(lv.min()) >= tab.size:
        raise KernelCovarianceError("level differences exceed the kernel table")
    kernels = compiled_level_kernels()
    out = np.empty((lv.shape[0], lv.shape[2], lv.shape[2]))
    if kernels is None:      # numpy fallback: the generic path on the scaled values
        scale = float(np.sqrt(-2.0 * np.log(tab[1]))) if tab.size > 1 and tab[1] < 1 else 1.0
        # table[1] = exp(-s^2 / 2 sigma^2) -> rebuild values in units where sigma^2 = 1
        return block_kernel_covariance(lv * scale, 1.0, dtype=np.float64)
    return kernels["covariance"](lv, tab, out)


def block_variance_levels(levels: np.ndarray, table: np.ndarray) -> np.ndarray:
    """Diagonal ``Sigma(j, j)`` of (3.5) for blocks of integer levels ``(B, F, p)``.

    ``2/F^2 sum_{tau < tau'} (1 - table[|x_tau(j) - x_tau'(j)|])`` with a
    :func:`kernel_table`; ``(B, p)`` float64.  Compiled with numba when it is installed.
    """
    lv = np.ascontiguousarray(levels, dtype=np.int32)
    if lv.ndim != 3:
        raise KernelCovarianceError(f"levels must be (B, F, p), got shape {lv.shape}")
    tab = np.ascontiguousarray(table, dtype=np.float64)
    if lv.size and int(lv.max()) - int(lv.min()) >= tab.size:
        raise KernelCovarianceError("level differences exceed the kernel table")
    kernels = compiled_level_kernels()
    out = np.zeros((lv.shape[0], lv.shape[2]))
    if kernels is None:
        n_frames = lv.shape[1]
        for a in range(n_frames):
            for c in range(a + 1, n_frames):
                out += 1.0 - tab[np.abs(lv[:, a, :] - lv[:, c, :])]
        return out * (2.0 / (n_frames * n_frames))
    return kernels["variance"](lv, tab, out)
