"""Kernel-weighted colour histograms, the K-L cost, the mean-shift vector and the scale ratio.

The appearance model of Chu et al. 2013 (Sec. III-A, III-E, IV-A, Appendix C), after
Comaniciu, Ramesh and Meer 2003:

* Pixels are quantised into ``m`` colour bins ``b(z)`` (HSV by default, Sec. IV-A; ``grey``
  bins the luminance alone, for a thermal image followed without an RGB camera).
* A kernel is an ellipse with centre ``x`` and half-axes ``(a_x, a_y)``; a pixel ``z`` has the
  normalised squared distance ``v = ((z_x - x_x)/a_x)^2 + ((z_y - x_y)/a_y)^2`` and contributes
  ``k(v)`` to its bin.  ``k`` is the *roof* profile ``k(v) = 1 - v`` on ``v < 1`` (piecewise
  linear, so ``g = -k' = 1`` is piecewise constant and the mean-shift step is a Newton step,
  Sec. V-A) or a truncated Gaussian profile.
* Target model ``q`` and candidate ``p(x)`` are such histograms normalised to sum 1.
* Cost ``J_i(x) = sum_u q_u log(q_u / p_u(x))``, the K-L distance (Appendix C).  The candidate
  is smoothed, ``p~ = (1 - eps) p + eps / m``, so ``J`` is finite and still ``>= 0``.
* Similarity ``sim_i = exp(-J_i)`` in ``(0, 1]``: 1 for identical histograms, decreasing as
  the cost grows -- the cost is ``-log`` of the similarity, a monotone version of eq. (2)
  ``J ~ 1/sim``.  A kernel with no pixel inside the image has similarity 0.
* Mean-shift vector (Appendix C, (C.3)): ``m(x) = sum z w g / sum w g - x`` with pixel weights
  ``w = q_u / p_u(x)`` (K-L, Appendix C) or ``sqrt(q_u / p_u(x))`` (Bhattacharyya, Comaniciu's
  original).  ``J_x = -m(x)`` up to a positive factor (C.4).
* Scale ratio ``r(h) = grad f(h) / (h f(h))`` of eqs. (9)-(10), from the same by-products.

Everything here works on a small region of interest (ROI) of bin indices; nothing reads
pixels outside it.

The numpy functions here are the reference: :func:`quantize` (OpenCV's HSV conversion, then
the bin tables of :func:`bin_lookup_tables`), :func:`evaluate_kernel` for one kernel, and
:meth:`PaddedBins.evaluate_batch` / :meth:`PaddedBins.evaluate_many`, which evaluate all
kernels of a target together through precomputed :class:`KernelTemplate` offsets.  The fast
path the tracker uses, the same arithmetic in numba loops, is
:mod:`mk_tracker.tracking.search_region`.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


COLOUR_SPACES = ("hsv", "bgr", "grey")
PROFILES = ("roof", "gaussian")
PIXEL_WEIGHTINGS = ("kl", "bhattacharyya")

#: OpenCV 8-bit HSV hue range.
_HUE_RANGE = 180
#: Fixed-point BGR -> luminance weights 0.114 B + 0.587 G + 0.299 R (BT.601) with 15
#: fractional bits; they sum to 2^15, so a grey-replicated pixel keeps its level.
_GREY_SHIFT = 15
_GREY_B, _GREY_G, _GREY_R = 3735, 19235, 9798


class InvalidImageError(ValueError):
    """An image is not a usable ``H x W x 3`` BGR array."""


def check_image(image: np.ndarray) -> np.ndarray:
    """Return ``image`` if it is an ``H x W x 3`` array, else raise :class:`InvalidImageError`."""
    if not isinstance(image, np.ndarray):
        raise InvalidImageError(f"image must be a numpy array, got {type(image).__name__}")
    if image.ndim != 3 or image.shape[2] != 3:
        raise InvalidImageError(f"image must be H x W x 3 (BGR), got shape {image.shape}")
    if image.shape[0] == 0 or image.shape[1] == 0:
        raise InvalidImageError("image is empty")
    if image.dtype != np.uint8 and not np.issubdtype(image.dtype, np.floating):
        raise InvalidImageError(f"image must be uint8 or float, got {image.dtype}")
    return image


def roi_has_nan(roi: np.ndarray) -> bool:
    """True when a float ROI holds a NaN or infinite value (uint8 never does)."""
    return roi.dtype != np.uint8 and not bool(np.all(np.isfinite(roi)))


def number_of_bins(bins: tuple[int, int, int]) -> int:
    """Total number of histogram bins ``m``."""
    return int(bins[0]) * int(bins[1]) * int(bins[2])


_LUTS: dict = {}


def bin_lookup_tables(colour_space: str, bins: tuple[int, int, int]) -> np.ndarray:
    """``(3, 256)`` int32 tables: ``b(z) = T[0, c0] + T[1, c1] + T[2, c2]`` for 8-bit channels.

    Channel 0 (hue, or blue) gets bin ``c0 * b0 // 180`` (``c0 * b0 >> 8`` for BGR), the others
    ``c * b >> 8``; the tables hold those bins already multiplied out to the flat index
    ``(bin0 * b1 + bin1) * b2 + bin2``.  Built once per configuration.  ``grey`` bins only
    the luminance ``L`` (channel 2 of :func:`_colour_converted`) into ``L * b2 >> 8``: it needs
    ``bins = (1, 1, b2)``, and its rows 0 and 1 are zero.
    """
    if colour_space not in COLOUR_SPACES:
        raise ValueError(f"colour_space must be one of {COLOUR_SPACES}, got {colour_space!r}")
    if not all(1 <= int(b) <= 256 for b in bins):
        raise ValueError(f"bins must lie in [1, 256], got {bins}")
    b0, b1, b2 = (int(b) for b in bins)
    if colour_space == "grey" and (b0, b1) != (1, 1):
        raise ValueError(f"grey histograms have bins (1, 1, n), got {bins}")
    key = (colour_space, b0, b1, b2)
    table = _LUTS.get(key)
    if table is None:
        level = np.arange(256, dtype=np.int64)
        if colour_space == "hsv":
            c0 = np.minimum(level * b0 // _HUE_RANGE, b0 - 1)
        else:
            c0 = level * b0 >> 8
        table = np.stack([c0 * (b1 * b2), (level * b1 >> 8) * b2, level * b2 >> 8])
        table = np.ascontiguousarray(table, dtype=np.int32)
        table.setflags(write=False)
        _LUTS[key] = table
    return table


def grey_levels(roi_bgr: np.ndarray) -> np.ndarray:
    """8-bit luminance ``(3735 B + 19235 G + 9798 R + 2^14) >> 15`` of a uint8 BGR array
    (the BT.601 weights in fixed point, the values of ``cv2.COLOR_BGR2GRAY`` in OpenCV 4.x,
    written out so the result does not depend on the OpenCV build); a grey-replicated pixel,
    as a mono8 thermal frame becomes, keeps its level."""
    c = roi_bgr.astype(np.int32)
    lum = (c[..., 0] * _GREY_B + c[..., 1] * _GREY_G + c[..., 2] * _GREY_R
           + (1 << (_GREY_SHIFT - 1))) >> _GREY_SHIFT
    return lum.astype(np.uint8)


def _colour_converted(roi_bgr: np.ndarray, colour_space: str) -> np.ndarray:
    """The uint8 ``H x W x 3`` channels that are binned: OpenCV HSV, the BGR itself, or for
    ``grey`` the luminance of :func:`grey_levels` in channel 2 (0 in the others)."""
    if colour_space == "hsv":
        return cv2.cvtColor(roi_bgr, cv2.COLOR_BGR2HSV)
    if colour_space == "grey":
        out = np.zeros(roi_bgr.shape[:2] + (3,), dtype=np.uint8)
        out[..., 2] = grey_levels(roi_bgr)
        return out
    return roi_bgr


def quantize(roi_bgr: np.ndarray, colour_space: str, bins: tuple[int, int, int]) -> np.ndarray:
    """Bin index ``b(z)`` of every pixel of a BGR ROI, int32 array of the ROI's shape.

    ``colour_space`` ``"hsv"`` converts with OpenCV (8-bit hue in ``[0, 180)``) and bins
    ``(hue, saturation, value)``; ``"bgr"`` bins the raw channels; ``"grey"`` the luminance
    alone (see :func:`bin_lookup_tables`).  Float ROIs are taken to be in ``[0, 255]`` and
    clipped; they must not hold NaN (see :func:`roi_has_nan`).
    """
    table = bin_lookup_tables(colour_space, bins)
    if roi_bgr.dtype != np.uint8:
        roi_bgr = np.clip(roi_bgr, 0, 255).astype(np.uint8)
    conv = _colour_converted(np.ascontiguousarray(roi_bgr), colour_space)
    out = table[0][conv[..., 0]]
    out += table[1][conv[..., 1]]
    out += table[2][conv[..., 2]]
    return out


@dataclass
class KernelSample:
    """The pixels under one kernel: bin index, profile values, coordinates and ``v``."""

    bins: np.ndarray      # (P,) int bin index b(z_i)
    k: np.ndarray         # (P,) profile k(v_i)
    g: np.ndarray         # (P,) g(v_i) = -k'(v_i)
    xs: np.ndarray        # (P,) pixel-centre x in image coordinates
    ys: np.ndarray        # (P,) pixel-centre y
    v: np.ndarray         # (P,) normalised squared distance

    @property
    def empty(self) -> bool:
        return self.k.size == 0 or float(self.k.sum()) <= 0.0


def profile_values(v: np.ndarray, profile: str) -> tuple[np.ndarray, np.ndarray]:
    """``k(v)`` and ``g(v) = -k'(v)`` of a profile, for ``v`` inside the support ``v < 1``.

    ``roof``: ``k = 1 - v``, ``g = 1``.  ``gaussian``: ``k = exp(-2 v)``, ``g = 2 exp(-2 v)``
    (a Gaussian with sigma = half the bandwidth, truncated at the ellipse).
    """
    if profile == "roof":
        return 1.0 - v, np.ones(v.shape)
    if profile == "gaussian":
        k = np.exp(-2.0 * v)
        return k, 2.0 * k
    raise ValueError(f"profile must be one of {PROFILES}, got {profile!r}")


def sample_kernel(bin_roi: np.ndarray, roi_origin: tuple[int, int], centre: np.ndarray,
                  half_axes: np.ndarray, profile: str = "roof", stride: int = 1
                  ) -> KernelSample:
    """Collect the ROI pixels whose centres fall strictly inside the kernel ellipse.

    ``bin_roi`` holds bin indices of a region of interest sampled every ``stride`` pixels:
    its element ``(r, c)`` is image pixel ``(ox + c * stride, oy + r * stride)`` with
    ``roi_origin = (ox, oy)``.  Pixels of the ellipse outside the ROI are simply absent (the
    kernel sees only its search region).  ``stride > 1`` subsamples large kernels on a grid
    fixed in the image, so histograms at different positions stay comparable.
    """
    ox, oy = int(roi_origin[0]), int(roi_origin[1])
    st = int(stride)
    rh, rw = bin_roi.shape
    cx, cy = float(centre[0]), float(centre[1])
    ax, ay = float(half_axes[0]), float(half_axes[1])
    c0 = max(int(np.ceil((cx - ax - 0.5 - ox) / st)), 0)
    c1 = min(int(np.floor((cx + ax - 0.5 - ox) / st)) + 1, rw)
    r0 = max(int(np.ceil((cy - ay - 0.5 - oy) / st)), 0)
    r1 = min(int(np.floor((cy + ay - 0.5 - oy) / st)) + 1, rh)
    if c1 <= c0 or r1 <= r0:
        empty_f = np.zeros(0)
        return KernelSample(np.zeros(0, dtype=np.int64), empty_f, empty_f, empty_f, empty_f,
                            empty_f)
    xs = ox + st * np.arange(c0, c1, dtype=np.float64) + 0.5
    ys = oy + st * np.arange(r0, r1, dtype=np.float64) + 0.5
    dx2 = ((xs - cx) / ax) ** 2
    dy2 = ((ys - cy) / ay) ** 2
    v = dy2[:, None] + dx2[None, :]
    inside = v < 1.0
    v_in = v[inside]
    k, g = profile_values(v_in, profile)
    shape = inside.shape
    return KernelSample(bins=bin_roi[r0:r1, c0:c1][inside], k=k, g=g,
                        xs=np.broadcast_to(xs[None, :], shape)[inside],
                        ys=np.broadcast_to(ys[:, None], shape)[inside], v=v_in)


def kernel_histogram(sample: KernelSample, n_bins: int) -> np.ndarray:
    """Kernel-weighted histogram ``q_u = C sum_i k(v_i) delta[b(z_i) - u]``, sums to 1.

    An empty kernel gives an all-zero histogram.
    """
    hist = np.bincount(sample.bins, weights=sample.k, minlength=n_bins)
    total = hist.sum()
    if total <= 0:
        return np.zeros(n_bins)
    return hist / total


def smoothed(p: np.ndarray, epsilon: float) -> np.ndarray:
    """``(1 - eps) p + eps / m``: a histogram with no empty bin, still summing to 1."""
    return (1.0 - epsilon) * p + epsilon / p.size


def kl_cost(q: np.ndarray, p: np.ndarray, epsilon: float = 0.01) -> float:
    """K-L distance ``J = sum_u q_u log(q_u / p~_u)`` of Appendix C, with ``p~`` smoothed."""
    ps = smoothed(p, epsilon)
    nz = q > 0
    return float(np.sum(q[nz] * np.log(q[nz] / ps[nz])))


def similarity_from_cost(cost: float) -> float:
    """``sim = exp(-J)`` in ``(0, 1]`` -- the mapping between eq. (2)'s cost and similarity."""
    return float(np.exp(-max(cost, 0.0)))


