"""Thermal multi-object detector of Schizas, Maroulas & Ren (2018), Secs. 2-5 (Algorithm 2).

Pipeline of one pass over a window of frames:

1. normalise the frames to the kernel's unit scale (:mod:`mk_tracker.thermal_image`);
2. split the region into ``rho x rho`` blocks (divide and conquer, Sec. 5.1); blocks whose
   factor is provably zero are skipped exactly (:mod:`mk_tracker.kernel_covariance`);
3. kernel covariance (3.5) of each remaining block and its sparse factor (3.7) by
   coordinate descent (Algorithm 1, :mod:`mk_tracker.sparse_factorization`); the stacked
   factors (5.1) give the support pixels;
4. K-means with the merge rule (3.12)-(3.13) splits the support into objects
   (:mod:`mk_tracker.pixel_clustering`);
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
  make the default scale-free at the price of merging people who touch (see the crowd
  rows of docs/benchmark_thermal_detector.md; ``link_gap=0, merge_by_footprint=False``
  with a large ``merge_distance_sq`` is the paper's rule alone).
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
* Frames: NaN/inf pixels are held at their last valid value (:mod:`mk_tracker.thermal_image`);
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
"""

from __future__ import annotations

import collections
import math
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from mk_tracker.association import assign
from mk_tracker.boxes import iou
from mk_tracker.kalman import ConstantVelocityKalman, KalmanConfig
from mk_tracker.kernel_covariance import (block_kernel_covariance,
                                          block_kernel_covariance_levels,
                                          block_variance_levels, kernel_table,
                                          pixel_kernel_variance, range_for_variance)
from mk_tracker.parameters import parameter, validate_config
from mk_tracker.pixel_clustering import (cluster_support_pixels, describe_pixels, link_groups,
                                         merge_linked)
from mk_tracker.sparse_factorization import sparse_factorize, zero_factor_threshold
from mk_tracker.stamps import checked_stamp
from mk_tracker.thermal_image import (ThermalInputError, as_thermal_array, fill_missing,
                                      normalization_map, robust_range)

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
    variance: np.ndarray     # (h, w) float32, Sigma(j, j) where computed, else 0
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
                     chunk: int = 512) -> SupportResult:
    """Support of the stacked sparse factors (5.1) of a ``(F, h, w)`` window.

    The window is padded to multiples of ``rho`` (with zeros, which never enter a support)
    and cut into ``rho x rho`` blocks; only the blocks of ``block_mask`` (``(nby, nbx)``
    bool, default all) are considered, and of those only the ones whose factor is not
    provably zero (see :mod:`mk_tracker.kernel_covariance`) are factored.

    Window values are ``(raw - offset)``; ``scale`` maps them to the kernel's unit scale, so
    the kernel variance in window units is ``sigma^2 / scale^2``.  With ``integer_levels``
    (mono8/mono16 frames, integer offset) (3.5) is evaluated with a table of (3.6) over
    level differences instead of exponentials (same values).
    """
    rho = config.block_size
    sigma2 = config.sigma2 / (scale * scale)
    threshold = zero_factor_threshold(config.lam)
    n_frames, h, w = window.shape
    padded = _pad_to(window, rho)
    nby, nbx = padded.shape[1] // rho, padded.shape[2] // rho
    if block_mask is None:
        by, bx = np.divmod(np.arange(nby * nbx), nbx)
    else:
        by, bx = np.nonzero(block_mask)
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
    active = np.flatnonzero((variance > np.float32(threshold)).any(axis=1))
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


