"""The tracker's fast path: a quantised search region and all kernels evaluated in one call.

:mod:`mk_tracker.tracking.kernel_histograms` defines the appearance model of Chu et al. 2013
(kernel-weighted histograms, the K-L cost of Appendix C, the mean-shift vector (C.3), the
scale ratio of (9)-(10)) and computes it with numpy.  This module computes the same numbers
faster, and is what :class:`~mk_tracker.tracking.multi_kernel.MultiKernelTracker` calls every
iteration:

* :func:`quantize_region` bins the strided pixels of a search region;
* :class:`SearchRegion` evaluates every kernel of a target against its model and returns a
  :class:`~mk_tracker.tracking.kernel_histograms.KernelBatch` of arrays.

Backend ``"auto"`` (the default) is compiled when numba is installed: the loops below are
compiled with ``cache=True`` (a few seconds on first use, then loaded from ``__pycache__``):

* :func:`_quantize_loops` reads the strided search region, converts each pixel to HSV exactly
  as ``cv2.COLOR_BGR2HSV`` does for 8-bit images (checked on all 2^24 colours) and looks up its
  bin, in one pass without intermediate images (or, for ``grey``, to the fixed-point
  luminance of :func:`~mk_tracker.tracking.kernel_histograms.grey_levels`);
* :func:`_kernels_loops` evaluates every kernel in one call: histogram (pass 1), ``q / p~``
  and ``J_i``, then the mean-shift and scale-ratio sums (pass 2).

Backend ``"numpy"`` uses the reference path (:class:`~mk_tracker.tracking.kernel_histograms.
PaddedBins` with cached :class:`~mk_tracker.tracking.kernel_histograms.KernelTemplate`).
Tests assert that both agree to 1e-9 on random inputs.  ``MK_TRACKER_NO_NUMBA=1`` (or a
missing numba) selects the numpy path everywhere.
"""

from __future__ import annotations

import numpy as np

from mk_tracker.numba_support import import_numba
from mk_tracker.tracking.kernel_histograms import (
    _HUE_RANGE, PIXEL_WEIGHTINGS, PROFILES, KernelBatch, KernelTemplate, PaddedBins,
    _GREY_B, _GREY_G, _GREY_R, _GREY_SHIFT, bin_lookup_tables, quantize, roi_has_nan)

BACKENDS = ("auto", "numpy", "compiled")


class KernelBackendError(ValueError):
    """A backend name is unknown, or ``"compiled"`` was asked for without numba."""


class BinMismatchError(ValueError):
    """Bin indices or target models do not fit the number of histogram bins."""


#: how :func:`_quantize_loops` converts a pixel before its table look-up
_MODES = {"bgr": 0, "hsv": 1, "grey": 2}

#: Fixed-point reciprocals of OpenCV's 8-bit BGR->HSV conversion (12 fractional bits):
#: ``255 / v`` for the saturation and ``180 / (6 * diff)`` for the hue.
_HSV_SHIFT = 12
_SAT_RECIPROCAL = np.array([0] + [int(np.rint((255 << _HSV_SHIFT) / i)) for i in range(1, 256)],
                           dtype=np.int64)
_HUE_RECIPROCAL = np.array([0] + [int(np.rint((_HUE_RANGE << _HSV_SHIFT) / (6.0 * i)))
                                  for i in range(1, 256)], dtype=np.int64)


def _quantize_loops(image, y0, x0, stride, mode, table, sat_rec, hue_rec, out):
    """Bin index of pixel ``image[y0 + r * stride, x0 + c * stride]`` into ``out[r, c]``.

    ``mode`` is one of :data:`_MODES`.  Grey (2) takes the luminance of
    :func:`~mk_tracker.tracking.kernel_histograms.grey_levels`.  With HSV (1) the pixel is
    first converted as ``cv2.COLOR_BGR2HSV`` does for 8-bit images (V = max, S = 255 (V - min) / V, H = 30 (hue sector offset + difference) / (V - min), in
    fixed point with the reciprocal tables ``sat_rec``, ``hue_rec``); equal to OpenCV on all
    2^24 colours (tested).  Then ``table`` of :func:`bin_lookup_tables`.
    """
    h_out, w_out = out.shape
    half = 1 << (_HSV_SHIFT - 1)
    grey_half = 1 << (_GREY_SHIFT - 1)
    for r in range(h_out):
        row = image[y0 + r * stride]
        dst = out[r]
        for c in range(w_out):
            x = x0 + c * stride
            b = np.int64(row[x, 0])
            g = np.int64(row[x, 1])
            red = np.int64(row[x, 2])
            if mode == 2:
                lum = (b * _GREY_B + g * _GREY_G + red * _GREY_R + grey_half) >> _GREY_SHIFT
                dst[c] = table[2, lum]
            elif mode == 1:
                v = max(b, g, red)
                diff = v - min(b, g, red)
                s = (diff * sat_rec[v] + half) >> _HSV_SHIFT
                if v == red:
                    h = g - b
                elif v == g:
                    h = b - red + 2 * diff
                else:
                    h = red - g + 4 * diff
                h = (h * hue_rec[diff] + half) >> _HSV_SHIFT
                if h < 0:
                    h += _HUE_RANGE
                dst[c] = table[0, h] + table[1, s] + table[2, v]
            else:
                dst[c] = table[0, b] + table[1, g] + table[2, red]
    return out