def pixel_weights(sample: KernelSample, q: np.ndarray, p: np.ndarray, epsilon: float,
                  weighting: str = "kl") -> np.ndarray:
    """Per-pixel weights ``w_i``: ``q_u/p~_u`` (K-L, Appendix C) or its square root."""
    ratio = q / smoothed(p, epsilon)
    if weighting == "bhattacharyya":
        ratio = np.sqrt(ratio)
    elif weighting != "kl":
        raise ValueError(f"weighting must be one of {PIXEL_WEIGHTINGS}, got {weighting!r}")
    return ratio[sample.bins]


def mean_shift_vector(sample: KernelSample, weights: np.ndarray, centre: np.ndarray
                      ) -> np.ndarray:
    """Mean-shift vector ``m(x) = sum z w g / sum w g - x`` (C.3); zero for an empty kernel.

    ``J_x = -m(x)`` for the kernel's two coordinates (C.4).
    """
    wg = weights * sample.g
    total = float(wg.sum())
    if not total > 0:
        return np.zeros(2)
    # elementwise sums rather than BLAS dot products: ddot may spawn threads, which costs far
    # more than it saves for a few thousand pixels on a loaded machine
    return np.array([float(np.sum(wg * sample.xs)) / total - float(centre[0]),
                     float(np.sum(wg * sample.ys)) / total - float(centre[1])])


