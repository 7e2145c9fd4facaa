"""Thermal multi-object detector of Schizas, Maroulas & Ren (2018), Secs. 2-5 (Algorithm 2).

Pipeline of one pass over a window of frames:

1. normalise the frames to the kernel's unit scale (:mod:`mk_tracker.detection.thermal_image`);
2. split the region into ``rho x rho`` blocks (divide and conquer, Sec. 5.1); blocks whose
   factor is provably zero are skipped exactly (:mod:`mk_tracker.detection.kernel_covariance`);
3. kernel covariance (3.5) of each remaining block and its sparse factor (3.7) by
   coordinate descent (Algorithm 1, :mod:`mk_tracker.detection.sparse_factorization`); the stacked
   factors (5.1) give the support pixels;
4. K-means with the merge rule (3.12)-(3.13) splits the support into objects
   (:mod:`mk_tracker.detection.pixel_clustering`);
5. each object gets a constant-velocity Kalman filter (2.1)-(2.3), (4.1)-(4.5)
   (:mod:`mk_tracker.kalman`).

Algorithm 2 (streaming, one result per frame from a sliding window): once ``F_s`` frames
have arrived, a *start-up* pass over the whole frame with the last ``F_s`` frames; then, for
every new frame, a *tracking* pass in which each object is searched only in a window around
its Kalman prediction (5.2), ``w_s x h_s`` rounded up to multiples of ``rho``, with the last
``F`` frames; every ``T_c`` frames a *reconfiguration* pass over the whole frame again, so
that objects can appear and disappear.

Where the paper is silent, and what we add (each switchable):

* **Current-frame footprint** (``current_frame_refinement``).  The support of a window's
  factor is the area an object *swept* during the window (pixels that changed), so its
  centroid lags the newest frame by about ``(F-1)/2`` frames.  To report where the object
  is *now*, the detection is the set of pixels inside the swept area whose newest value is
  dissimilar to the local background in the kernel's own sense,
  ``k(x_t(i), background) < 1/2`` with (3.6), the background being the median of the
  non-support pixels around it in the newest frame; the connected components of those
  pixels that touch the support are the object.  Clusters whose footprints share pixels
  are merged (a large object's support can fall apart into bands), and a cluster with no
  footprint is the trail an object has left and is dropped.
* **Linked support** (``link_gap``): support pixels closer than ``link_gap`` px always belong
  to one object, in addition to (3.13).  With (3.13) alone, ``epsilon_d`` must be of the
  order of (half an object)^2, i.e. a size prior; the link rule and the footprint merge
  make the default scale-free at the price of merging people who touch (the optional
  valley split below separates them again; ``link_gap=0, merge_by_footprint=False`` with a
  large ``merge_distance_sq`` is the paper's rule alone).
* **Valley split** (``split_by_valleys``).  A footprint of people who touch is split where
  its intensity has a valley: going down through its threshold sets, a component whose
  maximum stands ``r`` above the level is a peak, ``r = sigma sqrt(2 ln 2)`` being the
  similarity radius of (3.6) (the test that made the pixels foreground against the
  background); peaks with a small core (``valley_min_peak_fraction``: a person's warm
  hands beside the head) are dropped; the footprint is flooded from the peaks, highest
  pixels first (a watershed), one detection per part
  (:func:`mk_tracker.detection.pixel_clustering.valley_split`, compiled).  Full-frame passes split
  every footprint; in a tracking pass an object whose box grew by ``valley_grow_ratio``
  over its last box or its box at the last full-frame pass (it fused with someone it
  touches) keeps the part nearest its prediction.
* The (5.2) window is the object's box plus ``window_margin`` pixels plus the distance the
  Kalman velocity covers in the window's time span on each side, snapped to the ``rho``
  grid so that overlapping windows share blocks (their union is factored once).  Support
  pixels in a window go to the object whose predicted centroid is nearest.
* At a reconfiguration, objects found again keep their Kalman filter (Hungarian matching on
  predicted-centroid distance); the others are kept ``max_missed`` frames, then dropped.
* Objects with fewer than ``min_object_pixels`` support pixels are dropped as noise; an
  object whose window has no support for more than ``max_missed`` frames is dropped until
  the next full-frame pass finds it again (a person who stands still has no temporal change
  and is, as in the paper, not detected).
* Centroids are continuous (pixel ``(c, r)`` has centre ``(c + 0.5, r + 0.5)``), not the
  floor in the definition of Sec. 2.
* Frames: NaN/inf pixels are held at their last valid value (:mod:`mk_tracker.detection.thermal_image`);
  a frame with fewer than ``min_valid_fraction`` valid pixels, or a stamp equal to the
  previous one, is skipped (no detections, ``skipped_frames`` counts it); a frame of another
  size or encoding resets the detector (``resets``, ``last_reset``), and so does a stamp
  earlier than the previous one (a bag played in a loop: ``time_resets``, ``last_event``
  says by how much), after which the new frames fill a new window and detection resumes
  after ``F_s`` of them, as at start-up.  Memory is bounded: a
  ring buffer of ``max(F, F_s)`` frames and at most ``M_up`` objects.

Defaults: only ``sigma^2 = 0.01`` (Sec. 6) and ``sigma_w < 3 px`` (Sec. 4) come from the
paper; the others are ours, chosen on the synthetic scenes (see docs/benchmark_thermal_detector.md).
``lambda`` relates to the exact skip threshold of a pixel's kernel variance by
``T = 3/2 (lambda/2)^(2/3)``: the default 0.15 gives T = 0.267 (a pixel that is object in
one frame of six has 0.28; isolated dropouts of 5% missing pixels mostly stay below).

Speed (docs/profile_thermal_detector.md): with numba installed, integer frames (mono8,
mono16) take compiled paths that do the same arithmetic as the numpy reference paths
(``MK_TRACKER_NO_NUMBA=1`` selects those; tests check both give the same detections):
one loop over the blocks reads the ring buffer in place and runs the skip rule, (3.5) and
Algorithm 1 per block (:func:`_support_loops`); in a tracking pass one call per object
(:func:`_object_loops`) finds its support pixels by one scan of its (5.2) window
(:func:`_owned_loops`), gathers their kernel variances and finds its footprint by one flood
fill (:func:`_footprint_compiled`).  32FC1 frames use the numpy support path.
"""

from __future__ import annotations

import collections
import math
import os
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from mk_tracker.tracking.association import assign
from mk_tracker.boxes import iou
from mk_tracker.kalman import ConstantVelocityKalman, KalmanConfig
from mk_tracker.detection.kernel_covariance import (_levels_block_covariance, _levels_block_variance,
                                          block_kernel_covariance,
                                          block_kernel_covariance_levels,
                                          block_variance_levels, compiled_level_kernels,
                                          kernel_table, pixel_kernel_variance,
                                          range_for_variance)
from mk_tracker.parameters import parameter, validate_config
from mk_tracker.detection.pixel_clustering import (PixelObject, cluster_support_pixels, describe_pixels,
                                         describe_parts, link_groups, merge_linked,
                                         valley_split)
from mk_tracker.detection.sparse_factorization import (_factorize_block, compiled_block_factorizer,
                                             sparse_factorize, zero_factor_threshold)
from mk_tracker.stamps import checked_stamp
from mk_tracker.detection.thermal_image import (ThermalInputError, as_thermal_array, fill_missing,
                                      normalization_map, robust_range, thermal_view)

__all__ = ["ThermalDetectorConfig", "ThermalDetection", "ThermalDetector", "ThermalInputError",
           "SupportResult", "support_in_frame"]


