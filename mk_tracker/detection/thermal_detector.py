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
* **Background footprints** (``drop_background_footprints``).  Beside a large warm object
  (a person near the camera) the band of support it swept on its trailing side is
  surrounded mostly by the object's own unchanged pixels, so the *local* background of
  that band is the object, and the plain background next to it passes the footprint test
  (on the colder side).  In full-frame passes an object whose footprint's mean is within
  the similarity radius of (3.6) of the scene background (the median of the newest frame's
  non-support pixels) while its local background is not, is dropped; without this rule
  such a ghost took the upper or lower half of the person through the tracking passes'
  Voronoi cells (one person at 640x480 reported as two for 60 frames,
  docs/benchmark_groups.md).
* **Linked support** (``link_gap``): support pixels closer than ``link_gap`` px always belong
  to one object, in addition to (3.13).  With (3.13) alone, ``epsilon_d`` must be of the
  order of (half an object)^2, i.e. a size prior; the link rule and the footprint merge
  make the default scale-free at the price of merging people who touch (the optional
  valley split below separates them again; ``link_gap=0, merge_by_footprint=False`` with a
  large ``merge_distance_sq`` is the paper's rule alone).
* **Optional splits of groups**, off by default (each measured in
  docs/benchmark_groups.md, and documented in its own module): the valley split
  (``split_by_valleys``: a watershed from the intensity peaks of a footprint,
  :func:`mk_tracker.detection.pixel_clustering.valley_split`; ``valley_columns``: column
  ranges of upright people instead); the person-size split (``split_by_person_size``: a
  footprint wider than ``split_ratio`` expected widths at its row is cut at the emptiest
  columns, and the next full pass comes ``group_recheck_frames`` after the last one;
  :mod:`mk_tracker.detection.footprint_split`); the cluster split (``split_clusters``: the
  K-means clusters (3.12)-(3.13) grouped into people by the learnt size,
  :mod:`mk_tracker.detection.crowd_split`); the extent bound (``extent.bound``: an object
  wider than half the frame or three person widths re-split by K-means (3.12),
  :mod:`mk_tracker.detection.object_extent`); previous objects kept apart
  (``keep_apart.enabled``: K-means (3.12) started at the Kalman predictions (4.2) of the
  objects a footprint holds, :mod:`mk_tracker.detection.keep_apart`); and stacked parts
  joined (``body_extent.join_stacked``: an upper and a lower box of one person reported as
  one, :mod:`mk_tracker.detection.body_extent`).  The expected person height at each image
  row is learnt online from the person-shaped detections
  (:mod:`mk_tracker.detection.person_size`, a least-squares line in the row of the feet).
* **Person cover** (``person_cover.*``, on).  After every pass, a detection wider or taller
  than one person at the learnt person size of its bottom row is replaced by whole-person
  boxes that cover its warm pixels greedily (:mod:`mk_tracker.detection.person_cover`),
  while the learnt heights follow the image row (a ground plane); the objects and their
  Kalman filters are unchanged.  In generated crowds it lifts the held-out thermal -> RGB
  pipeline by 0.14 MOTA; on BU-TIV-lab (no ground plane) it never acts
  (docs/benchmark_groups.md).
* **Stacked parts joined** (``body_extent.join_stacked``).  A person reported as an upper
  and a lower box (two objects of one full pass, each keeping its Voronoi cell) is
  reported as one box; the objects themselves are unchanged
  (:mod:`mk_tracker.detection.body_extent`).  Off by default (docs/benchmark_groups.md).
* The (5.2) window is the object's box plus ``window_margin`` pixels plus the distance the
  Kalman velocity covers in the window's time span on each side, snapped to the ``rho``
  grid so that overlapping windows share blocks (their union is factored once).  Support
  pixels in a window go to the object whose predicted centroid is nearest.
* At a reconfiguration, objects found again keep their Kalman filter (Hungarian matching on
  predicted-centroid distance); the others are kept ``max_missed`` frames, then dropped.
* Objects with fewer than ``min_object_pixels`` support pixels are dropped as noise; an
  object whose window has no support for more than ``max_missed`` frames is dropped until
  the next full-frame pass finds it again (a person who stands still has no temporal change
  and is, as in the paper, not detected by the support).
* **Bandwidth and noise** (``noise_bandwidth``, on).  The kernel (3.6) keeps the paper's
  ``sigma2`` unless ``noise_bandwidth`` (3) times the stream's temporal noise std, measured
  at each full-frame pass, exceeds its ``sigma``; then ``sigma`` is widened to that, so
  that a noisy stream does not make every block change
  (:mod:`mk_tracker.detection.stream_noise`; docs/benchmark_thermal_conditions.md).
* **Windows in seconds** (``counts_fps``, on).  ``window_frames``, ``startup_frames``,
  ``reconfigure_period`` and ``group_recheck_frames`` are counted at 25 fps; on a slower
  stream (rate from the stamps, :class:`mk_tracker.stamps.FrameRate`) they keep their
  durations (docs/benchmark_thermal_frame_rate.md).  A frame identical to the one before
  (a frozen camera) is skipped (``last_mode`` ``repeated_frame``).
* **Still people** (``still_people.enabled``, on): a warm region of a detected person's
  shape, size and warmth that stays in place for ``still_people.min_time`` is reported too
  (:mod:`mk_tracker.detection.still_people`; docs/benchmark_real_thermal.md).
* Centroids are continuous (pixel ``(c, r)`` has centre ``(c + 0.5, r + 0.5)``), not the
  floor in the definition of Sec. 2.
* Frames: NaN/inf pixels are held at their last valid value (:mod:`mk_tracker.detection.thermal_image`);
  a frame with fewer than ``min_valid_fraction`` valid pixels, or a stamp equal to the
  previous one, is skipped (no detections, ``skipped_frames`` counts it); a frame of another
  size or encoding resets the detector (``resets``, ``last_reset``), and so does a stamp
  earlier than the previous one (a bag played in a loop: ``time_resets``, ``last_event``
  says by how much), after which the new frames fill a new window and detection resumes
  after ``F_s`` of them, as at start-up.
* **AGC compensation** (``gain.model``, off by default): each frame is mapped onto the
  previous frame of the window by an affine or quadratic intensity map fitted over the
  static pixels, so that a change of the camera's automatic gain control is not temporal
  change to (3.5); a change too large to compensate starts a new window (``gain_resets``)
  (:mod:`mk_tracker.detection.gain_compensation`).  Memory is bounded: a
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
Algorithm 1 per block (:mod:`mk_tracker.detection.block_support`); in a tracking pass one
call per object finds its support pixels by one scan of its (5.2) window, gathers their
kernel variances and finds its footprint by one flood fill
(:mod:`mk_tracker.detection.footprint`).  32FC1 frames use the numpy support path.  This
module holds the logic of Algorithm 2; the per-pixel and per-block loops live in those two.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from mk_tracker.tracking.association import assign
from mk_tracker.boxes import iou
from mk_tracker.detection.block_support import SupportResult, _support, support_in_frame
from mk_tracker.detection.body_extent import BodyExtent
from mk_tracker.detection.crowd_split import CrowdSplitting
from mk_tracker.detection.frame_window import FrameWindow
from mk_tracker.detection.footprint import (_NO_CENTRES, _UNSET, _VoronoiCell, _median,
                                            _object_kernel, _owned_support,
                                            _similarity_radius, footprint_mask,
                                            footprint_stats, overlapping_footprints)
from mk_tracker.kalman import ConstantVelocityKalman
from mk_tracker.parameters import validate_config
from mk_tracker.detection.gain_compensation import IntensityMap, compensate
from mk_tracker.detection.footprint_split import (FootprintSplitting, _Candidate,
                                                 _footprint_levels)
from mk_tracker.detection.keep_apart import KeepApart
from mk_tracker.detection.object_extent import ObjectExtent
from mk_tracker.detection.person_cover import PersonCover
from mk_tracker.detection.person_size import PersonHeightModel
from mk_tracker.detection.still_people import StillPeople
from mk_tracker.detection.stream_noise import NoiseBandwidth
from mk_tracker.detection.pixel_clustering import (cluster_support_pixels, describe_pixels,
                                                   link_groups, merge_linked)
from mk_tracker.stamps import FrameRate, checked_stamp
from mk_tracker.detection.thermal_detector_config import ThermalDetectorConfig
from mk_tracker.detection.thermal_image import (ThermalInputError, as_thermal_array, fill_missing,
                                      normalization_map, robust_range, thermal_view)

__all__ = ["ThermalDetectorConfig", "ThermalDetection", "ThermalDetector", "ThermalInputError",
           "SupportResult", "support_in_frame"]


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
class _Track:
    """One object of Algorithm 2: its filter, last box, id and bookkeeping."""

    object_id: int
    kf: ConstantVelocityKalman
    box: tuple[float, float, float, float]
    stamp: float
    missed: int = 0
    size: tuple[float, float] = (math.inf, math.inf)   # box size at its last full pass
    passes: int = 0      # full passes that found it as an object of its own (keep_apart)


def _box_detection(box: tuple, score: float, pixels: int, object_id: int = -1
                   ) -> ThermalDetection:
    """A detection known by its box only, centred in it: a ``still_people`` region (no
    Kalman filter of its own: ``object_id`` -1) or a person box of ``person_cover``."""
    return ThermalDetection(box=box, centroid=(box[0] + box[2] / 2.0, box[1] + box[3] / 2.0),
                            score=score, pixel_count=pixels, object_id=object_id)


def _piece(group: ThermalDetection, box: tuple) -> ThermalDetection:
    """One person box of ``person_cover`` in a group detection: the group's score, pixel
    count and object id (its Kalman filter follows the group)."""
    return _box_detection(box, group.score, group.pixel_count, group.object_id)


def _overlap(a: tuple, b: tuple) -> bool:
    """Whether boxes ``(x, y, w, h)`` share area: the test of
    :func:`mk_tracker.boxes.intersection_area` (False there means an IoU of 0)."""
    return (min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0]) > 0
            and min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1]) > 0)