def scale_ratio(sample: KernelSample, weights: np.ndarray, half_axes: np.ndarray) -> float:
    """``r(h) = grad f(h) / (h f(h))`` from eqs. (9)-(10), ``h = sqrt(a_x^2 + a_y^2)``.

    From (9): ``r = (2 / h^2) [sum w g v / sum w k - sum g v / sum k]``.  Positive when widening
    the kernel would raise the density estimate (1), i.e. the target looks larger than the
    kernel.  Zero for an empty kernel.
    """
    sk = float(sample.k.sum())
    wk = float(np.sum(weights * sample.k))
    if not (sk > 0 and wk > 0):
        return 0.0
    gv = sample.g * sample.v
    h2 = float(half_axes[0]) ** 2 + float(half_axes[1]) ** 2
    return 2.0 / h2 * (float(np.sum(weights * gv)) / wk - float(gv.sum()) / sk)


@dataclass
class KernelEvaluation:
    """One kernel evaluated at one position: candidate, cost, similarity, mean shift.

    ``scale_ratio`` (``r(h)`` of (9)-(10)) is computed on first access from the kept sample.
    """

    p: np.ndarray
    cost: float
    similarity: float
    mean_shift: np.ndarray
    n_pixels: int
    sample: KernelSample | None = None
    weights: np.ndarray | None = None
    half_axes: np.ndarray | None = None

    @property
    def scale_ratio(self) -> float:
        if self.sample is None or self.n_pixels == 0:
            return 0.0
        return scale_ratio(self.sample, self.weights, self.half_axes)