def _kernels_loops(bins, ox, oy, stride, centres, axes, models, epsilon, sqrt_weights,
                   gaussian, p, costs, sims, ms, counts, ratios):
    """Every kernel of :meth:`PaddedBins.evaluate_batch` in two passes over its pixels.

    Kernel ``i`` visits the ROI pixels within ``ceil(a / stride) + 1`` grid steps of the grid
    node nearest its centre (the reach of :class:`KernelTemplate`, clipped to the ROI) in
    row-major order, with the arithmetic of the numpy path: pass 1 accumulates the histogram
    into ``p[i]``, then come ``q / p~`` and ``J_i``; pass 2 accumulates the weighted sums from
    which :func:`_batch_from_sums` finishes the numpy path, finished here the same way.
    ``p``, ``costs``, ``sims``, ``ms``, ``counts``, ``ratios`` are the zeroed outputs.
    """
    n_k, m = models.shape
    rh, rw = bins.shape
    ratio = np.empty(m)
    for i in range(n_k):
        if not (axes[i, 0] > 0.0 and axes[i, 1] > 0.0):
            # a zero (or NaN) half-axis, e.g. the layout of a box whose visible part is
            # thinner than rounding: no pixel, like the numpy path (numba would raise
            # ZeroDivisionError on 1 / 0 where numpy gives inf)
            costs[i] = np.inf
            continue
        cx = centres[i, 0]
        cy = centres[i, 1]
        iax = 1.0 / axes[i, 0]
        iay = 1.0 / axes[i, 1]
        jx = int(np.ceil(axes[i, 0] / stride)) + 1
        jy = int(np.ceil(axes[i, 1] / stride)) + 1
        cn = int(np.rint((cx - 0.5 - ox) / stride))
        rn = int(np.rint((cy - 0.5 - oy) / stride))
        cn = min(max(cn, 0), rw - 1)
        rn = min(max(rn, 0), rh - 1)
        shx = (ox + cn * stride + 0.5) - cx
        shy = (oy + rn * stride + 0.5) - cy
        r0, r1 = max(rn - jy, 0), min(rn + jy, rh - 1)
        c0, c1 = max(cn - jx, 0), min(cn + jx, rw - 1)
        hist = p[i]
        count = 0
        for r in range(r0, r1 + 1):
            dy = float((r - rn) * stride) + shy
            dy2 = (dy * iay) ** 2
            for c in range(c0, c1 + 1):
                dx = float((c - cn) * stride) + shx
                v = (dx * iax) ** 2 + dy2
                if v < 1.0:
                    k = np.exp(-2.0 * v) if gaussian else 1.0 - v
                    hist[bins[r, c]] += k
                    count += 1
        total = 0.0
        for u in range(m):
            total += hist[u]
        if count == 0 or not total > 0:
            hist[:] = 0.0
            costs[i] = np.inf
            continue
        counts[i] = count
        cost = 0.0
        for u in range(m):
            hist[u] /= total
            q = models[i, u]
            ratio[u] = q / ((1.0 - epsilon) * hist[u] + epsilon / m)
            if q > 0:
                cost += q * np.log(ratio[u])
            if sqrt_weights:
                ratio[u] = np.sqrt(ratio[u])
        costs[i] = cost
        sims[i] = np.exp(-max(cost, 0.0))
        sk = 0.0
        s = 0.0
        sx = 0.0
        sy = 0.0
        wk = 0.0
        wgv = 0.0
        sgv = 0.0
        for r in range(r0, r1 + 1):
            dy = float((r - rn) * stride) + shy
            dy2 = (dy * iay) ** 2
            for c in range(c0, c1 + 1):
                dx = float((c - cn) * stride) + shx
                v = (dx * iax) ** 2 + dy2
                if v < 1.0:
                    if gaussian:
                        k = np.exp(-2.0 * v)
                        g = 2.0 * k
                    else:
                        k = 1.0 - v
                        g = 1.0
                    w = ratio[bins[r, c]]
                    wg = w * g
                    gv = g * v
                    sk += k
                    s += wg
                    sx += wg * dx
                    sy += wg * dy
                    wk += w * k
                    wgv += w * gv
                    sgv += gv
        if s > 0:
            ms[i, 0] = sx / s
            ms[i, 1] = sy / s
        if wk > 0 and sk > 0:
            h2 = axes[i, 0] ** 2 + axes[i, 1] ** 2
            ratios[i] = 2.0 / h2 * (wgv / wk - sgv / sk)
    return counts