@dataclass(frozen=True)
class ThermalDetectorConfig:
    """Every constant of the detector (paper symbol in brackets)."""

    sigma2: float = parameter(0.01, "[sigma^2] RBF kernel variance (3.6) on the unit "
                              "intensity scale (Sec. 6: 0.01)", minimum=1e-6, maximum=10.0)
    lam: float = parameter(0.15, "[lambda] sparsity weight of (3.7); a pixel whose kernel "
                           "variance is below 3/2 (lambda/2)^(2/3) can never start a support",
                           minimum=0.0, maximum=10.0)
    max_cycles: int = parameter(10, "[kappa] maximum coordinate-descent cycles (Alg. 1)",
                                minimum=1, maximum=1000)
    tol: float = parameter(1e-2, "[epsilon] stop when ||M^k - M^(k-1)|| <= epsilon (Alg. 1)",
                           minimum=0.0, maximum=1.0)
    columns: int = parameter(1, "number of columns of M per block (Sec. 3.3)", minimum=1,
                             maximum=8)
    block_size: int = parameter(4, "[rho] side of the divide-and-conquer blocks (5.1), px",
                                minimum=2, maximum=32)
    window_frames: int = parameter(4, "[F] frames of the sliding window in tracking mode",
                                   minimum=2, maximum=64)
    startup_frames: int = parameter(6, "[F_s] frames of a start-up/reconfiguration pass",
                                    minimum=2, maximum=64)
    reconfigure_period: int = parameter(25, "[T_c] frames between full-frame passes",
                                        minimum=1, maximum=100000)
    merge_distance_sq: float = parameter(150.0, "[epsilon_d] K-means clusters whose centroids "
                                         "are closer than this (px^2) are merged (3.13)",
                                         minimum=0.0, maximum=1e8)
    link_gap: int = parameter(4, "support pixels closer than this (px) always belong to one "
                              "object (added to the merge rule (3.13); 0 = paper rule only)",
                              minimum=0, maximum=1000)
    max_objects: int = parameter(20, "[M_up] upper limit on the number of objects",
                                 minimum=1, maximum=1000)
    min_object_pixels: int = parameter(6, "objects with fewer support pixels are dropped",
                                       minimum=1, maximum=100000)
    window_margin: int = parameter(8, "extra pixels on each side of the (5.2) window",
                                   minimum=0, maximum=1000)
    max_missed: int = parameter(3, "tracking frames without support before an object is "
                                "dropped", minimum=0, maximum=10000)
    current_frame_refinement: bool = parameter(True, "report the object's footprint in the "
                                               "newest frame instead of the swept support")
    normalization: str = parameter("auto", "auto: mono8 / 255, other encodings by the robust "
                                   "range of each full-frame pass; fixed: range_min..range_max",
                                   choices=("auto", "fixed"))
    range_min: float = parameter(0.0, "raw value mapped to 0 (normalization=fixed)")
    range_max: float = parameter(255.0, "raw value mapped to 1 (normalization=fixed)")
    merge_by_footprint: bool = parameter(True, "merge clusters whose newest-frame footprints "
                                         "touch (needs current_frame_refinement)")
    split_by_valleys: bool = parameter(False, "split a footprint where people touch, along "
                                       "the intensity valleys between peaks that each stand "
                                       "out of the valley by the kernel's similarity radius "
                                       "(3.6); in full-frame passes, and in tracking passes "
                                       "when an object's box grows (valley_grow_ratio); not "
                                       "in the paper; needs current_frame_refinement")
    valley_min_peak_fraction: float = parameter(0.4, "split_by_valleys: a peak whose core "
                                                "(pixels within half the similarity radius "
                                                "of its top) is smaller than this fraction "
                                                "of the footprint's largest core is part of "
                                                "a bigger object (a warm hand beside a "
                                                "head); a piece of the footprint with one "
                                                "peak needs this fraction of the pieces' "
                                                "area per peak", minimum=0.0, maximum=1.0)
    valley_grow_ratio: float = parameter(1.3, "split_by_valleys in tracking passes: an "
                                         "object whose box is wider or taller than this "
                                         "times its last box, or its box at the last "
                                         "full-frame pass, is split and keeps the part "
                                         "nearest its prediction", minimum=1.0, maximum=100.0)
    min_valid_fraction: float = parameter(0.5, "frames with fewer finite pixels are skipped",
                                          minimum=0.0, maximum=1.0)
    kalman: KalmanConfig = parameter(KalmanConfig(), "per-object Kalman filter (Sec. 4)")