def evaluate_kernel(bin_roi: np.ndarray, roi_origin: tuple[int, int], centre: np.ndarray,
                    half_axes: np.ndarray, q: np.ndarray, *, profile: str = "roof",
                    epsilon: float = 0.01, weighting: str = "kl",
                    stride: int = 1) -> KernelEvaluation:
    """Candidate ``p(x)``, ``J_i``, ``sim_i``, mean shift ``m`` (and lazily ``r(h)``).

    Same values as :func:`kl_cost`, :func:`pixel_weights` and :func:`mean_shift_vector`, with
    the ratio ``q / p~`` computed once.  A kernel with no pixel in the ROI has cost ``inf``,
    similarity 0 and no mean shift.
    """
    sample = sample_kernel(bin_roi, roi_origin, centre, half_axes, profile, stride)
    n_bins = q.size
    if sample.empty:
        return KernelEvaluation(np.zeros(n_bins), float("inf"), 0.0, np.zeros(2), 0)
    p = kernel_histogram(sample, n_bins)
    ratio = q / smoothed(p, epsilon)
    log_ratio = np.zeros(n_bins)
    np.log(ratio, out=log_ratio, where=q > 0)
    cost = float(np.sum(q * log_ratio))
    if weighting == "bhattacharyya":
        ratio = np.sqrt(ratio)
    elif weighting != "kl":
        raise ValueError(f"weighting must be one of {PIXEL_WEIGHTINGS}, got {weighting!r}")
    w = ratio[sample.bins]
    ms = mean_shift_vector(sample, w, centre)
    return KernelEvaluation(p, cost, similarity_from_cost(cost), ms, int(sample.k.size),
                            sample, w, np.asarray(half_axes, dtype=np.float64))