@dataclass
class _Candidate:
    centroid: tuple[float, float]
    box: tuple[float, float, float, float]
    score: float
    pixel_count: int


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
        raw, enc = as_thermal_array(frame, encoding)
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
        valid = np.isfinite(raw)
        if np.count_nonzero(valid) < self.config.min_valid_fraction * raw.size or not valid.any():
            self.skipped_frames += 1
            self.last_mode = "invalid_frame"
            return []
        if self._last_stamp is not None and t == self._last_stamp:
            self.skipped_frames += 1
            self.last_mode = "out_of_order"
            return []
        filled, _ = fill_missing(raw, self._last_filled)
        self._last_filled = filled
        self._shape, self._encoding, self._last_stamp = raw.shape, enc, t
        self._buffer.append((filled, t))
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

    def _window(self, n_frames: int, y0: int = 0, y1: int | None = None, x0: int = 0,
                x1: int | None = None) -> np.ndarray:
        """``(raw - offset)`` of the last ``n_frames`` frames over a region, float32."""
        frames = [f for f, _ in list(self._buffer)[-n_frames:]]
        stack = np.stack([f[y0:y1, x0:x1] for f in frames])
        stack -= np.float32(self._map[0])
        return stack

    # -- passes ----------------------------------------------------------------------------
    def _full_pass(self) -> list[ThermalDetection]:
        """Algorithm 2, line 1: start-up / reconfiguration over the whole frame, F_s frames."""
        c = self.config
        self.full_passes += 1
        self._since_full = 0
        frames = [f for f, _ in list(self._buffer)[-c.startup_frames:]]
        self._update_map(frames)
        window = self._window(c.startup_frames)
        result = support_in_frame(window, c, self._map[1], self._integer)
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
            if c.current_frame_refinement and c.merge_by_footprint and len(groups) > 1:
                groups = self._merge_by_footprint(window, result, rows, cols, groups)
            for g in groups:
                cand = self._candidate(window, result, rows[g], cols[g], 0, 0)
                if cand is not None:
                    candidates.append(cand)
        return self._reassociate(candidates)

    def _merge_by_footprint(self, window: np.ndarray, result: SupportResult, rows: np.ndarray,
                            cols: np.ndarray, groups: list[np.ndarray]) -> list[np.ndarray]:
        """Clusters whose newest-frame footprints share pixels are one object (a large
        object's swept support can fall apart into bands; its footprint does not)."""
        owner = np.full(window.shape[1:], -1, dtype=np.int64)
        parent = list(range(len(groups)))

        def find(a: int) -> int:
            while parent[a] != a:
                parent[a] = parent[parent[a]]
                a = parent[a]
            return a

        for k, g in enumerate(groups):
            fp = self._footprint(window, result, rows[g], cols[g])
            if fp is None:
                continue
            (y0, x0), mask = fp
            region = owner[y0:y0 + mask.shape[0], x0:x0 + mask.shape[1]]
            for other in np.unique(region[mask & (region >= 0)]):
                parent[find(int(other))] = find(k)
            region[mask] = k
        merged: dict[int, list[np.ndarray]] = {}
        for k, g in enumerate(groups):
            merged.setdefault(find(k), []).append(g)
        return [np.concatenate(v) for v in merged.values()]

    def _footprint(self, window: np.ndarray, result: SupportResult, rows: np.ndarray,
                   cols: np.ndarray, allowed: np.ndarray | None = None
                   ) -> tuple[tuple[int, int], np.ndarray] | None:
        """Newest-frame pixels of the object whose support is ``(rows, cols)``.

        Inside the support's bounding box grown by ``window_margin`` plus half its larger
        side (parts of the object that did not move have no support), the pixels dissimilar
        to the local background (kernel (3.6) below 1/2; background = median of the
        non-support pixels there) and on the same side of it as most of the support (warmer or
        colder) form connected components; those touching the support are the object.
        ``allowed`` (window-sized bool) restricts them.  Returns
        ``((y0, x0), mask)`` or ``None`` when there is nothing.
        """
        c = self.config
        newest = window[-1]
        h, w = newest.shape
        r0, r1, c0, c1 = int(rows.min()), int(rows.max()) + 1, int(cols.min()), int(cols.max()) + 1
        m = c.window_margin + max(r1 - r0, c1 - c0) // 2       # room for parts that stood still
        y0, y1 = max(r0 - m, 0), min(r1 + m, h)
        x0, x1 = max(c0 - m, 0), min(c1 + m, w)
        patch = newest[y0:y1, x0:x1]
        background = patch[~result.support[y0:y1, x0:x1]]
        if background.size == 0:
            background = newest[~result.support]
        if background.size == 0:
            return None
        step = max(1, background.size // 2048)     # a stride sample is enough for a median
        level = np.float32(np.median(background[::step]))
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
        if allowed is not None:
            fg &= allowed[y0:y1, x0:x1].astype(np.uint8)
        n, labels = cv2.connectedComponents(fg, connectivity=8)
        if n <= 1:
            return None
        lut = np.zeros(n, dtype=bool)
        lut[labels[rows - y0, cols - x0]] = True
        lut[0] = False
        if not lut.any():
            return None
        return (y0, x0), lut[labels]

    def _candidate(self, window: np.ndarray, result: SupportResult, rows: np.ndarray,
                   cols: np.ndarray, oy: int, ox: int,
                   allowed: np.ndarray | None = None) -> _Candidate | None:
        """Detection from support pixels ``(rows, cols)`` of a window at offset (oy, ox)."""
        c = self.config
        score = float(min(1.0, result.variance[rows, cols].mean() / 0.5))
        if not c.current_frame_refinement:
            swept = describe_pixels(cols + ox, rows + oy)
            return _Candidate(swept.centroid, swept.box, score, swept.pixel_count)
        fp = self._footprint(window, result, rows, cols, allowed)
        if fp is None:
            return None          # support the object has left: a trailing "ghost", no object
        (y0, x0), mask = fp
        fr, fc = np.nonzero(mask)
        if fr.size < c.min_object_pixels:
            return None
        now = describe_pixels(fc + x0 + ox, fr + y0 + oy)
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
            else:
                tr = _Track(self._next_id,
                            ConstantVelocityKalman.from_config(cand.centroid, self.config.kalman),
                            cand.box, stamp)
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
        blocks, and the union of their blocks is factored once.
        """
        c = self.config
        if not self._tracks:
            return []
        h, w = self._shape
        rho = c.block_size
        stamp = self._last_stamp
        stamps = [s for _, s in list(self._buffer)[-c.window_frames:]]
        span = stamps[-1] - stamps[0]
        nby, nbx = -(-h // rho), -(-w // rho)
        mask = np.zeros((nby, nbx), dtype=bool)
        regions, preds = [], []
        for tr in self._tracks:
            state, _ = tr.kf.predicted(stamp - tr.stamp)
            preds.append(state)
            reach = c.window_margin + math.hypot(state[2], state[3]) * span
            # (5.2): a w_s x h_s window around the prediction, w_s >= w_s^0, mod(w_s, rho) = 0
            bx0 = max(int(math.floor((state[0] - tr.box[2] / 2.0 - reach) / rho)), 0)
            bx1 = min(int(math.ceil((state[0] + tr.box[2] / 2.0 + reach) / rho)), nbx)
            by0 = max(int(math.floor((state[1] - tr.box[3] / 2.0 - reach) / rho)), 0)
            by1 = min(int(math.ceil((state[1] + tr.box[3] / 2.0 + reach) / rho)), nby)
            if bx1 <= bx0 or by1 <= by0:        # predicted outside the frame
                regions.append(None)
                continue
            mask[by0:by1, bx0:bx1] = True
            regions.append((by0 * rho, min(by1 * rho, h), bx0 * rho, min(bx1 * rho, w)))
        window = self._window(c.window_frames)
        result = support_in_frame(window, c, self._map[1], self._integer, block_mask=mask)
        detections: list[ThermalDetection] = []
        kept: list[_Track] = []
        for tr, state, region in zip(self._tracks, preds, regions):
            dt = stamp - tr.stamp
            cand = None
            if region is not None:
                y0, y1, x0, x1 = region
                sub = SupportResult(result.support[y0:y1, x0:x1], result.variance[y0:y1, x0:x1],
                                    0, 0)
                rows, cols = np.nonzero(sub.support)
                if rows.size >= c.min_object_pixels:
                    # support pixels belong to the object whose predicted centroid is nearest
                    px = cols + 0.5 + x0
                    py = rows + 0.5 + y0
                    own = (px - state[0]) ** 2 + (py - state[1]) ** 2
                    mine = np.ones(rows.size, dtype=bool)
                    for other in preds:
                        if other is not state:
                            mine &= own <= (px - other[0]) ** 2 + (py - other[1]) ** 2
                    if np.count_nonzero(mine) >= c.min_object_pixels:
                        allowed = None
                        if len(preds) > 1:
                            gx = np.arange(x0, x1) + 0.5
                            gy = (np.arange(y0, y1) + 0.5)[:, None]
                            d_own = (gx - state[0]) ** 2 + (gy - state[1]) ** 2
                            allowed = np.ones(d_own.shape, dtype=bool)
                            for other in preds:
                                if other is not state:
                                    allowed &= d_own <= (gx - other[0]) ** 2 + (gy - other[1]) ** 2
                        cand = self._candidate(window[:, y0:y1, x0:x1], sub, rows[mine],
                                               cols[mine], y0, x0, allowed)
            tr.kf.predict(dt)
            tr.stamp = stamp
            if cand is None:
                tr.missed += 1
                if tr.missed <= c.max_missed:
                    kept.append(tr)
                continue
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
            if any(iou(d.box, k.box) > 0.5 for k in keep):
                self._tracks = [t for t in self._tracks if t.object_id != d.object_id]
                continue
            keep.append(d)
        return keep