@dataclass(frozen=True)
class ThermalDetection:
    """One detected object in the newest frame.

    ``box`` ``(x, y, w, h)`` and ``centroid`` ``(cx, cy)`` in pixels; ``score`` in [0, 1]
    (mean kernel variance of the support pixels over 0.5, the variance of a pixel that is
    object in half of the window); ``pixel_count`` pixels of the object; ``object_id`` the
    detector's id of its Kalman filter; ``filtered_centroid`` and ``velocity`` (px/s) that
    filter's estimate after this frame.
    """

    box: tuple[float, float, float, float]
    centroid: tuple[float, float]
    score: float
    pixel_count: int
    object_id: int = -1
    filtered_centroid: tuple[float, float] | None = None
    velocity: tuple[float, float] | None = None


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
             backend: str = "auto") -> SupportResult:
    """:func:`support_in_frame` of the window ``frames[order] - offset`` (``frames`` may be
    the detector's ring buffer: the compiled path reads it in place)."""
    if backend not in ("auto", "numpy", "compiled"):
        raise ThermalInputError(f"unknown backend {backend!r}")
    rho = config.block_size
    _, h, w = frames.shape
    nby, nbx = -(-h // rho), -(-w // rho)
    sigma2 = config.sigma2 / (scale * scale)
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
    return factored


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
    _levels_block_variance = level["block_variance"]
    _levels_block_covariance = level["block_covariance"]
    _factorize_block = block
    kernel = numba.njit(cache=True, nogil=True)(_support_loops)
    _drop_stale_cache(kernel)
    _FUSED.append(kernel)
    return _FUSED[0]


def _drop_stale_cache(kernel: Any) -> bool:
    """numba's disk cache of a function is keyed on its own source file only, but the
    compiled :func:`_support_loops` contains the level kernels and the block factorizer of
    two other modules: when their source changes, drop its cache (recompiled on first use).
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
    path = os.path.join(cache_path, "thermal_detector._support_loops.deps")
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


@dataclass
class _Track:
    """One object of Algorithm 2: its filter, last box, id and bookkeeping."""

    object_id: int
    kf: ConstantVelocityKalman
    box: tuple[float, float, float, float]
    stamp: float
    missed: int = 0
    size: tuple[float, float] = (math.inf, math.inf)   # box size at its last full pass


@dataclass
class _Candidate:
    centroid: tuple[float, float]
    box: tuple[float, float, float, float]
    score: float
    pixel_count: int


#: "not computed yet" marker for a footprint (``None`` means "computed: nothing there")
_UNSET: Any = object()


def _owned_support(support: np.ndarray, regions: list, centres: np.ndarray
                   ) -> list[tuple[int, np.ndarray, np.ndarray]]:
    """For each object ``k``: the number of support pixels in its (5.2) window
    ``regions[k]`` (``(y0, y1, x0, x1)`` or ``None``) and the rows/columns (frame
    row-major order) of those whose centre is at least as close to its prediction
    ``centres[k]`` as to every other one (ties: to both).  Compiled (one scan of each
    window) when numba is available, else numpy over all support pixels (the reference)."""
    empty = np.zeros(0, dtype=np.int64)
    compiled = _owner_kernel()
    if compiled is not None:
        out = []
        for k, region in enumerate(regions):
            if region is None:
                out.append((0, empty, empty))
                continue
            y0, y1, x0, x1 = region
            rows = np.empty((y1 - y0) * (x1 - x0), dtype=np.int64)
            cols = np.empty_like(rows)
            n_inside, n_mine = compiled(support, y0, y1, x0, x1, centres, k, rows, cols)
            out.append((int(n_inside), rows[:n_mine], cols[:n_mine]))
        return out
    live = [r for r in regions if r is not None]
    if not live:
        return [(0, empty, empty) for _ in regions]
    uy0, uy1 = min(r[0] for r in live), max(r[1] for r in live)
    ux0, ux1 = min(r[2] for r in live), max(r[3] for r in live)
    rows, cols = np.nonzero(support[uy0:uy1, ux0:ux1])
    rows += uy0
    cols += ux0
    px = cols + 0.5
    py = rows + 0.5
    dist = (px[:, None] - centres[None, :, 0]) ** 2 + (py[:, None] - centres[None, :, 1]) ** 2
    bounds = np.array([r if r is not None else (0, 0, 0, 0) for r in regions])
    r, cl = rows[:, None], cols[:, None]
    inside = ((r >= bounds[None, :, 0]) & (r < bounds[None, :, 1])
              & (cl >= bounds[None, :, 2]) & (cl < bounds[None, :, 3]))
    mine = inside & (dist <= dist.min(axis=1)[:, None])
    n_inside = np.count_nonzero(inside, axis=0)
    return [(int(n_inside[k]), rows[mine[:, k]], cols[mine[:, k]]) for k in range(len(regions))]


def _owned_loops(support, y0, y1, x0, x1, centres, k, rows, cols):
    """Compiled :func:`_owned_support` of one window: same distances, same order.
    Returns ``(support pixels in the window, owned pixels written to rows/cols)``."""
    n_inside = 0
    n_mine = 0
    for y in range(y0, y1):
        for x in range(x0, x1):
            if not support[y, x]:
                continue
            n_inside += 1
            px = x + 0.5
            py = y + 0.5
            own = (px - centres[k, 0]) ** 2 + (py - centres[k, 1]) ** 2
            nearest = True
            for j in range(centres.shape[0]):
                if j != k and (px - centres[j, 0]) ** 2 + (py - centres[j, 1]) ** 2 < own:
                    nearest = False
                    break
            if nearest:
                rows[n_mine] = y
                cols[n_mine] = x
                n_mine += 1
    return n_inside, n_mine


_OWNER: list = []


def _owner_kernel():
    """:func:`_owned_loops` compiled with numba, or ``None`` (no numba, or
    ``MK_TRACKER_NO_NUMBA`` set)."""
    if not _OWNER:
        try:
            if os.environ.get("MK_TRACKER_NO_NUMBA"):
                raise ImportError("disabled by MK_TRACKER_NO_NUMBA")
            import numba
            _OWNER.append(numba.njit(cache=True, nogil=True)(_owned_loops))
        except ImportError:
            _OWNER.append(None)
    return _OWNER[0]


class _VoronoiCell:
    """Pixels whose centre is at least as close to prediction ``k`` as to every other one
    (the (5.2) windows of neighbours overlap; each pixel goes to the nearest prediction)."""

    def __init__(self, centres: np.ndarray, k: int) -> None:
        self.centres = centres
        self.k = k

    def __call__(self, y0: int, y1: int, x0: int, x1: int) -> np.ndarray:
        """Bool mask of the cell over rows ``y0:y1``, columns ``x0:x1``."""
        gx = np.arange(x0, x1) + 0.5
        gy = (np.arange(y0, y1) + 0.5)[:, None]
        cx, cy = self.centres[self.k]
        d_own = (gx - cx) ** 2 + (gy - cy) ** 2
        allowed = np.ones(d_own.shape, dtype=bool)
        # a prediction farther from the patch than the patch's farthest corner is from the
        # own prediction can win no pixel of it (exact skip)
        reach = max(abs(x0 - cx), abs(x1 - cx)) ** 2 + max(abs(y0 - cy), abs(y1 - cy)) ** 2
        for j, (ox, oy) in enumerate(self.centres):
            if j == self.k:
                continue
            dx = max(x0 - ox, 0.0, ox - x1)
            dy = max(y0 - oy, 0.0, oy - y1)
            if dx * dx + dy * dy > reach:
                continue
            allowed &= d_own <= (gx - ox) ** 2 + (gy - oy) ** 2
        return allowed


_NO_CENTRES = np.zeros((0, 2))


def _footprint_loops(frame, offset, y0, x0, level, radius, rows, cols, centres, k, state,
                     stats):
    """Compiled footprint of :meth:`ThermalDetector._footprint` over the patch of ``state``
    (``(ph, pw)`` int8 zeros at ``(y0, x0)``; values ``frame - offset``): the polarity from
    the support pixels ``(rows, cols)``, then a flood fill (8-connectivity) from them
    through the pixels with ``polarity * (frame - offset - level) > radius`` that lie in the
    Voronoi cell of ``centres[k]`` (``k < 0``: no cell).  Same arithmetic as the numpy path.
    Marks the object's pixels 1 (others visited 2) and returns their number (0: none);
    ``stats`` (int64, 6) receives their patch-coordinate sums and extremes
    ``(sum_c, sum_r, c_min, c_max, r_min, r_max)``, gathered as they are marked."""
    n_seeds = rows.shape[0]
    valid = 0
    warmer = 0
    for s in range(n_seeds):
        d = (frame[rows[s], cols[s]] - offset) - level
        if abs(d) > radius:
            valid += 1
            if d > 0:
                warmer += 1
    if valid == 0:
        return 0
    polarity = np.float32(1.0) if 2 * warmer >= valid else np.float32(-1.0)
    ph, pw = state.shape
    stack_r = np.empty(ph * pw, dtype=np.int32)   # every pixel is pushed at most once
    stack_c = np.empty(ph * pw, dtype=np.int32)
    top = 0
    count = 0
    sum_c = 0
    sum_r = 0
    c_min = pw
    c_max = -1
    r_min = ph
    r_max = -1
    for s in range(n_seeds):
        r0 = rows[s] - y0
        c0 = cols[s] - x0
        if state[r0, c0] != 0:
            continue
        if not _in_footprint(frame, offset, r0 + y0, c0 + x0, level, polarity, radius,
                             centres, k):
            state[r0, c0] = 2
            continue
        state[r0, c0] = 1
        stack_r[0] = r0
        stack_c[0] = c0
        top = 1
        while top > 0:               # every pixel on the stack is marked 1: count it here
            top -= 1
            r = stack_r[top]
            c = stack_c[top]
            count += 1
            sum_c += c
            sum_r += r
            c_min = min(c_min, c)
            c_max = max(c_max, c)
            r_min = min(r_min, r)
            r_max = max(r_max, r)
            for rr in range(max(r - 1, 0), min(r + 2, ph)):
                for cc in range(max(c - 1, 0), min(c + 2, pw)):
                    if state[rr, cc] != 0:
                        continue
                    if _in_footprint(frame, offset, rr + y0, cc + x0, level, polarity,
                                     radius, centres, k):
                        state[rr, cc] = 1
                        stack_r[top] = rr
                        stack_c[top] = cc
                        top += 1
                    else:
                        state[rr, cc] = 2
    stats[0] = sum_c
    stats[1] = sum_r
    stats[2] = c_min
    stats[3] = c_max
    stats[4] = r_min
    stats[5] = r_max
    return count


def _background_level(frame, offset, support, y0, y1, x0, x1, buf):
    """Median (as :func:`_median`) of a stride sample of at most ~2048 of the non-support
    pixels of ``frame[y0:y1, x0:x1] - offset`` in row-major order, like the numpy path's
    ``patch[~support][::step]``; NaN when there is none."""
    n = 0
    for y in range(y0, y1):
        for x in range(x0, x1):
            if not support[y, x]:
                buf[n] = frame[y, x] - offset
                n += 1
    if n == 0:
        return np.float32(np.nan)
    step = max(1, n // 2048)
    return _sample_median(buf[0:n:step])


def _sample_median(sample):
    """:func:`_median` of a float32 sample, compiled: by counting when the values are
    integers spanning less than 65536 (integer encodings; the same order statistics
    exactly), else by a partition."""
    size = sample.shape[0]
    half = size // 2
    lo = sample[0]
    hi = sample[0]
    integral = True
    for i in range(size):
        v = sample[i]
        if v < lo:
            lo = v
        elif v > hi:
            hi = v
        if v != np.floor(v):
            integral = False
    if integral and hi - lo < 65536:
        counts = np.zeros(int(hi - lo) + 1, dtype=np.int64)
        for i in range(size):
            counts[int(sample[i] - lo)] += 1
        seen = 0
        below = lo
        for level in range(counts.shape[0]):
            seen += counts[level]
            if seen >= half and seen - counts[level] < half:
                below = lo + level                  # element half - 1 (0-based)
            if seen > half:
                middle = np.float32(lo + level)     # element half
                if size % 2:
                    return middle
                return np.float32((np.float32(below) + middle) / np.float32(2.0))
    part = np.partition(sample.copy(), half)
    if size % 2:
        return part[half]
    below = part[0]
    for i in range(1, half):
        if part[i] > below:
            below = part[i]
    return np.float32((below + part[half]) / np.float32(2.0))


def _footprint_compiled(frame, offset, support, by0, by1, bx0, bx1, rows, cols, margin, radius,
                        centres, k):
    """All of :meth:`ThermalDetector._footprint` in one compiled call: the patch, the
    background level, the flood fill (:func:`_footprint_loops`) and the footprint's pixel
    statistics.  Returns ``(y0, x0, state, count, sum_x, sum_y, x_min, x_max, y_min,
    y_max)`` (frame coordinates; ``count`` 0: no footprint)."""
    r0 = rows.min()
    r1 = rows.max() + 1
    c0 = cols.min()
    c1 = cols.max() + 1
    m = margin + max(r1 - r0, c1 - c0) // 2
    y0 = max(r0 - m, by0)
    y1 = min(r1 + m, by1)
    x0 = max(c0 - m, bx0)
    x1 = min(c1 + m, bx1)
    state = np.zeros((y1 - y0, x1 - x0), dtype=np.int8)
    buf = np.empty((by1 - by0) * (bx1 - bx0), dtype=frame.dtype)
    level = _background_level(frame, offset, support, y0, y1, x0, x1, buf)
    if np.isnan(level):
        level = _background_level(frame, offset, support, by0, by1, bx0, bx1, buf)
    if np.isnan(level):
        return y0, x0, state, 0, 0, 0, 0, 0, 0, 0
    stats = np.zeros(6, dtype=np.int64)
    count = _footprint_loops(frame, offset, y0, x0, level, radius, rows, cols, centres, k,
                             state, stats)
    if count == 0:
        return y0, x0, state, 0, 0, 0, x1, -1, y1, -1
    # integer sums: the order in which the fill met the pixels does not matter
    return (y0, x0, state, count, stats[0] + count * x0, stats[1] + count * y0,
            stats[2] + x0, stats[3] + x0, stats[4] + y0, stats[5] + y0)


def _in_footprint(frame, offset, y, x, level, polarity, radius, centres, k):
    """Pixel test of :func:`_footprint_loops`: dissimilar to the background on the object's
    side, and in the Voronoi cell of ``centres[k]`` (ties included) when ``k >= 0``."""
    if not ((frame[y, x] - offset) - level) * polarity > radius:
        return False
    if k < 0:
        return True
    gx = x + 0.5
    gy = y + 0.5
    d_own = (gx - centres[k, 0]) ** 2 + (gy - centres[k, 1]) ** 2
    for j in range(centres.shape[0]):
        if j != k and d_own > (gx - centres[j, 0]) ** 2 + (gy - centres[j, 1]) ** 2:
            return False
    return True


_FOOTPRINT: list = []


def _footprint_kernel():
    """:func:`_footprint_compiled` compiled with numba, or ``None`` (no numba, or
    ``MK_TRACKER_NO_NUMBA`` set)."""
    if not _FOOTPRINT:
        try:
            if os.environ.get("MK_TRACKER_NO_NUMBA"):
                raise ImportError("disabled by MK_TRACKER_NO_NUMBA")
            import numba
            global _in_footprint, _footprint_loops, _background_level, _sample_median
            _sample_median = numba.njit(cache=True, nogil=True)(_sample_median)
            _in_footprint = numba.njit(cache=True, nogil=True)(_in_footprint)
            _footprint_loops = numba.njit(cache=True, nogil=True)(_footprint_loops)
            _background_level = numba.njit(cache=True, nogil=True)(_background_level)
            _FOOTPRINT.append(numba.njit(cache=True, nogil=True)(_footprint_compiled))
        except ImportError:
            _FOOTPRINT.append(None)
    return _FOOTPRINT[0]


def _object_loops(frame, offset, support, variance, y0, y1, x0, x1, centres, k, cell_centres,
                  cell_k, min_pixels, margin, radius, values):
    """One object of a tracking pass in one compiled call: its support pixels in its (5.2)
    window ``(y0, y1, x0, x1)`` and those it owns (:func:`_owned_loops`); when both number
    at least ``min_pixels``, the kernel variances of the owned ones (in their order, into
    ``values``, one slot per window pixel) and their footprint (:func:`_footprint_compiled`
    with the Voronoi cell ``cell_centres``, ``cell_k``).  Returns ``(n_inside, n_owned,
    count, sum_x, sum_y, x_min, x_max, y_min, y_max)``; ``count`` 0: no footprint (or not
    searched)."""
    size = (y1 - y0) * (x1 - x0)
    rows = np.empty(size, dtype=np.int64)
    cols = np.empty(size, dtype=np.int64)
    near = _near_centres(centres, k, y0, y1, x0, x1)
    n_inside, n_mine = _owned_loops(support, y0, y1, x0, x1, near, 0, rows, cols)
    if n_inside < min_pixels or n_mine < min_pixels:
        return n_inside, n_mine, 0, 0, 0, 0, 0, 0, 0
    for i in range(n_mine):
        values[i] = variance[rows[i], cols[i]]
    if cell_k >= 0:                 # the footprint patch lies inside the window
        cell_centres = _near_centres(cell_centres, cell_k, y0, y1, x0, x1)
        cell_k = 0
    _, _, _, count, sx, sy, xmin, xmax, ymin, ymax = _footprint_compiled(
        frame, offset, support, y0, y1, x0, x1, rows[:n_mine], cols[:n_mine], margin, radius,
        cell_centres, cell_k)
    return n_inside, n_mine, count, sx, sy, xmin, xmax, ymin, ymax


def _near_centres(centres, k, y0, y1, x0, x1):
    """``centres[k]`` followed by the other centres that can be nearer than it to some pixel
    centre of rows ``y0:y1``, columns ``x0:x1`` -- the Voronoi tests against the others
    always pass there, so leaving them out changes no test.  A centre is left out only when
    its distance to the pixel-centre box exceeds the own centre's distance to the box's
    farthest corner by a wide margin (1e-9 relative, far above the rounding of either)."""
    n = centres.shape[0]
    near = np.empty((n, 2))
    near[0, 0] = centres[k, 0]
    near[0, 1] = centres[k, 1]
    if n == 1:
        return near
    gx0, gx1 = x0 + 0.5, x1 - 0.5
    gy0, gy1 = y0 + 0.5, y1 - 0.5
    cx, cy = centres[k, 0], centres[k, 1]
    far = max((gx0 - cx) ** 2, (gx1 - cx) ** 2) + max((gy0 - cy) ** 2, (gy1 - cy) ** 2)
    bound = far * (1.0 + 1e-9) + 1e-6
    m = 1
    for j in range(n):
        if j == k:
            continue
        dx = max(gx0 - centres[j, 0], 0.0, centres[j, 0] - gx1)
        dy = max(gy0 - centres[j, 1], 0.0, centres[j, 1] - gy1)
        if dx * dx + dy * dy > bound:
            continue
        near[m, 0] = centres[j, 0]
        near[m, 1] = centres[j, 1]
        m += 1
    return near[:m]


_OBJECT: list = []


def _object_kernel():
    """:func:`_object_loops` compiled with numba, or ``None`` (no numba, or
    ``MK_TRACKER_NO_NUMBA`` set)."""
    if not _OBJECT:
        owner, footprint = _owner_kernel(), _footprint_kernel()
        if owner is None or footprint is None:
            _OBJECT.append(None)
        else:
            import numba
            global _owned_loops, _footprint_compiled, _near_centres
            _owned_loops, _footprint_compiled = owner, footprint
            _near_centres = numba.njit(cache=True, nogil=True)(_near_centres)
            _OBJECT.append(numba.njit(cache=True, nogil=True)(_object_loops))
    return _OBJECT[0]


def _median(values: np.ndarray) -> np.float32:
    """``np.median`` of a 1-D float32 array (same value: the middle element, or the float32
    mean of the two middle ones), by one partition without numpy's generic reduction."""
    n = values.size
    half = n // 2
    if n % 2:
        return np.float32(np.partition(values, half)[half])
    part = np.partition(values, (half - 1, half))
    return np.float32((part[half - 1] + part[half]) / np.float32(2.0))


def _overlap(a: tuple, b: tuple) -> bool:
    """Whether boxes ``(x, y, w, h)`` share area: the test of
    :func:`mk_tracker.boxes.intersection_area` (False there means an IoU of 0)."""
    return (min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0]) > 0
            and min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1]) > 0)


