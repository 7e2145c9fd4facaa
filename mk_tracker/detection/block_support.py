"""Support of the stacked sparse factors (5.1) of a window of thermal frames (Schizas,
Maroulas & Ren 2018, Secs. 3 and 5.1): the per-block work of every pass of Algorithm 2.

The window is cut into ``rho x rho`` blocks (divide and conquer, Sec. 5.1).  A block whose
factor is provably zero is skipped exactly: no pixel's kernel variance ``Sigma(j, j)`` of
(3.5) exceeds the threshold ``T(lambda)`` of Algorithm 1
(:func:`mk_tracker.detection.sparse_factorization.zero_factor_threshold`), which is first
bounded by the pixels' temporal ranges (:func:`mk_tracker.detection.kernel_covariance.range_for_variance`).
The other blocks get their kernel covariance (3.5) with the kernel (3.6) and its sparse
factor (3.7) by coordinate descent (Algorithm 1); the pixels of the non-zero rows of the
stacked factors (5.1) are the support, the pixels that changed during the window.

Two paths do the same arithmetic:

* :func:`_support_numpy`, the reference: gathers the blocks into batches, the variance of
  all of them, then (3.5) and Algorithm 1 of the active ones (any frame encoding);
* :func:`_support_loops`, compiled with numba (``nogil``) by :func:`_fused_kernel`: one loop
  over the blocks that reads the detector's ring buffer in place and runs the skip rule,
  (3.5) and Algorithm 1 per block, for integer levels (mono8, mono16) whose range fits the
  kernel table.  With one column (the default) the active blocks wait in batches of
  ``_LOCKSTEP_BLOCKS`` and Algorithm 1 runs on a batch in lock step
  (:func:`_factor_waiting`): the same values as one block at a time, faster because the
  blocks' dependent steps overlap.  ``MK_TRACKER_NO_NUMBA=1`` selects the reference; tests
  check both give the same support.

The compiled loop embeds the level kernels of :mod:`mk_tracker.detection.kernel_covariance`
and the block factorizer of :mod:`mk_tracker.detection.sparse_factorization`; numba's disk
cache does not see changes to those modules, so :func:`_drop_stale_cache` keeps a digest of
their sources beside the cache and drops it when they change.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from mk_tracker.detection.kernel_covariance import (_levels_block_covariance, _levels_block_variance,
                                          block_kernel_covariance,
                                          block_kernel_covariance_levels,
                                          block_variance_levels, compiled_level_kernels,
                                          kernel_table, pixel_kernel_variance,
                                          range_for_variance)
from mk_tracker.detection.sparse_factorization import (_factorize_block,
                                             _factorize_blocks_one_column,
                                             compiled_block_factorizer,
                                             compiled_lockstep_factorizer,
                                             sparse_factorize, zero_factor_threshold)
from mk_tracker.detection.thermal_image import ThermalInputError

if TYPE_CHECKING:
    from mk_tracker.detection.thermal_detector_config import ThermalDetectorConfig

__all__ = ["SupportResult", "TABLE_LEVELS", "support_in_frame"]


@dataclass
class SupportResult:
    """Support of the stacked factors (5.1) of one region and the kernel variance per pixel."""

    support: np.ndarray      # (h, w) bool
    variance: np.ndarray     # (h, w) float32, Sigma(j, j) in the factored blocks, else 0
    blocks_total: int
    blocks_factored: int


def _pad_to(window: np.ndarray, rho: int) -> np.ndarray:
    """Pad ``(F, h, w)`` with zeros up to multiples of rho.  The padding is constant over
    time, so its kernel-covariance rows are zero and it never enters a support."""
    _, h, w = window.shape
    ph, pw = (-h) % rho, (-w) % rho
    if ph == 0 and pw == 0:
        return window
    return np.pad(window, ((0, 0), (0, ph), (0, pw)))


#: Largest level difference served by a kernel table (integer encodings); wider windows
#: use the exponential path.
TABLE_LEVELS = 4096


def support_in_frame(window: np.ndarray, config: ThermalDetectorConfig, scale: float = 1.0,
                     integer_levels: bool = False, block_mask: np.ndarray | None = None,
                     chunk: int = 512, backend: str = "auto") -> SupportResult:
    """Support of the stacked sparse factors (5.1) of a ``(F, h, w)`` window.

    The window is padded to multiples of ``rho`` (with zeros, which never enter a support)
    and cut into ``rho x rho`` blocks; only the blocks of ``block_mask`` (``(nby, nbx)``
    bool, default all) are considered, and of those only the ones whose factor is not
    provably zero (see :mod:`mk_tracker.detection.kernel_covariance`) are factored.

    Window values are ``(raw - offset)``; ``scale`` maps them to the kernel's unit scale, so
    the kernel variance in window units is ``sigma^2 / scale^2``.  With ``integer_levels``
    (mono8/mono16 frames, integer offset) (3.5) is evaluated with a table of (3.6) over
    level differences instead of exponentials (same values).

    ``backend``: ``"numpy"`` (blocks gathered into batches: variance, then kernel covariance
    and Algorithm 1 of the active ones -- the reference), ``"compiled"`` (integer levels
    only: one numba loop that does the same per block, without gathering; needs numba) or
    ``"auto"`` (compiled when it applies and numba is available).
    """
    win = np.asarray(window)
    if win.ndim != 3:
        raise ThermalInputError(f"window must be (F, h, w), got shape {win.shape}")
    return _support(win, np.arange(win.shape[0]), 0.0, config, scale, integer_levels,
                    block_mask, chunk, backend)


def _block_list(nby: int, nbx: int, block_mask: np.ndarray | None
                ) -> tuple[np.ndarray, np.ndarray]:
    if block_mask is None:
        by, bx = np.divmod(np.arange(nby * nbx), nbx)
        return by, bx
    return np.nonzero(block_mask)


def _support(frames: np.ndarray, order: np.ndarray, offset: float,
             config: ThermalDetectorConfig, scale: float, integer_levels: bool,
             block_mask: np.ndarray | None, chunk: int = 512,
             backend: str = "auto", sigma2: float | None = None) -> SupportResult:
    """:func:`support_in_frame` of the window ``frames[order] - offset`` (``frames`` may be
    the detector's ring buffer: the compiled path reads it in place); ``sigma2`` (unit
    scale) replaces ``config.sigma2`` when given."""
    if backend not in ("auto", "numpy", "compiled"):
        raise ThermalInputError(f"unknown backend {backend!r}")
    rho = config.block_size
    _, h, w = frames.shape
    nby, nbx = -(-h // rho), -(-w // rho)
    sigma2 = (config.sigma2 if sigma2 is None else sigma2) / (scale * scale)
    threshold = zero_factor_threshold(config.lam)
    fused = _fused_kernel() if backend != "numpy" else None
    if backend == "compiled" and (fused is None or not integer_levels):
        raise ThermalInputError("the compiled support path needs numba and integer levels")
    if fused is not None and integer_levels:
        if block_mask is None:
            listed = np.ones((nby, nbx), dtype=bool)
        else:
            listed = np.asarray(block_mask, dtype=bool)
            if listed.shape != (nby, nbx):
                raise ThermalInputError(f"block mask of shape {listed.shape}, expected "
                                        f"{(nby, nbx)}")
        support = np.zeros((h, w), dtype=bool)
        variance = np.zeros((h, w), dtype=np.float32)
        factored = fused(frames, np.ascontiguousarray(order, dtype=np.int64), np.float32(offset),
                         listed, rho, _kernel_table(sigma2), threshold,
                         range_for_variance(threshold, sigma2), config.lam,
                         config.columns, config.max_cycles, config.tol, support, variance)
        if factored >= 0:
            return SupportResult(support, variance, int(np.count_nonzero(listed)),
                                 int(factored))
        # a block's levels span more than the table: the exponential path
    window = frames[order] - np.float32(offset)
    return _support_numpy(window, config, sigma2, threshold, integer_levels, block_mask, chunk)


def _support_numpy(window: np.ndarray, config: ThermalDetectorConfig, sigma2: float,
                   threshold: float, integer_levels: bool, block_mask: np.ndarray | None,
                   chunk: int) -> SupportResult:
    """Reference path: gather the blocks, batch the variance, factor the active blocks."""
    rho = config.block_size
    n_frames, h, w = window.shape
    padded = _pad_to(window, rho)
    nby, nbx = padded.shape[1] // rho, padded.shape[2] // rho
    by, bx = _block_list(nby, nbx, block_mask)
    p = rho * rho
    blocks = (padded.reshape(n_frames, nby, rho, nbx, rho)[:, by, :, bx, :]
              .reshape(by.size, n_frames, p))
    use_table = integer_levels and by.size > 0 and \
        float(blocks.max()) - float(blocks.min()) < TABLE_LEVELS
    table = _kernel_table(sigma2) if use_table else None
    # exact activity test: Sigma(j, j) > T(lambda) for some pixel of the block
    if table is not None:
        blocks = blocks.astype(np.int32)
        variance = block_variance_levels(blocks, table).astype(np.float32)
    else:
        spread = blocks.max(axis=1) - blocks.min(axis=1)      # range bound first
        candidates = spread > np.float32(range_for_variance(threshold, sigma2))
        variance = np.zeros((by.size, p), dtype=np.float32)
        if candidates.any():
            variance = pixel_kernel_variance(blocks.transpose(1, 0, 2), sigma2, mask=candidates)
    is_active = (variance > np.float32(threshold)).any(axis=1)
    variance[~is_active] = 0.0
    active = np.flatnonzero(is_active)
    supports = np.zeros((by.size, p), dtype=bool)
    work = blocks[active]
    for start in range(0, active.size, chunk):
        part = work[start:start + chunk]
        if table is not None:
            sigma = block_kernel_covariance_levels(part, table)
        else:
            sigma = block_kernel_covariance(part, sigma2)
        res = sparse_factorize(sigma, config.lam, columns=config.columns,
                               max_cycles=config.max_cycles, tol=config.tol)
        supports[active[start:start + chunk]] = res.support()
    sup = np.zeros((nby * nbx, p), dtype=bool)
    var = np.zeros((nby * nbx, p), dtype=np.float32)
    flat = by * nbx + bx
    sup[flat] = supports
    var[flat] = variance
    sup_img = sup.reshape(nby, nbx, rho, rho).transpose(0, 2, 1, 3).reshape(nby * rho, nbx * rho)
    var_img = var.reshape(nby, nbx, rho, rho).transpose(0, 2, 1, 3).reshape(nby * rho, nbx * rho)
    return SupportResult(sup_img[:h, :w], var_img[:h, :w], by.size, int(active.size))


def _support_loops(frames, order, offset, listed, rho, table, threshold, max_range, lam,
                   n_cols, max_cycles, tol, support, variance):
    """Compiled per-block loop of :func:`_support_numpy` on integer levels, same arithmetic.

    For each block listed in ``listed`` (``(nby, nbx)`` bool), in row-major order like
    ``np.nonzero``: its levels ``frames[order[t]] - offset`` (0 outside the frame,
    like the zero padding); blocks where no pixel's temporal range exceeds ``max_range``
    are skipped (their variance is provably <= ``threshold``); the others get the diagonal
    of (3.5), and if some pixel's variance exceeds ``threshold`` the kernel covariance (3.5)
    and Algorithm 1.  Writes ``support``/``variance`` (frame-sized) of the factored blocks
    and returns their number, or -1 if a block's levels span more than the ``table``.
    """
    n_frames = order.shape[0]
    h, w = support.shape
    p = rho * rho
    n_levels = table.shape[0]
    x = np.zeros((n_frames, p), dtype=np.int32)
    lo = np.empty(p, dtype=np.int32)               # per-pixel temporal range
    hi = np.empty(p, dtype=np.int32)
    var = np.zeros(p)
    sigma = np.zeros((p, p))
    same = np.zeros((p, p))
    cross = np.zeros((p, p))
    m = np.zeros((p, n_cols))
    sv = np.zeros((n_cols, p))
    norms = np.zeros(n_cols)
    gram = np.zeros((n_cols, n_cols))
    # one column (the default): active blocks wait in a batch and are factored in lock step
    lockstep = n_cols == 1
    batch = _LOCKSTEP_BLOCKS if lockstep else 1
    sigmas = np.zeros((batch, p, p))
    factors = np.zeros((batch, p))
    svs = np.zeros((batch, p))
    norms_b = np.zeros(batch)
    changes = np.zeros(batch)
    live = np.zeros(batch, dtype=np.int64)
    coef = np.zeros((5, batch))
    variances = np.zeros((batch, p))
    corners = np.zeros((batch, 2), dtype=np.int64)
    waiting = 0
    factored = 0
    nby, nbx = listed.shape
    for by in range(nby):
        for bx in range(nbx):
            if not listed[by, bx]:
                continue
            y0 = by * rho
            x0 = bx * rho
            inside = y0 + rho <= h and x0 + rho <= w
            if inside:
                for t in range(n_frames):
                    f = frames[order[t]]
                    xt = x[t]
                    for dy in range(rho):
                        row = f[y0 + dy]
                        for dx in range(rho):
                            xt[dy * rho + dx] = np.int32(row[x0 + dx] - offset)
            else:
                x[:, :] = 0                              # the zero padding at the frame edge
                for t in range(n_frames):
                    f = frames[order[t]]
                    for dy in range(rho):
                        if y0 + dy >= h:
                            break
                        row = f[y0 + dy]
                        for dx in range(rho):
                            if x0 + dx >= w:
                                break
                            x[t, dy * rho + dx] = np.int32(row[x0 + dx] - offset)
            lo[:] = x[0]
            hi[:] = x[0]
            for t in range(1, n_frames):
                xt = x[t]
                for i in range(p):
                    lo[i] = min(lo[i], xt[i])
                    hi[i] = max(hi[i], xt[i])
            moving = False
            block_lo = 0 if not inside else n_levels
            block_hi = 0 if not inside else -n_levels
            for i in range(p):
                moving |= hi[i] - lo[i] > max_range
                block_lo = min(block_lo, lo[i])
                block_hi = max(block_hi, hi[i])
            if block_hi - block_lo >= n_levels:
                return -1
            if not moving:
                continue
            _levels_block_variance(x, table, var)
            active = False
            for i in range(p):
                if var[i] > threshold:
                    active = True
                    break
            if not active:
                continue
            factored += 1
            if lockstep:
                _levels_block_covariance(x, table, same, cross, sigmas[waiting])
                variances[waiting, :] = var
                corners[waiting, 0] = y0
                corners[waiting, 1] = x0
                waiting += 1
                if waiting == batch:
                    _factor_waiting(sigmas, factors, svs, waiting, lam, max_cycles, tol,
                                    norms_b, changes, live, coef, variances, corners,
                                    rho, support, variance)
                    waiting = 0
                continue
            _levels_block_covariance(x, table, same, cross, sigma)
            m[:, :] = 0.0
            # sigma is exactly symmetric (each entry is written to both halves), so it is its
            # own column array
            _factorize_block(sigma, m, sv, norms, gram, lam, n_cols, max_cycles, tol)
            for dy in range(rho):
                if y0 + dy >= h:
                    break
                for dx in range(rho):
                    if x0 + dx >= w:
                        break
                    i = dy * rho + dx
                    variance[y0 + dy, x0 + dx] = var[i]
                    on = False
                    for r in range(n_cols):
                        if m[i, r] != 0.0:
                            on = True
                    support[y0 + dy, x0 + dx] = on
    if waiting:
        _factor_waiting(sigmas, factors, svs, waiting, lam, max_cycles, tol, norms_b, changes,
                        live, coef, variances, corners, rho, support, variance)
    return factored

#: active one-column blocks factored together (:func:`_factor_waiting`)
_LOCKSTEP_BLOCKS = 16


def _factor_waiting(sigmas, factors, svs, n, lam, max_cycles, tol, norms, changes, live,
                    coef, variances, corners, rho, support, variance):
    """Algorithm 1 on the ``n`` waiting blocks (kernel covariances ``sigmas``, top-left
    corners ``corners``) in lock step (:func:`~mk_tracker.detection.sparse_factorization.
    _factorize_blocks_one_column`, the same values as one block at a time); writes their
    support and kernel variances (``variances``) into the frame-sized arrays."""
    h, w = support.shape
    factors[:n, :] = 0.0
    _factorize_blocks_one_column(sigmas, factors, svs, n, lam, max_cycles, tol, norms,
                                 changes, live, coef)
    for k in range(n):
        y0 = corners[k, 0]
        x0 = corners[k, 1]
        for dy in range(rho):
            if y0 + dy >= h:
                break
            for dx in range(rho):
                if x0 + dx >= w:
                    break
                i = dy * rho + dx
                variance[y0 + dy, x0 + dx] = variances[k, i]
                support[y0 + dy, x0 + dx] = factors[k, i] != 0.0


_FUSED: list = []


def _fused_kernel():
    """:func:`_support_loops` compiled with numba (with the compiled level kernels and block
    factorizer it calls), or ``None`` without numba / with ``MK_TRACKER_NO_NUMBA`` set."""
    if _FUSED:
        return _FUSED[0]
    level = compiled_level_kernels()
    block = compiled_block_factorizer()
    if level is None or block is None:
        _FUSED.append(None)
        return None
    import numba
    global _levels_block_variance, _levels_block_covariance, _factorize_block
    global _factorize_blocks_one_column, _factor_waiting
    _levels_block_variance = level["block_variance"]
    _levels_block_covariance = level["block_covariance"]
    _factorize_block = block
    _factorize_blocks_one_column = compiled_lockstep_factorizer()
    _factor_waiting = numba.njit(cache=True, nogil=True)(_factor_waiting)
    _drop_stale_cache(_factor_waiting, "_factor_waiting")
    kernel = numba.njit(cache=True, nogil=True)(_support_loops)
    _drop_stale_cache(kernel)
    _FUSED.append(kernel)
    return _FUSED[0]


def _drop_stale_cache(kernel: Any, name: str = "_support_loops") -> bool:
    """numba's disk cache of a function is keyed on its own source file only, but the
    compiled :func:`_support_loops` (and :func:`_factor_waiting`, ``name``) contains the
    level kernels and the block factorizers of two other modules: when their source changes,
    drop its cache (recompiled on first use).
    The sources' digest is kept next to the cache.  Returns whether the cache was dropped."""
    import hashlib
    from mk_tracker.detection import kernel_covariance
    from mk_tracker.detection import sparse_factorization
    digest = hashlib.sha256()
    for module in (kernel_covariance, sparse_factorization):
        with open(module.__file__, "rb") as fh:
            digest.update(fh.read())
    cache = getattr(kernel, "_cache", None)
    cache_path = getattr(cache, "cache_path", None)
    if not cache_path:
        return False                       # no disk cache: nothing can be stale
    path = os.path.join(cache_path, f"block_support.{name}.deps")
    try:
        with open(path, encoding="ascii") as fh:
            if fh.read().strip() == digest.hexdigest():
                return False
    except OSError:
        pass
    try:
        cache.flush()
        os.makedirs(cache_path, exist_ok=True)
        with open(path, "w", encoding="ascii") as fh:
            fh.write(digest.hexdigest())
    except OSError:
        pass           # an unwritable cache: numba compiles in memory anyway
    return True


_TABLES: dict[float, np.ndarray] = {}


def _kernel_table(sigma2: float) -> np.ndarray:
    """Cached :func:`kernel_table` over ``TABLE_LEVELS`` unit steps (bounded cache)."""
    table = _TABLES.get(sigma2)
    if table is None:
        if len(_TABLES) > 16:
            _TABLES.clear()
        table = kernel_table(TABLE_LEVELS - 1, 1.0, sigma2)
        _TABLES[sigma2] = table
    return table