class ThermalDetector(FootprintSplitting, CrowdSplitting, BodyExtent, ObjectExtent,
                      KeepApart, PersonCover):
    """Streaming detector (Algorithm 2).  Feed frames in time order with :meth:`process`.

    Counters the node can log: ``resets`` (frame size or encoding changed, or time went
    backwards, or, with ``gain.model``, the intensities changed too much to compensate),
    ``time_resets`` (time only), ``gain_resets`` (intensities only), ``skipped_frames``
    (too few valid pixels, or the same stamp as the previous frame), ``full_passes``;
    ``gain_map`` is the last intensity map fitted (``gain.model``); ``last_mode`` is one of
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
        self._window = FrameWindow(max(c.window_frames, c.startup_frames))
        self._rate = FrameRate(c.rate_window)
        self.resets = 0
        self.time_resets = 0
        self.last_event: str | None = None
        self.skipped_frames = 0
        self.repeated_frames = 0          # of them, identical to the frame before
        self.gain_resets = 0
        self.gain_map: IntensityMap | None = None
        self.full_passes = 0
        self.last_mode = "warming_up"
        self.last_reset = False
        self._clear()

    # -- state -----------------------------------------------------------------------------
    def _clear(self) -> None:
        self._window.clear()
        self._shape: tuple[int, int] | None = None
        self._encoding: str | None = None
        self._last_stamp: float | None = None
        self._last_filled: np.ndarray | None = None
        self._last_raw: np.ndarray | None = None     # the last frame used, as received
        self._tracks: list[_Track] = []
        self._next_id = 1
        self._since_full: int | None = None
        self._map: tuple[float, float] | None = None
        self._integer = False
        c = self.config
        self.heights = PersonHeightModel(c.size_memory, c.size_max_residual if
                                         c.size_max_residual < 100 else math.inf,
                                         c.size_min_samples)
        self.aspects = np.zeros(2)      # forgetting sums of (1, width / height) of samples
        # object id -> number of its newest size sample (_note_size_object)
        self.size_objects: dict[int, int] = {}
        self._size_samples = 0
        self._group_seen = False        # a tracking pass saw a footprint of several people
        self._oversize_seen = False     # extent.bound: a tracking pass met a group
        self._extents: dict = {}        # body_extent: object id -> its person's extent
        self._still = StillPeople(c.still_people, c.person_aspect)
        self._bandwidth = NoiseBandwidth(c.sigma2, c.noise_bandwidth)

    def reset(self) -> None:
        """Forget every frame and object (counters are kept)."""
        self._clear()
        self.last_mode = "warming_up"

    @property
    def kernel_sigma2(self) -> float:
        """The kernel variance (3.6) in use (unit scale): ``sigma2``, or wider on a noisy
        stream (``noise_bandwidth``)."""
        return self._bandwidth.sigma2

    @property
    def stream_noise(self) -> float:
        """The temporal noise std measured at the recent full-frame passes (unit scale)."""
        return self._bandwidth.noise

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
        if self._last_raw is not None and raw.shape == self._last_raw.shape and \
                np.array_equal(raw, self._last_raw, equal_nan=enc == "32FC1"):
            # a frozen camera (an uncooled core's shutter / flat-field correction holds the
            # image for a few tenths of a second; a driver that repeats its last frame): no
            # new information, and in the window it would look like people who stopped
            self.skipped_frames += 1
            self.repeated_frames += 1
            self.last_mode = "repeated_frame"
            return []
        self._last_raw = np.array(raw, copy=True)
        c = self.config
        filled = raw
        if enc == "32FC1":
            filled, _ = fill_missing(raw, self._last_filled)
            self._last_filled = filled
        else:
            self._last_filled = None      # only float frames are filled from the previous one
        if c.gain.model != "off":
            filled = self._gain_compensated(filled, enc, t)
        if self._last_stamp is not None:
            self._rate.add(t - self._last_stamp)
        self._shape, self._encoding, self._last_stamp = raw.shape, enc, t
        self._window.add(filled, t)
        if self._since_full is None:
            if len(self._window) < self._count(c.startup_frames, 2):
                self.last_mode = "warming_up"
                return []
            self.last_mode = "startup"
            return self._finish(self._full_pass(), True)
        self._since_full += 1
        if self._since_full >= self._count(c.reconfigure_period) or (
                (self._group_seen or self._oversize_seen)
                and self._since_full >= self._count(c.group_recheck_frames)):
            self.last_mode = "reconfiguration"
            return self._finish(self._full_pass(), True)
        self.last_mode = "tracking"
        return self._finish(self._tracking_pass(), False)

    def _finish(self, detections: list[ThermalDetection], full_pass: bool
                ) -> list[ThermalDetection]:
        """Sizes learnt, whole bodies joined, groups covered by person boxes
        (``person_cover``), still people added (``still_people``)."""
        found = self._covered(self._whole_bodies(self._learn_sizes(detections)), _piece)
        if not self.config.still_people.enabled:
            return found
        return self._still.step(self._newest(), self._raw_radius(), found, self._last_stamp,
                                full_pass, _box_detection)

    # -- normalisation ---------------------------------------------------------------------
    def _gain_compensated(self, frame: np.ndarray, enc: str, stamp: float) -> np.ndarray:
        """``gain.model``: ``frame`` mapped onto the newest frame of the window
        (:func:`mk_tracker.detection.gain_compensation.compensate`); a change too large to
        compensate starts a new window from ``frame`` as it is (``gain_resets``,
        ``last_event``)."""
        if not len(self._window):
            self.gain_map = None
            return frame                 # the first frame of a window sets its photometry
        mapped, self.gain_map = compensate(frame, self._newest(), self.config.gain,
                                           self._raw_radius())
        if mapped is not None:
            return mapped
        fit = self.gain_map
        self.last_event = (f"intensity change too large to compensate (gain {fit.gain:.2f}, "
                           f"{100 * fit.similar_fraction:.0f} % of the pixels similar after "
                           "the fit): new window")
        last_filled = self._last_filled
        self._clear()
        self._last_filled = last_filled
        self._shape, self._encoding, self._last_stamp = frame.shape, enc, stamp
        self.resets += 1
        self.gain_resets += 1
        self.last_reset = True
        return frame

    def _raw_radius(self) -> float:
        """The similarity radius of (3.6) in raw units of the current encoding: by the
        window's map, or before the first full pass by the paper's mono8 scale or the
        robust range of the newest frame."""
        if self._map is not None:
            scale = self._map[1]
        elif self._encoding == "mono8":
            scale = normalization_map("mono8", None)[1]
        else:
            rng = robust_range(self._newest())
            scale = normalization_map(self._encoding, rng if rng else (0.0, 1.0))[1]
        return float(_similarity_radius(self._bandwidth.sigma2)) / scale

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

    def _count(self, frames: int, minimum: int = 1) -> int:
        """``frames`` counted at ``counts_fps``, in frames of this stream: the same duration
        on a slower stream (at least ``minimum``), the count itself otherwise."""
        return self._rate.frames(frames, self.config.counts_fps, minimum, slower_only=True)

    def _newest(self) -> np.ndarray:
        """The newest frame as stored (raw, float32; window units are ``raw - offset``)."""
        return self._window.newest()

    # -- passes ----------------------------------------------------------------------------
    def _full_pass(self) -> list[ThermalDetection]:
        """Algorithm 2, line 1: start-up / reconfiguration over the whole frame, F_s frames."""
        c = self.config
        self.full_passes += 1
        self._since_full = 0
        self._oversize_seen = False
        order = self._window.order(self._count(c.startup_frames, 2))
        frames = self._window.frames(len(order))
        self._update_map(frames)
        before = self._bandwidth.sigma2
        if self._bandwidth.observe(frames, self._map[1]) != before:
            self.last_event = (f"stream noise {self._bandwidth.noise:.3g} (unit intensity "
                               f"scale): kernel bandwidth sigma2 {before:.3g} -> "
                               f"{self._bandwidth.sigma2:.3g} (noise_bandwidth)")
        result = _support(self._window.ring, order, self._map[0], c, self._map[1],
                          self._integer, None, sigma2=self._bandwidth.sigma2)
        frame = self._newest()
        bounds = (0, frame.shape[0], 0, frame.shape[1])
        rows, cols = np.nonzero(result.support)
        candidates: list[_Candidate] = []
        parts: set[int] = set()       # ids of the candidates made by keep_apart
        made: list[_Candidate] = []    # ... and the candidates, so that no id is reused
        if rows.size:
            _, labels = cluster_support_pixels(np.column_stack([cols, rows]),
                                               max_objects=c.max_objects,
                                               merge_distance_sq=c.merge_distance_sq)
            # with a size check, split_clusters only while the learnt size holds (person_size)
            crowd = c.current_frame_refinement and c.split_clusters and self.heights.allows()
            if c.link_gap > 0 and not crowd:
                labels = merge_linked(labels, link_groups(result.support, c.link_gap)[rows, cols])
            groups = [np.flatnonzero(labels == k) for k in range(int(labels.max()) + 1)]
            groups = [g for g in groups if g.size >= c.min_object_pixels]
            if crowd:
                candidates = self._crowd_candidates(frame, result, rows, cols, groups, bounds)
                groups = []
            footprints: list[Any] = [_UNSET] * len(groups)
            if c.current_frame_refinement and c.merge_by_footprint and len(groups) > 1:
                groups, footprints = self._merge_by_footprint(frame, result.support, rows,
                                                              cols, groups, bounds)
            apart = c.current_frame_refinement and c.keep_apart.enabled and not crowd
            seeds = self._seed_points() if apart else None
            for g, fp in zip(groups, footprints):
                if c.current_frame_refinement and c.split_by_valleys:
                    candidates.extend(self._valley_candidates(frame, result, rows[g], cols[g],
                                                              bounds, fp))
                    continue
                if c.current_frame_refinement and c.split_by_person_size:
                    candidates.extend(self._size_candidates(frame, result, rows[g], cols[g],
                                                            bounds, fp))
                    continue
                cand = self._candidate(frame, result, rows[g], cols[g], bounds, footprint=fp)
                split = None if cand is None or not apart else self._apart_parts(
                    frame, result, rows[g], cols[g], bounds, cand, fp, seeds)
                if split is not None:
                    # objects followed apart that the link rule / footprint merge joined
                    candidates.extend(split)
                    parts.update(id(p) for p in split)
                    made.extend(split)
                elif cand is not None and c.extent.bound and self._oversized(cand.box):
                    # a group made one object (link rule): K-means with more clusters
                    candidates.extend(self._resplit(frame, result, rows[g], cols[g], bounds))
                elif cand is not None:
                    candidates.append(cand)
            if c.extent.bound:
                candidates = [cand for cand in candidates if not self._oversized(cand.box)]
            if c.current_frame_refinement and c.drop_background_footprints and candidates:
                candidates = self._without_background(frame, result.support, candidates)
        return self._reassociate(candidates, parts)

    def _without_background(self, frame: np.ndarray, support: np.ndarray,
                            candidates: list[_Candidate]) -> list[_Candidate]:
        """``drop_background_footprints``: the candidates whose footprint is not the scene's
        background seen against a neighbour.  A footprint is the set of pixels dissimilar,
        by (3.6), to the *local* background around a cluster's support; beside a large warm
        object (a person near the camera) the trailing band of support it swept is
        surrounded mostly by that object's unchanged pixels, so the local background is
        the object and the plain background next to it becomes a "footprint" (a ghost,
        which then takes half of the person in the tracking passes' Voronoi cells).  With
        the scene background ``b`` (median of the newest frame's non-support pixels) and
        the similarity radius ``r`` of (3.6), a candidate is such a ghost when its
        footprint's mean is similar to the scene (``|level - b| <= r``) while its local
        background is not (``|local - b| > r``): an object seen against the plain
        background, however faint, is kept."""
        rest = frame[~support]
        if rest.size == 0:
            return candidates
        scene = float(_median(rest[::max(1, rest.size // 8192)]))
        radius = float(self._radius())
        return [cand for cand in candidates
                if not (abs(cand.level - scene) <= radius < abs(cand.local - scene))]

    def _merge_by_footprint(self, frame: np.ndarray, support: np.ndarray, rows: np.ndarray,
                            cols: np.ndarray, groups: list[np.ndarray],
                            bounds: tuple[int, int, int, int]
                            ) -> tuple[list[np.ndarray], list[Any]]:
        """Clusters whose newest-frame footprints share pixels are one object (a large
        object's swept support can fall apart into bands; its footprint does not).

        Returns the merged groups and, for each, its footprint when it was computed here
        (a group left alone) or ``_UNSET`` (a merged group: recomputed by the caller)."""
        prints, merged = overlapping_footprints(
            frame.shape, len(groups),
            lambda k: self._footprint(frame, support, rows[groups[k]], cols[groups[k]],
                                      bounds))
        out_groups = [np.concatenate([groups[k] for k in v]) for v in merged]
        out_prints = [prints[v[0]] if len(v) == 1 else _UNSET for v in merged]
        return out_groups, out_prints

    def _footprint(self, frame: np.ndarray, support: np.ndarray, rows: np.ndarray,
                   cols: np.ndarray, bounds: tuple[int, int, int, int],
                   cell: _VoronoiCell | None = None
                   ) -> tuple[tuple[int, int], np.ndarray] | None:
        """Newest-frame footprint of the object whose support is ``(rows, cols)``, searched
        inside ``bounds`` (:func:`mk_tracker.detection.footprint.footprint_mask` in the
        current window units): ``((y0, x0), mask)`` or ``None``."""
        return footprint_mask(frame, np.float32(self._map[0]), support, rows, cols, bounds,
                              self.config.window_margin, self._radius(), cell)

    def _footprint_stats(self, frame: np.ndarray, support: np.ndarray, rows: np.ndarray,
                         cols: np.ndarray, bounds: tuple[int, int, int, int],
                         cell: _VoronoiCell | None) -> Any:
        """The compiled footprint (:func:`mk_tracker.detection.footprint.footprint_stats`):
        ``((y0, x0), state, PixelObject)`` or ``None`` (nothing); ``_UNSET`` without numba."""
        return footprint_stats(frame, np.float32(self._map[0]), support, rows, cols, bounds,
                               self.config.window_margin, self._radius(), cell)

    def _radius(self) -> np.float32:
        """The similarity radius of (3.6) in window units (the map's scale)."""
        return np.float32(_similarity_radius(self._bandwidth.sigma2) / self._map[1])

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
                (y0, x0), state, now = stats
                levels = _footprint_levels(frame, result.support, ((y0, x0), state == 1))
                return _Candidate(now.centroid, now.box, score, now.pixel_count, *levels)
            fp = self._footprint(frame, result.support, rows, cols, bounds, cell)
        if fp is None:
            return None          # support the object has left: a trailing "ghost", no object
        (y0, x0), mask = fp
        fr, fc = np.nonzero(mask)
        if fr.size < c.min_object_pixels:
            return None
        now = describe_pixels(fc + x0, fr + y0)
        return _Candidate(now.centroid, now.box, score, now.pixel_count,
                          *_footprint_levels(frame, result.support, fp))

    def _reassociate(self, candidates: list[_Candidate], parts: set[int] = frozenset()
                     ) -> list[ThermalDetection]:
        """Full pass: keep the filters of objects found again, start new ones, and let the
        others go after ``max_missed`` frames.  A candidate whose ``id`` is in ``parts``
        was made by ``keep_apart`` and does not count as a pass of its own."""
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
                tr.passes += id(cand) not in parts
            else:
                tr = _Track(self._next_id,
                            ConstantVelocityKalman.from_config(cand.centroid, self.config.kalman),
                            cand.box, stamp, size=cand.box[2:],
                            passes=int(id(cand) not in parts))
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
        window = self._count(c.window_frames, 2)
        span = self._window.span(window)
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
        result = _support(self._window.ring, self._window.order(window), self._map[0], c,
                          self._map[1], self._integer, mask, sigma2=self._bandwidth.sigma2)
        centres = np.array([(s[0], s[1]) for s in preds])
        frame = self._newest()
        # the compiled path does ownership, variances and footprint of an object in one call
        compiled = _object_kernel() if c.current_frame_refinement else None
        if compiled is None:
            owned = _owned_support(result.support, regions, centres)
        else:
            offset = np.float32(self._map[0])
            radius = self._radius()
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
            if c.extent.bound and c.extent.in_tracking and self._oversized(cand.box):
                # a group: the part nearest the prediction, or neither published nor carried
                cand = self._bounded_part(frame, result, regions, centres, k, cand)
                if cand is None:
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
            # iou is 0 for boxes that do not overlap (intersection_area): only the others
            # are computed
            if any(iou(d.box, k.box) > 0.5 for k in keep if _overlap(d.box, k.box)):
                self._tracks = [t for t in self._tracks if t.object_id != d.object_id]
                continue
            keep.append(d)
        return keep