def _similarity_radius(sigma2: float) -> float:
    """``|a - b|`` at which the kernel (3.6) equals 1/2: ``sigma sqrt(2 ln 2)``."""
    return math.sqrt(2.0 * sigma2 * math.log(2.0))


class ThermalDetector:
    """Streaming detector (Algorithm 2).  Feed frames in time order with :meth:`process`.

    Counters the node can log: ``resets`` (frame size or encoding changed, or time went
    backwards), ``time_resets`` (the latter only), ``skipped_frames`` (too few valid pixels,
    or the same stamp as the previous frame), ``full_passes``; ``last_mode`` is one of
    ``warming_up``, ``startup``, ``reconfiguration``, ``tracking``, ``invalid_frame``,
    ``out_of_order``; ``last_reset`` says whether the last frame reset the detector and
    ``last_event`` why (e.g. ``"time went backwards by 4.000 s: reset"``), else None.
    """

    def __init__(self, config: ThermalDetectorConfig | None = None) -> None:
        self.config = config if config is not None else ThermalDetectorConfig()
        validate_config(self.config)
        c = self.config
        if c.normalization == "fixed" and not c.range_max > c.range_min:
            raise ThermalInputError("range_max must be above range_min for fixed normalisation")
        # (ring slot, stamp) of the frames in the window, oldest first; the frames themselves
        # live in the ring buffer self._ring (one array, no per-frame stacking)
        self._buffer: collections.deque = collections.deque(
            maxlen=max(c.window_frames, c.startup_frames))
        self.resets = 0
        self.time_resets = 0
        self.last_event: str | None = None
        self.skipped_frames = 0
        self.full_passes = 0
        self.last_mode = "warming_up"
        self.last_reset = False
        self._clear()

    # -- state -----------------------------------------------------------------------------
    def _clear(self) -> None:
        self._buffer.clear()
        self._shape: tuple[int, int] | None = None
        self._encoding: str | None = None
        self._last_stamp: float | None = None
        self._last_filled: np.ndarray | None = None
        self._tracks: list[_Track] = []
        self._next_id = 1
        self._since_full: int | None = None
        self._map: tuple[float, float] | None = None
        self._integer = False
        self._ring: np.ndarray | None = None
        self._frames_seen = 0

    def reset(self) -> None:
        """Forget every frame and object (counters are kept)."""
        self._clear()
        self.last_mode = "warming_up"

    @property
    def tracks(self) -> list[tuple[int, np.ndarray]]:
        """``(object_id, Kalman state)`` of the objects currently followed."""
        return [(t.object_id, t.kf.state) for t in self._tracks]

    # -- entry point -----------------------------------------------------------------------
    def process(self, frame: Any, stamp: float, encoding: str | None = None
                ) -> list[ThermalDetection]:
        """Detections in ``frame`` (raw array as received) taken at ``stamp`` seconds."""
        raw, enc = thermal_view(frame, encoding)
        if enc == "32FC1":
            raw, enc = as_thermal_array(raw, enc)        # float copy, missing pixels NaN
        # integer frames stay as received: they are converted once, into the ring buffer
        t = checked_stamp(stamp, ThermalInputError)
        self.last_reset = False
        self.last_event = None
        if self._shape is not None and (raw.shape != self._shape or enc != self._encoding):
            self.last_event = (f"frame {raw.shape[1]}x{raw.shape[0]} {enc} differs from the "
                               f"previous {self._shape[1]}x{self._shape[0]} {self._encoding}: "
                               "reset")
            self._clear()
            self.resets += 1
            self.last_reset = True
        elif self._last_stamp is not None and t < self._last_stamp:
            # a looping bag: skipping every frame until the stamps pass the old newest one
            # would stall detection for a whole loop; start a new window from this frame
            self.last_event = f"time went backwards by {self._last_stamp - t:.3f} s: reset"
            self._clear()
            self.resets += 1
            self.time_resets += 1
            self.last_reset = True
        # integer encodings cannot hold missing pixels: only float frames are checked
        n_valid = np.count_nonzero(np.isfinite(raw)) if enc == "32FC1" else raw.size
        if n_valid < self.config.min_valid_fraction * raw.size or n_valid == 0:
            self.skipped_frames += 1
            self.last_mode = "invalid_frame"
            return []
        if self._last_stamp is not None and t == self._last_stamp:
            self.skipped_frames += 1
            self.last_mode = "out_of_order"
            return []
        filled = raw
        if enc == "32FC1":
            filled, _ = fill_missing(raw, self._last_filled)
            self._last_filled = filled
        else:
            self._last_filled = None      # only float frames are filled from the previous one
        self._shape, self._encoding, self._last_stamp = raw.shape, enc, t
        n_slots = self._buffer.maxlen
        if self._ring is None or self._ring.shape[1:] != filled.shape:
            self._ring = np.empty((n_slots,) + filled.shape, dtype=np.float32)
        slot = self._frames_seen % n_slots
        self._frames_seen += 1
        self._ring[slot] = filled
        self._buffer.append((slot, t))
        c = self.config
        if self._since_full is None:
            if len(self._buffer) < c.startup_frames:
                self.last_mode = "warming_up"
                return []
            self.last_mode = "startup"
            return self._full_pass()
        self._since_full += 1
        if self._since_full >= c.reconfigure_period:
            self.last_mode = "reconfiguration"
            return self._full_pass()
        self.last_mode = "tracking"
        return self._tracking_pass()

    # -- normalisation ---------------------------------------------------------------------
    def _update_map(self, frames: list[np.ndarray]) -> None:
        """Choose ``(offset, scale)`` for the next windows; integer offsets for integer
        encodings so that their windows hold integer levels (table path)."""
        c = self.config
        if c.normalization == "fixed":
            offset, scale = normalization_map(self._encoding, (c.range_min, c.range_max))
        elif self._encoding == "mono8":
            offset, scale = normalization_map("mono8", None)
        else:
            rng = robust_range(np.stack(frames))
            offset, scale = normalization_map(self._encoding, rng if rng else (0.0, 1.0))
        integer = self._encoding in ("mono8", "mono16")
        if integer:
            offset = float(math.floor(offset))
        self._map = (offset, scale)
        self._integer = integer and float(offset).is_integer()

    def _order(self, n_frames: int) -> np.ndarray:
        """Ring slots of the last ``n_frames`` frames, oldest first."""
        n = min(n_frames, len(self._buffer))
        return np.array([self._buffer[i][0] for i in range(len(self._buffer) - n,
                                                             len(self._buffer))], dtype=np.int64)

    def _newest(self) -> np.ndarray:
        """The newest frame as stored (raw, float32; window units are ``raw - offset``)."""
        return self._ring[self._buffer[-1][0]]

    # -- passes ----------------------------------------------------------------------------
    def _full_pass(self) -> list[ThermalDetection]:
        """Algorithm 2, line 1: start-up / reconfiguration over the whole frame, F_s frames."""
        c = self.config
        self.full_passes += 1
        self._since_full = 0
        order = self._order(c.startup_frames)
        self._update_map([self._ring[i] for i in order])
        result = _support(self._ring, order, self._map[0], c, self._map[1], self._integer, None)
        frame = self._newest()
        bounds = (0, frame.shape[0], 0, frame.shape[1])
        rows, cols = np.nonzero(result.support)
        candidates: list[_Candidate] = []
        if rows.size:
            _, labels = cluster_support_pixels(np.column_stack([cols, rows]),
                                               max_objects=c.max_objects,
                                               merge_distance_sq=c.merge_distance_sq)
            if c.link_gap > 0:
                labels = merge_linked(labels, link_groups(result.support, c.link_gap)[rows, cols])
            groups = [np.flatnonzero(labels == k) for k in range(int(labels.max()) + 1)]
            groups = [g for g in groups if g.size >= c.min_object_pixels]
            footprints: list[Any] = [_UNSET] * len(groups)
            if c.current_frame_refinement and c.merge_by_footprint and len(groups) > 1:
                groups, footprints = self._merge_by_footprint(frame, result.support, rows,
                                                              cols, groups, bounds)
            for g, fp in zip(groups, footprints):
                if c.current_frame_refinement and c.split_by_valleys:
                    candidates.extend(self._valley_candidates(frame, result, rows[g], cols[g],
                                                              bounds, fp))
                    continue
                cand = self._candidate(frame, result, rows[g], cols[g], bounds, footprint=fp)
                if cand is not None:
                    candidates.append(cand)
        return self._reassociate(candidates)

    def _valley_candidates(self, frame: np.ndarray, result: SupportResult, rows: np.ndarray,
                           cols: np.ndarray, bounds: tuple[int, int, int, int],
                           footprint: Any) -> list[_Candidate]:
        """Detections of one group's footprint split along its intensity valleys
        (:meth:`_valley_parts`): touching people whose footprints fused are one part each; a
        footprint with one peak is one detection, as :meth:`_candidate` gives it."""
        c = self.config
        fp = footprint
        if fp is _UNSET:
            fp = self._footprint(frame, result.support, rows, cols, bounds)
        if fp is None:
            return []
        score = float(min(1.0, result.variance[rows, cols].mean() / 0.5))
        parts = self._valley_parts(frame, fp)
        if parts is None:
            (y0, x0), mask = fp
            fr, fc = np.nonzero(mask)
            if fr.size < c.min_object_pixels:
                return []
            now = describe_pixels(fc + x0, fr + y0)
            parts = [(now.centroid, now.box, now.pixel_count)]
        return [_Candidate(centroid, box, score, n) for centroid, box, n in parts]

    def _valley_parts(self, frame: np.ndarray, footprint: tuple[tuple[int, int], np.ndarray]
                      ) -> list[tuple[tuple[float, float], tuple[float, float, float, float],
                                      int]] | None:
        """``(centroid, box, pixel_count)`` of each part of a footprint split along its
        intensity valleys (:func:`mk_tracker.detection.pixel_clustering.valley_split` with depth = the
        kernel's similarity radius, so each part is dissimilar, k < 1/2, to the valley that
        separates it); parts smaller than ``min_object_pixels`` are left out.  ``None``
        when the footprint has one peak (it does not split)."""
        c = self.config
        (y0, x0), mask = footprint
        h, w = mask.shape
        patch = frame[y0:y0 + h, x0:x0 + w]
        # the side of the background the footprint is on (all of it is on one side): its
        # mean against the median of the patch's border pixels off the footprint
        ring = np.concatenate([patch[0], patch[-1], patch[1:-1, 0], patch[1:-1, -1]])
        off = ring[~np.concatenate([mask[0], mask[-1], mask[1:-1, 0], mask[1:-1, -1]])]
        polarity = 1.0
        if off.size:
            polarity = 1.0 if float(patch[mask].mean()) >= float(_median(off)) else -1.0
        depth = _similarity_radius(c.sigma2) / self._map[1]          # window units
        n, labels = valley_split(patch * np.float32(polarity), mask, depth,
                                 min_area=c.min_object_pixels,
                                 min_peak_fraction=c.valley_min_peak_fraction)
        if n <= 1:
            return None
        out = []
        for cnt, sx, sy, xmin, xmax, ymin, ymax in describe_parts(labels, n).tolist():
            if cnt < c.min_object_pixels:
                continue
            out.append(((sx / cnt + 0.5 + x0, sy / cnt + 0.5 + y0),
                        (float(xmin + x0), float(ymin + y0), float(xmax + 1 - xmin),
                         float(ymax + 1 - ymin)), int(cnt)))
        return out

    def _split_grown(self, frame: np.ndarray, result: SupportResult, regions: list,
                     centres: np.ndarray, k: int, cand: _Candidate,
                     owned: tuple[int, np.ndarray, np.ndarray] | None = None) -> _Candidate:
        """Tracking pass: object ``k``'s footprint grew past ``valley_grow_ratio`` times its
        last box or its box at the last full-frame pass (it fused with someone it touches):
        the part of the footprint, split along its valleys, nearest its prediction
        (``cand`` when it does not split).  ``owned``: object ``k``'s entry of
        :func:`_owned_support` when the caller has it (the numpy path); the compiled path
        does not keep the owned pixels, so they are found again here."""
        if owned is None:
            only = [r if j == k else None for j, r in enumerate(regions)]
            owned = _owned_support(result.support, only, centres)[k]
        _, rows, cols = owned
        if rows.size < self.config.min_object_pixels:
            return cand
        cell = _VoronoiCell(centres, k) if len(centres) > 1 else None
        fp = self._footprint(frame, result.support, rows, cols, regions[k], cell)
        if fp is None:
            return cand
        parts = self._valley_parts(frame, fp)
        if not parts:
            return cand
        px, py = centres[k]
        centroid, box, n = min(parts, key=lambda q: math.dist(q[0], (px, py)))
        return _Candidate(centroid, box, cand.score, n)

    def _merge_by_footprint(self, frame: np.ndarray, support: np.ndarray, rows: np.ndarray,
                            cols: np.ndarray, groups: list[np.ndarray],
                            bounds: tuple[int, int, int, int]
                            ) -> tuple[list[np.ndarray], list[Any]]:
        """Clusters whose newest-frame footprints share pixels are one object (a large
        object's swept support can fall apart into bands; its footprint does not).

        Returns the merged groups and, for each, its footprint when it was computed here
        (a group left alone) or ``_UNSET`` (a merged group: recomputed by the caller)."""
        owner = np.full(frame.shape, -1, dtype=np.int64)
        parent = list(range(len(groups)))

        def find(a: int) -> int:
            while parent[a] != a:
                parent[a] = parent[parent[a]]
                a = parent[a]
            return a

        prints = []
        for k, g in enumerate(groups):
            fp = self._footprint(frame, support, rows[g], cols[g], bounds)
            prints.append(fp)
            if fp is None:
                continue
            (y0, x0), mask = fp
            region = owner[y0:y0 + mask.shape[0], x0:x0 + mask.shape[1]]
            for other in np.unique(region[mask & (region >= 0)]):
                parent[find(int(other))] = find(k)
            region[mask] = k
        merged: dict[int, list[int]] = {}
        for k in range(len(groups)):
            merged.setdefault(find(k), []).append(k)
        out_groups = [np.concatenate([groups[k] for k in v]) for v in merged.values()]
        out_prints = [prints[v[0]] if len(v) == 1 else _UNSET for v in merged.values()]
        return out_groups, out_prints

    def _footprint(self, frame: np.ndarray, support: np.ndarray, rows: np.ndarray,
                   cols: np.ndarray, bounds: tuple[int, int, int, int],
                   cell: _VoronoiCell | None = None
                   ) -> tuple[tuple[int, int], np.ndarray] | None:
        """Newest-frame pixels of the object whose support is ``(rows, cols)`` (frame
        coordinates; ``frame`` is the newest frame as stored, window units are
        ``frame - offset``), searched inside ``bounds`` ``(y0, y1, x0, x1)`` (its (5.2)
        window, or the frame).

        Inside the support's bounding box grown by ``window_margin`` plus half its larger
        side (parts of the object that did not move have no support), the pixels dissimilar
        to the local background (kernel (3.6) below 1/2; background = median of the
        non-support pixels there) and on the same side of it as most of the support (warmer or
        colder) form connected components; those touching the support are the object.
        ``cell`` (the object's :class:`_VoronoiCell`), when given, restricts them.
        Returns ``((y0, x0), mask)`` in frame coordinates, or ``None`` when there is nothing.

        The thresholding and the components are one compiled flood fill from the support
        pixels (:func:`_footprint_loops`) when numba is available, else numpy and
        ``cv2.connectedComponents`` (the reference; a test checks they agree).
        """
        c = self.config
        stats = self._footprint_stats(frame, support, rows, cols, bounds, cell)
        if stats is not _UNSET:
            if stats is None:
                return None
            return stats[0], stats[1] == 1
        by0, by1, bx0, bx1 = bounds
        r0, r1, c0, c1 = int(rows.min()), int(rows.max()) + 1, int(cols.min()), int(cols.max()) + 1
        m = c.window_margin + max(r1 - r0, c1 - c0) // 2       # room for parts that stood still
        y0, y1 = max(r0 - m, by0), min(r1 + m, by1)
        x0, x1 = max(c0 - m, bx0), min(c1 + m, bx1)
        offset = np.float32(self._map[0])
        patch = frame[y0:y1, x0:x1] - offset                 # window units
        background = patch[~support[y0:y1, x0:x1]]
        if background.size == 0:
            background = (frame[by0:by1, bx0:bx1] - offset)[~support[by0:by1, bx0:bx1]]
        if background.size == 0:
            return None
        step = max(1, background.size // 2048)     # a stride sample is enough for a median
        level = _median(background[::step])
        radius = np.float32(_similarity_radius(c.sigma2) / self._map[1])   # window units
        diff = patch - level
        at_support = diff[rows - y0, cols - x0]
        at_support = at_support[np.abs(at_support) > radius]
        if at_support.size == 0:
            return None
        # one polarity: a warm person in front of a cold pillar is not one object with it
        polarity = np.float32(1.0 if 2 * np.count_nonzero(at_support > 0) >= at_support.size
                              else -1.0)
        fg = (diff * polarity > radius).astype(np.uint8)
        if cell is not None:
            fg &= cell(y0, y1, x0, x1).astype(np.uint8)
        n, labels = cv2.connectedComponents(fg, connectivity=8)
        if n <= 1:
            return None
        lut = np.zeros(n, dtype=bool)
        lut[labels[rows - y0, cols - x0]] = True
        lut[0] = False
        if not lut.any():
            return None
        return (y0, x0), lut[labels]

    def _footprint_stats(self, frame: np.ndarray, support: np.ndarray, rows: np.ndarray,
                         cols: np.ndarray, bounds: tuple[int, int, int, int],
                         cell: _VoronoiCell | None) -> Any:
        """The compiled footprint: ``((y0, x0), state, PixelObject)`` or ``None`` (nothing);
        ``_UNSET`` when numba is not available."""
        compiled = _footprint_kernel()
        if compiled is None:
            return _UNSET
        centres, k = (cell.centres, cell.k) if cell is not None else (_NO_CENTRES, -1)
        radius = np.float32(_similarity_radius(self.config.sigma2) / self._map[1])
        y0, x0, state, n, sx, sy, xmin, xmax, ymin, ymax = compiled(
            frame, np.float32(self._map[0]), support, bounds[0], bounds[1], bounds[2],
            bounds[3], rows, cols,
            self.config.window_margin, radius, centres, k)
        if n == 0:
            return None
        # describe_pixels of the footprint: continuous centroid, box, count
        obj = PixelObject(centroid=(sx / n + 0.5, sy / n + 0.5),
                          box=(float(xmin), float(ymin), float(xmax + 1 - xmin),
                               float(ymax + 1 - ymin)), pixel_count=int(n))
        return (y0, x0), state, obj

    def _candidate(self, frame: np.ndarray, result: SupportResult, rows: np.ndarray,
                   cols: np.ndarray, bounds: tuple[int, int, int, int],
                   cell: _VoronoiCell | None = None, footprint: Any = _UNSET
                   ) -> _Candidate | None:
        """Detection from support pixels ``(rows, cols)`` (frame coordinates); ``footprint``
        is reused when the caller has it already (``_UNSET``: compute it)."""
        c = self.config
        score = float(min(1.0, result.variance[rows, cols].mean() / 0.5))
        if not c.current_frame_refinement:
            swept = describe_pixels(cols, rows)
            return _Candidate(swept.centroid, swept.box, score, swept.pixel_count)
        fp = footprint
        if fp is _UNSET:
            stats = self._footprint_stats(frame, result.support, rows, cols, bounds, cell)
            if stats is not _UNSET:
                if stats is None or stats[2].pixel_count < c.min_object_pixels:
                    return None
                now = stats[2]
                return _Candidate(now.centroid, now.box, score, now.pixel_count)
            fp = self._footprint(frame, result.support, rows, cols, bounds, cell)
        if fp is None:
            return None          # support the object has left: a trailing "ghost", no object
        (y0, x0), mask = fp
        fr, fc = np.nonzero(mask)
        if fr.size < c.min_object_pixels:
            return None
        now = describe_pixels(fc + x0, fr + y0)
        return _Candidate(now.centroid, now.box, score, now.pixel_count)

    def _reassociate(self, candidates: list[_Candidate]) -> list[ThermalDetection]:
        """Full pass: keep the filters of objects found again, start new ones, and let the
        others go after ``max_missed`` frames."""
        stamp = self._last_stamp
        old = self._tracks
        predicted = []
        for tr in old:
            dt = stamp - tr.stamp
            predicted.append(tr.kf.predicted(dt)[0][:2] if dt > 0 else tr.kf.center)
        matches: list[tuple[int, int]] = []
        if old and candidates:
            cost = np.full((len(old), len(candidates)), np.inf)
            for i, tr in enumerate(old):
                gate = max(tr.box[2], tr.box[3], math.sqrt(self.config.merge_distance_sq))
                for j, cand in enumerate(candidates):
                    d = math.dist(predicted[i], cand.centroid)
                    if d <= gate:
                        cost[i, j] = d
            matches = assign(cost, max_cost=float("inf")).matches
        new_tracks: list[_Track] = []
        detections: list[ThermalDetection] = []
        matched = {j: i for i, j in matches}
        for j, cand in enumerate(candidates):
            if j in matched:
                tr = old[matched[j]]
                dt = stamp - tr.stamp
                if dt > 0:
                    tr.kf.predict(dt)
                tr.kf.update(cand.centroid)
                tr.box, tr.stamp, tr.missed = cand.box, stamp, 0
                tr.size = cand.box[2:]
            else:
                tr = _Track(self._next_id,
                            ConstantVelocityKalman.from_config(cand.centroid, self.config.kalman),
                            cand.box, stamp, size=cand.box[2:])
                self._next_id += 1
            new_tracks.append(tr)
            detections.append(self._detection(tr, cand))
        # objects not found again: kept for max_missed frames (they may be merged with a
        # neighbour in this pass; the tracking pass separates them again), then dropped
        matched_old = {i for i, _ in matches}
        for i, tr in enumerate(old):
            if i in matched_old:
                continue
            tr.missed += 1
            if tr.missed <= self.config.max_missed and len(new_tracks) < self.config.max_objects:
                dt = stamp - tr.stamp
                if dt > 0:
                    tr.kf.predict(dt)
                tr.stamp = stamp
                new_tracks.append(tr)
        self._tracks = new_tracks
        return detections

    def _detection(self, tr: _Track, cand: _Candidate) -> ThermalDetection:
        s = tr.kf.state
        return ThermalDetection(box=cand.box, centroid=cand.centroid, score=cand.score,
                                pixel_count=cand.pixel_count, object_id=tr.object_id,
                                filtered_centroid=(float(s[0]), float(s[1])),
                                velocity=(float(s[2]), float(s[3])))

    def _tracking_pass(self) -> list[ThermalDetection]:
        """Algorithm 2, lines 3-6: each object searched in its (5.2) window, F frames.

        The windows are snapped to the global ``rho`` grid so that overlapping windows share
        blocks, and the union of their blocks is factored once.  Support pixels and
        footprint pixels belong to the object whose predicted centroid is nearest (ties to
        both); the distances of the support pixels to all predictions are computed once.
        """
        c = self.config
        if not self._tracks:
            return []
        h, w = self._shape
        rho = c.block_size
        stamp = self._last_stamp
        span = self._buffer[-1][1] - self._buffer[-min(c.window_frames, len(self._buffer))][1]
        nby, nbx = -(-h // rho), -(-w // rho)
        mask = np.zeros((nby, nbx), dtype=bool)
        regions, preds = [], []
        for tr in self._tracks:
            state = tr.kf.predict(stamp - tr.stamp)          # (4.2)-(4.3)
            tr.stamp = stamp
            preds.append(state)
            px, py, vx, vy = state.tolist()                 # the same doubles, as floats
            reach = c.window_margin + math.hypot(vx, vy) * span
            # (5.2): a w_s x h_s window around the prediction, w_s >= w_s^0, mod(w_s, rho) = 0
            bx0 = max(int(math.floor((px - tr.box[2] / 2.0 - reach) / rho)), 0)
            bx1 = min(int(math.ceil((px + tr.box[2] / 2.0 + reach) / rho)), nbx)
            by0 = max(int(math.floor((py - tr.box[3] / 2.0 - reach) / rho)), 0)
            by1 = min(int(math.ceil((py + tr.box[3] / 2.0 + reach) / rho)), nby)
            if bx1 <= bx0 or by1 <= by0:        # predicted outside the frame
                regions.append(None)
                continue
            mask[by0:by1, bx0:bx1] = True
            regions.append((by0 * rho, min(by1 * rho, h), bx0 * rho, min(bx1 * rho, w)))
        result = _support(self._ring, self._order(c.window_frames), self._map[0], c,
                          self._map[1], self._integer, mask)
        centres = np.array([(s[0], s[1]) for s in preds])
        frame = self._newest()
        # the compiled path does ownership, variances and footprint of an object in one call
        compiled = _object_kernel() if c.current_frame_refinement else None
        if compiled is None:
            owned = _owned_support(result.support, regions, centres)
        else:
            offset = np.float32(self._map[0])
            radius = np.float32(_similarity_radius(c.sigma2) / self._map[1])
        detections: list[ThermalDetection] = []
        kept: list[_Track] = []
        for k, (tr, region) in enumerate(zip(self._tracks, regions)):
            cand = None
            if compiled is not None:
                if region is not None:
                    cell_centres, cell_k = (centres, k) if len(preds) > 1 else (_NO_CENTRES, -1)
                    y0, y1, x0, x1 = region
                    values = np.empty((y1 - y0) * (x1 - x0), dtype=result.variance.dtype)
                    n_inside, n_mine, n, sx, sy, xmin, xmax, ymin, ymax = compiled(
                        frame, offset, result.support, result.variance, y0, y1, x0, x1,
                        centres, k, cell_centres, cell_k, c.min_object_pixels,
                        c.window_margin, radius, values)
                    # as _candidate: no footprint, or a smaller one than min_object_pixels,
                    # is no object
                    if n_inside >= c.min_object_pixels and n_mine >= c.min_object_pixels \
                            and n >= c.min_object_pixels:
                        cand = _Candidate((sx / n + 0.5, sy / n + 0.5),
                                          (float(xmin), float(ymin), float(xmax + 1 - xmin),
                                           float(ymax + 1 - ymin)),
                                          float(min(1.0, values[:n_mine].mean() / 0.5)),
                                          int(n))
            else:
                n_inside, rows, cols = owned[k]
                if n_inside >= c.min_object_pixels and rows.size >= c.min_object_pixels:
                    cell = _VoronoiCell(centres, k) if len(preds) > 1 else None
                    cand = self._candidate(frame, result, rows, cols, region, cell)
            if cand is None:
                tr.missed += 1
                if tr.missed <= c.max_missed:
                    kept.append(tr)
                continue
            if c.split_by_valleys and c.current_frame_refinement and \
                    (cand.box[2] > c.valley_grow_ratio * min(tr.box[2], tr.size[0])
                     or cand.box[3] > c.valley_grow_ratio * min(tr.box[3], tr.size[1])):
                split = self._split_grown(frame, result, regions, centres, k, cand,
                                          owned[k] if compiled is None else None)
                if split is cand:
                    tr.size = cand.box[2:]     # it grew but is one object: its new size
                cand = split
            tr.kf.update(cand.centroid)
            tr.box, tr.missed = cand.box, 0
            kept.append(tr)
            detections.append(self._detection(tr, cand))
        self._tracks = kept
        return self._suppress_duplicates(detections)

    def _suppress_duplicates(self, detections: list[ThermalDetection]) -> list[ThermalDetection]:
        """Two filters that latched onto one object: keep the older (smaller id)."""
        order = sorted(range(len(detections)), key=lambda i: detections[i].object_id)
        keep: list[ThermalDetection] = []
        for i in order:
            d = detections[i]
            # iou is 0 for boxes that do not overlap (intersection_area): only the others
            # are computed
            if any(iou(d.box, k.box) > 0.5 for k in keep if _overlap(d.box, k.box)):
                self._tracks = [t for t in self._tracks if t.object_id != d.object_id]
                continue
            keep.append(d)
        return keep