_COMPILED: list = []


def compiled_kernels():
    """``(quantize, kernels)`` compiled with numba (cache on disk, compiled on first
    use), or ``None`` without numba or with the environment variable ``MK_TRACKER_NO_NUMBA``
    set."""
    if not _COMPILED:
        try:
            numba = import_numba()
        except ImportError:
            _COMPILED.append(None)
        else:
            kernels = tuple(numba.njit(cache=True, nogil=True)(f) for f in (_quantize_loops, _kernels_loops))
            _warm_up(*kernels)
            _COMPILED.append(kernels)
    return _COMPILED[0]


def _warm_up(quantize_loops, kernels_loops) -> None:
    """Compile (or load from numba's disk cache) the loops for the argument types the
    tracker passes, so the first frame of a node is not the one that pays for it."""
    quantize_loops(np.zeros((2, 2, 3), np.uint8), 0, 0, 1, _MODES["hsv"],
                   bin_lookup_tables("hsv", (2, 2, 2)), _SAT_RECIPROCAL, _HUE_RECIPROCAL,
                   np.empty((2, 2), np.int32))
    m = 8
    kernels_loops(np.zeros((4, 4), np.int32), 0, 0, 1, np.full((1, 2), 2.0),
                  np.ones((1, 2)), np.full((1, m), 1.0 / m), 0.01, False, False,
                  np.zeros((1, m)), np.zeros(1), np.zeros(1), np.zeros((1, 2)),
                  np.zeros(1, dtype=np.int64), np.zeros(1))


def resolve_backend(backend: str) -> str:
    """``"numpy"`` or ``"compiled"`` for a requested backend (``"auto"``: compiled when numba
    is available); :class:`KernelBackendError` for an unknown name or a missing numba."""
    if backend not in BACKENDS:
        raise KernelBackendError(f"backend must be one of {BACKENDS}, got {backend!r}")
    if backend == "numpy":
        return "numpy"
    if compiled_kernels() is None:
        if backend == "compiled":
            raise KernelBackendError("the compiled backend needs numba, which is not "
                                     "installed (or MK_TRACKER_NO_NUMBA is set)")
        return "numpy"
    return "compiled"