# --------------------------------------------------------------------------------------------
# Fast path used by the tracker: kernels evaluated at grid-aligned centres from a template
# --------------------------------------------------------------------------------------------

class KernelTemplate:
    """The sampling-grid offsets that can fall inside one kernel ellipse, precomputed.

    Within one frame a kernel's shape does not change, only its centre.  The template holds
    every grid offset within the ellipse grown by one stride; an evaluation anchors it at the
    grid node nearest the continuous centre ``x`` and computes ``v`` of each offset relative to
    ``x`` itself, so the result equals :func:`evaluate_kernel` at ``x`` (tested), with one
    gather instead of building the pixel set anew.
    """

    def __init__(self, half_axes: np.ndarray, stride: int, profile: str = "roof"):
        if profile not in PROFILES:
            raise ValueError(f"profile must be one of {PROFILES}, got {profile!r}")
        ax, ay = float(half_axes[0]), float(half_axes[1])
        st = int(stride)
        jx, jy = int(np.ceil(ax / st)) + 1, int(np.ceil(ay / st)) + 1
        dj = np.arange(-jx, jx + 1)
        di = np.arange(-jy, jy + 1)
        grown = ((di[:, None] * st / (ay + st)) ** 2) + ((dj[None, :] * st / (ax + st)) ** 2)
        ii, jj = np.nonzero(grown < 1.0)
        self.di = di[ii]
        self.dj = dj[jj]
        self.dx = self.dj * float(st)
        self.dy = self.di * float(st)
        self.reach = (jx, jy)
        self.stride = st
        self.profile = profile
        self.half_axes = np.array([ax, ay])
        self.linear_offsets: tuple[int, np.ndarray] | None = None   # (row width, offsets)