def quantize_region(image: np.ndarray, region: tuple[int, int, int, int], stride: int,
                    colour_space: str, bins: tuple[int, int, int], backend: str = "auto"
                    ) -> np.ndarray | None:
    """:func:`quantize` of ``image[y0:y1:stride, x0:x1:stride]`` for ``region = (x0, y0, x1,
    y1)``; ``None`` when those pixels hold NaN.  For uint8 images the compiled backend reads,
    converts and bins the strided pixels in one numba loop (:func:`_quantize_loops`)."""
    x0, y0, x1, y1 = (int(v) for v in region)
    st = int(stride)
    kernels = compiled_kernels() if resolve_backend(backend) == "compiled" else None
    if kernels is None or image.dtype != np.uint8:
        roi = image[y0:y1:st, x0:x1:st]
        if roi_has_nan(roi):
            return None
        return quantize(roi, colour_space, bins)
    h, w = max(-(-(y1 - y0) // st), 0), max(-(-(x1 - x0) // st), 0)
    if not (image.flags.c_contiguous and image.flags.writeable):
        # one argument type for numba (a read-only message buffer or a padded row stride
        # would compile another version): copy the region's rows, cheap next to the rest
        image = np.array(image[y0:y1, x0:x1], order="C", copy=True)
        x0, y0 = 0, 0
    table = bin_lookup_tables(colour_space, bins)     # raises for an unknown colour space
    return kernels[0](image, y0, x0, st, _MODES[colour_space], table, _SAT_RECIPROCAL,
                      _HUE_RECIPROCAL, np.empty((h, w), np.int32))


class SearchRegion:
    """A quantised search region on which the tracker evaluates its kernels.

    ``bins`` is the ROI of :func:`quantize` sampled every ``stride`` px from image pixel
    ``origin``.  :meth:`evaluate` gives the :class:`KernelBatch` of kernels with half-axes
    ``half_axes`` at ``centres``; backend ``"numpy"`` uses :class:`PaddedBins` with
    :class:`KernelTemplate` (cached per kernel shape), ``"compiled"`` the numba loops of
    :func:`_kernels_loops`; both give the same numbers (tested to 1e-9).
    """

    def __init__(self, bins: np.ndarray, origin: tuple[int, int], stride: int, n_bins: int,
                 profile: str = "roof", backend: str = "auto"):
        if profile not in PROFILES:
            raise ValueError(f"profile must be one of {PROFILES}, got {profile!r}")
        self.backend = resolve_backend(backend)
        self.bins = np.ascontiguousarray(bins, dtype=np.int32)
        # the compiled loops index histograms with these without bounds checks
        if self.bins.size and (int(self.bins.min()) < 0 or int(self.bins.max()) >= n_bins):
            raise BinMismatchError(f"bin indices must lie in [0, {n_bins})")
        self.origin = (int(origin[0]), int(origin[1]))
        self.stride = int(stride)
        self.n_bins = int(n_bins)
        self.profile = profile
        self._padded: PaddedBins | None = None
        self._templates: dict = {}

    def evaluate(self, half_axes: np.ndarray, centres: np.ndarray, models: np.ndarray,
                 epsilon: float = 0.01, weighting: str = "kl") -> KernelBatch:
        """Kernel ``i`` (half-axes ``half_axes[i]``) at ``centres[i]`` against ``models[i]``."""
        if weighting not in PIXEL_WEIGHTINGS:
            raise ValueError(f"weighting must be one of {PIXEL_WEIGHTINGS}, got {weighting!r}")
        axes = np.ascontiguousarray(half_axes, dtype=np.float64).reshape(-1, 2)
        centres = np.ascontiguousarray(centres, dtype=np.float64).reshape(-1, 2)
        models = np.ascontiguousarray(models, dtype=np.float64)
        if models.shape != (len(axes), self.n_bins) or centres.shape != axes.shape:
            raise BinMismatchError(f"{len(axes)} kernels need {len(axes)} centres and models "
                                   f"of {self.n_bins} bins, got centres {centres.shape} and "
                                   f"models {models.shape}")
        if self.backend == "numpy":
            templates = [self._template(a) for a in axes]
            return self._padded_bins(templates).evaluate_batch(templates, centres, models,
                                                               epsilon, weighting)
        n_k, m = models.shape
        out = KernelBatch(np.zeros((n_k, m)), np.zeros(n_k), np.zeros(n_k), np.zeros((n_k, 2)),
                          np.zeros(n_k, dtype=np.int64), np.zeros(n_k))
        compiled_kernels()[1](self.bins, self.origin[0], self.origin[1], self.stride, centres,
                              axes, models, float(epsilon), weighting == "bhattacharyya",
                              self.profile == "gaussian", out.p, out.costs, out.similarities,
                              out.mean_shift, out.n_pixels, out.scale_ratios)
        return out

    def _template(self, axes: np.ndarray) -> KernelTemplate:
        key = axes.tobytes()
        t = self._templates.get(key)
        if t is None:
            t = self._templates[key] = KernelTemplate(axes, self.stride, self.profile)
        return t

    def _padded_bins(self, templates: list[KernelTemplate]) -> PaddedBins:
        reach = np.max([t.reach for t in templates], axis=0)
        padded = self._padded
        if padded is None or reach[0] > padded.pad[0] or reach[1] > padded.pad[1]:
            # room for somewhat larger kernels (a scale step) without re-padding
            pad = tuple(int(np.ceil(r * 1.25)) + 1 for r in reach)
            if padded is not None:
                pad = (max(pad[0], padded.pad[0]), max(pad[1], padded.pad[1]))
            padded = self._padded = PaddedBins(self.bins, self.origin, self.stride,
                                               self.n_bins, pad)
        return padded