class PaddedBins:
    """A quantised ROI padded with a sentinel bin ``m`` so templates never index outside it.

    Evaluations of :class:`KernelTemplate` kernels on it are the tracker's fast path.

    ``bins`` is the ``(H, W)`` ROI of :func:`quantize` sampled every ``stride`` px from image
    pixel ``origin``; ``pad`` is the largest template reach.  Sentinel pixels count in no
    histogram and have zero weight, exactly like pixels missing from the ROI.
    """

    def __init__(self, bins: np.ndarray, origin: tuple[int, int], stride: int, n_bins: int,
                 pad: tuple[int, int]):
        px, py = int(pad[0]), int(pad[1])
        h, w = bins.shape
        padded = np.full((h + 2 * py, w + 2 * px), n_bins, dtype=np.int64)
        padded[py:py + h, px:px + w] = bins
        self.flat = padded.reshape(-1)
        self.width = w + 2 * px
        self.shape = (h, w)
        self.pad = (px, py)
        self.origin = (int(origin[0]), int(origin[1]))
        self.stride = int(stride)
        self.n_bins = int(n_bins)

    def grid_node(self, centre: np.ndarray) -> tuple[int, int]:
        """ROI (row, col) of the grid node nearest ``centre``, clamped into the ROI."""
        st = self.stride
        c = int(round((float(centre[0]) - 0.5 - self.origin[0]) / st))
        r = int(round((float(centre[1]) - 0.5 - self.origin[1]) / st))
        return (min(max(r, 0), self.shape[0] - 1), min(max(c, 0), self.shape[1] - 1))

    def evaluate(self, template: KernelTemplate, centre: np.ndarray, q: np.ndarray,
                 epsilon: float = 0.01, weighting: str = "kl") -> KernelEvaluation:
        """:func:`evaluate_kernel` at ``centre``, gathering pixels through ``template``."""
        return self.evaluate_many([template], np.asarray(centre, float).reshape(1, 2),
                                  np.asarray(q).reshape(1, -1), epsilon, weighting)[0]

    def evaluate_many(self, templates: list[KernelTemplate], centres: np.ndarray,
                      models: np.ndarray, epsilon: float = 0.01, weighting: str = "kl"
                      ) -> list[KernelEvaluation]:
        """Evaluate kernel ``i`` (``templates[i]`` at ``centres[i]`` against ``models[i]``) for
        all kernels in one pass; each result equals :func:`evaluate_kernel` and keeps its
        pixels (:class:`KernelSample`).  :meth:`evaluate_batch` gives the same numbers as
        arrays without building the per-kernel objects."""
        batch, (b, k, g, ox, oy, v, w, counts) = self._evaluate_arrays(
            templates, centres, models, epsilon, weighting)
        ends = np.cumsum(counts)
        out = []
        for i in range(len(templates)):
            if batch.n_pixels[i] == 0:
                out.append(KernelEvaluation(np.zeros(self.n_bins), float("inf"), 0.0,
                                            np.zeros(2), 0))
                continue
            a, e = ends[i] - counts[i], ends[i]
            cx, cy = float(centres[i][0]), float(centres[i][1])
            sample = KernelSample(bins=b[a:e], k=k[a:e], g=g[a:e], xs=ox[a:e] + cx,
                                  ys=oy[a:e] + cy, v=v[a:e])
            out.append(KernelEvaluation(batch.p[i], float(batch.costs[i]),
                                        float(batch.similarities[i]), batch.mean_shift[i],
                                        int(counts[i]), sample, w[a:e],
                                        templates[i].half_axes))
        return out

    def evaluate_batch(self, templates: list[KernelTemplate], centres: np.ndarray,
                       models: np.ndarray, epsilon: float = 0.01, weighting: str = "kl"
                       ) -> "KernelBatch":
        """:meth:`evaluate_many` as one :class:`KernelBatch` (the numpy reference of the
        compiled :meth:`mk_tracker.tracking.search_region.SearchRegion.evaluate`)."""
        return self._evaluate_arrays(templates, centres, models, epsilon, weighting)[0]

    def _evaluate_arrays(self, templates, centres, models, epsilon, weighting):
        """All kernels in one pass: the pixels of all kernels are gathered, binned (kernel
        ``i`` uses bins ``i*m ... i*m+m-1``) and summed together, so the number of numpy calls
        does not grow with the number of kernels."""
        if weighting not in PIXEL_WEIGHTINGS:
            raise ValueError(f"weighting must be one of {PIXEL_WEIGHTINGS}, got {weighting!r}")
        n_k = len(templates)
        m = self.n_bins
        st = self.stride
        lins, dxs, dys = [], [], []
        sizes = np.empty(n_k, dtype=np.int64)
        gxy = np.empty((n_k, 2))
        axes = np.empty((n_k, 2))
        for i, t in enumerate(templates):
            if t.reach[0] > self.pad[0] or t.reach[1] > self.pad[1]:
                raise ValueError(f"kernel reach {t.reach} exceeds the padding {self.pad}")
            cached = t.linear_offsets
            if cached is None or cached[0] != self.width:
                cached = (self.width, t.di * self.width + t.dj)
                t.linear_offsets = cached
            r, c = self.grid_node(centres[i])
            lins.append(cached[1] + ((r + self.pad[1]) * self.width + (c + self.pad[0])))
            gxy[i] = (self.origin[0] + c * st + 0.5, self.origin[1] + r * st + 0.5)
            dxs.append(t.dx)
            dys.append(t.dy)
            sizes[i] = t.dx.size
            axes[i] = t.half_axes
        inv_axes = 1.0 / axes
        kid = np.repeat(np.arange(n_k), sizes)
        shift = gxy - np.asarray(centres, dtype=np.float64)       # node minus true centre
        b = self.flat[np.concatenate(lins)]
        ox = np.concatenate(dxs) + shift[kid, 0]                   # offsets from the centre
        oy = np.concatenate(dys) + shift[kid, 1]
        v = (ox * inv_axes[kid, 0]) ** 2 + (oy * inv_axes[kid, 1]) ** 2
        use = (v < 1.0) & (b < m)
        b, ox, oy, v, kid = b[use], ox[use], oy[use], v[use], kid[use]
        k, g = profile_values(v, templates[0].profile)
        counts = np.bincount(kid, minlength=n_k)
        hist = np.bincount(kid * m + b, weights=k, minlength=n_k * m).reshape(n_k, m)
        q = np.asarray(models, dtype=np.float64)
        ratio, costs = _ratio_and_cost(hist, q, epsilon, weighting)
        w = ratio.reshape(-1)[kid * m + b]
        wg = w * g
        gv = g * v
        # per-kernel sums: the pixels of kernel i are the contiguous run ends[i]-counts[i]..
        per_pixel = np.stack([k, wg, wg * ox, wg * oy, w * k, w * gv, gv])
        starts = np.cumsum(counts) - counts
        sums = np.zeros((n_k, 7))
        filled = counts > 0
        if per_pixel.shape[1]:
            sums[filled] = np.add.reduceat(per_pixel, starts[filled], axis=1).T
        batch = _batch_from_sums(hist, counts, costs, sums, axes)
        return batch, (b, k, g, ox, oy, v, w, counts)


def _ratio_and_cost(hist: np.ndarray, q: np.ndarray, epsilon: float, weighting: str
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Per-bin pixel weight ``q / p~`` (or its root) and ``J_i`` for kernel histograms
    ``hist`` (unnormalised, one row per kernel)."""
    m = hist.shape[1]
    totals = hist.sum(axis=1)
    p = hist / np.where(totals > 0, totals, 1.0)[:, None]
    ratio = q / ((1.0 - epsilon) * p + epsilon / m)
    log_ratio = np.zeros_like(ratio)
    np.log(ratio, out=log_ratio, where=q > 0)
    costs = np.sum(q * log_ratio, axis=1)
    if weighting == "bhattacharyya":
        ratio = np.sqrt(ratio)
    return ratio, costs


@dataclass
class KernelBatch:
    """Kernels evaluated together: row ``i`` holds kernel ``i``'s results.

    ``p`` candidate histograms ``(N, m)``, ``costs`` ``J_i`` (inf for a kernel with no
    pixel), ``similarities`` ``exp(-J_i)`` (0 then), ``mean_shift`` ``m(x)`` of (C.3)
    ``(N, 2)``, ``n_pixels``, ``scale_ratios`` ``r(h)`` of (9)-(10) (0 for an empty kernel).
    """

    p: np.ndarray
    costs: np.ndarray
    similarities: np.ndarray
    mean_shift: np.ndarray
    n_pixels: np.ndarray
    scale_ratios: np.ndarray


def _batch_from_sums(hist: np.ndarray, counts: np.ndarray, costs: np.ndarray,
                     sums: np.ndarray, axes: np.ndarray) -> KernelBatch:
    """The results from per-kernel sums ``[sum k, sum w g, sum w g dx, sum w g dy, sum w k,
    sum w g v, sum g v]`` (``dx, dy`` offsets from the kernel centre), shared by both
    backends."""
    sk, s, sx, sy, wk, wgv, gv = (sums[:, j] for j in range(7))
    totals = hist.sum(axis=1)
    valid = (counts > 0) & (totals > 0)
    h2 = axes[:, 0] ** 2 + axes[:, 1] ** 2
    if valid.all() and (s > 0).all() and (wk > 0).all():      # the common case, fewer calls
        return KernelBatch(hist / totals[:, None], costs, np.exp(-np.maximum(costs, 0.0)),
                           np.stack([sx / s, sy / s], axis=1), counts.astype(np.int64),
                           2.0 / h2 * (wgv / wk - gv / sk))
    p = np.where(valid[:, None], hist / np.where(valid, totals, 1.0)[:, None], 0.0)
    costs = np.where(valid, costs, np.inf)
    sims = np.where(valid, np.exp(-np.maximum(costs, 0.0)), 0.0)
    moving = valid & (s > 0)
    safe_s = np.where(moving, s, 1.0)
    ms = np.where(moving[:, None], np.stack([sx / safe_s, sy / safe_s], axis=1), 0.0)
    scaled = valid & (wk > 0)
    ratios = np.where(scaled, 2.0 / h2 * (wgv / np.where(scaled, wk, 1.0)
                                          - gv / np.where(sk > 0, sk, 1.0)), 0.0)
    return KernelBatch(p, costs, sims, ms, np.where(valid, counts, 0).astype(np.int64),
                       ratios)
