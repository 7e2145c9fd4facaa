"""One tracked person: Kalman state, smoothed box size, appearance model and lifecycle.

States (:class:`TrackState`) and the rules of :func:`next_state`:

* ``tentative`` -- started from an unassigned detection; becomes ``confirmed`` after
  ``min_hits`` detections, is deleted after more than ``max_tentative_misses`` consecutive
  frames without one (a false positive never gets an output id of its own for long);
* ``confirmed`` -- seen this frame, by a detection or by a multiple-kernel refinement whose
  similarity is at least ``occlusion_similarity``;
* ``occluded`` (coasting) -- neither: the Kalman prediction (4.2)-(4.3) continues alone while
  the multiple-kernel search keeps running from the prediction; its adaptive kernel weights
  (Chu et al. 2013, Sec. III-D, (7)-(8)) shift trust to the kernels that are still visible;
  a track started by hand that coasts until its prediction's position std exceeds its
  bound is ``held`` (:meth:`Track.hold_if_uncertain`): the prediction stops and the box
  stands where the target was last believed to be, still searched for;
* a track seen only by its multiple-kernel refinement for longer than
  ``max_undetected_time`` is ``lost`` (a refiner locked on background must not live on),
  unless it moves slower than ``still_speed`` box heights per second: the kernel covariance
  detector (Schizas et al. 2018) finds only what moves, so a person standing still gets no
  detections, and the track stays while its appearance still matches (``visible``);
* ``lost`` -- coasted for longer than ``max_coast_time`` (or the prediction left the image):
  no output box, but the track is kept for ``max_lost_time`` so that a detection near its
  predicted position that matches its appearance model takes its id back.  This answers the
  limitation Chu et al. state in Sec. V-D (long total occlusion);
* ``deleted`` -- final.  Ids are never reused.

The centre is filtered by :class:`mk_tracker.kalman.ConstantVelocityKalman` ((2.1)-(2.3),
(4.1)-(4.5) of Schizas et al. 2018).  The measurement noise of every update follows the match
quality (:func:`measurement_sigma`): a poor multiple-kernel similarity or a low detection score
informs the filter less.  Box size and reported velocity are exponentially smoothed so the
output does not jitter.
"""

from __future__ import annotations

import copy
import enum
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from mk_tracker.boxes import center_to_xywh
from mk_tracker.kalman import ConstantVelocityKalman, KalmanConfig
from mk_tracker.parameters import parameter


class TrackState(str, enum.Enum):
    """Lifecycle state of a track (see the module docstring)."""

    TENTATIVE = "tentative"
    CONFIRMED = "confirmed"
    OCCLUDED = "occluded"
    LOST = "lost"
    DELETED = "deleted"


#: States whose box is reported as a tracked target (MOTChallenge output, the node's topic).
OUTPUT_STATES = (TrackState.CONFIRMED, TrackState.OCCLUDED)


@dataclass(frozen=True)
class LifecycleConfig:
    """Constants of the track lifecycle and of its smoothing."""

    min_hits: int = parameter(3, "Detections a tentative track needs to be confirmed",
                              minimum=1, maximum=1000)
    max_tentative_misses: int = parameter(
        0, "Consecutive frames without a detection after which a tentative track is deleted",
        minimum=0, maximum=1000)
    occlusion_similarity: float = parameter(
        0.6, "Multiple-kernel similarity below which an undetected track is occluded "
        "(coasting on the Kalman prediction)", minimum=0.0, maximum=1.0)
    visibility_statistic: str = parameter(
        "mean", "Statistic of the kernel similarities compared with occlusion_similarity and "
        "mapped to the measurement quality: mean (plain mean) or weighted (sum_i W_i rho_i / N "
        "with the adaptive weights (7)-(8): one occluded kernel does not make a visible target "
        "occluded)", choices=("mean", "weighted"))
    max_coast_time: float = parameter(
        1.0, "Seconds a track may coast (occluded, no detection) before it is lost",
        minimum=0.0, maximum=1e4)
    max_lost_time: float = parameter(
        4.0, "Seconds a lost track is kept for re-acquisition before it is deleted",
        minimum=0.0, maximum=1e5)
    max_undetected_time: float = parameter(
        0.5, "Seconds a track may go on by its multiple-kernel refinement alone, with no "
        "detection, before it is lost (a refiner locked on background must not live on); "
        "0 = no limit.  Tracks started by hand are exempt", minimum=0.0, maximum=1e5)
    still_speed: float = parameter(
        0.3, "A visible track moving slower than this many box heights per second is exempt "
        "from max_undetected_time (the kernel covariance detector finds only what moves: a "
        "person standing still gets no detections while the multiple-kernel appearance "
        "still matches); 0 = no exemption", minimum=0.0, maximum=100.0)
    still_contrast: float = parameter(
        0.0, "A still track (still_speed) whose multiple-kernel level is below "
        "occlusion_similarity still counts as visible when sqrt(level x contrast) is at "
        "least this, the contrast being the mean over kernels of the located peak against "
        "a ring of copies one box size away (peak_contrast.py: it stands out whatever the "
        "light; a person who left leaves a flat neighbourhood); 0 = off", minimum=0.0,
        maximum=1.0)
    still_needs_visible: bool = parameter(
        True, "The still_speed exemption from max_undetected_time holds only in frames where "
        "the multiple-kernel refinement sees the track (visible); false: a still track that "
        "stops matching for a frame coasts (occluded) like any other and is lost "
        "max_coast_time after it was last seen, not at once")
    size_smoothing: float = parameter(
        0.6, "Weight of a new measured box size in the exponential size smoothing "
        "(scaled by match quality; 1 = no smoothing)", minimum=0.0, maximum=1.0)
    velocity_smoothing: float = parameter(
        0.5, "Weight of the newest Kalman velocity in the reported (smoothed) velocity",
        minimum=0.0, maximum=1.0)
    refinement_size_weight: float = parameter(
        0.2, "Factor on the size-smoothing weight for sizes measured by the multiple-kernel "
        "scale update alone (detections give better sizes)", minimum=0.0, maximum=1.0)
    measurement_noise: float = parameter(
        0.02, "Centroid measurement std (4.1) of a perfect match, as a fraction of the box "
        "height", minimum=1e-4, maximum=10.0)
    min_noise_px: float = parameter(1.0, "Lower bound of the centroid measurement std, px",
                                    minimum=1e-3, maximum=1e4)
    quality_floor: float = parameter(
        0.1, "Lowest match quality used to scale the noise: std = noise / max(q, floor)",
        minimum=1e-3, maximum=1.0)
    observation_centric_reupdate: bool = parameter(
        False, "When a detection comes back to a track that coasted unseen for more than "
        "one frame, re-run its Kalman filter from the last seen state through virtual "
        "observations on the straight line to the new one (OC-SORT's observation-centric "
        "re-update, Cao et al. 2023, Sec. 4.1), instead of correcting the drifted "
        "prediction.  Off by default: the leave-one-sequence-out grid of "
        "benchmarks/bench_multi_object.py chose it for one held-out sequence of four")


def measurement_sigma(box_height: float, quality: float, config: LifecycleConfig) -> float:
    """Std (px) of a centroid measurement (4.1) whose match quality is ``quality`` in [0, 1].

    ``sigma_w = max(measurement_noise * h, min_noise_px) / max(quality, quality_floor)``: a
    similarity of 0.5 doubles the std, so the gain (4.5) trusts that measurement less.
    """
    q = quality if math.isfinite(quality) else 0.0
    q = min(max(q, config.quality_floor), 1.0)
    base = max(config.measurement_noise * float(box_height), config.min_noise_px)
    return base / q


def next_state(state: TrackState, *, detected: bool, visible: bool, in_image: bool,
               hits: int, tentative_misses: int, unseen_time: float, lost_time: float,
               config: LifecycleConfig, undetected_time: float = 0.0,
               still: bool = False) -> TrackState:
    """The lifecycle transition of one track for one frame (pure function).

    ``detected``: a detection was assigned this frame.  ``visible``: the multiple-kernel
    refinement matched with at least ``occlusion_similarity``.  ``in_image``: the predicted
    box overlaps the image.  ``hits``: detections so far (this one included).
    ``tentative_misses``: consecutive undetected frames (this one included).
    ``unseen_time``: seconds since the track was last detected or visible.  ``lost_time``:
    seconds since it became lost.  ``undetected_time``: seconds since the last detection
    (pass 0 for tracks exempt from ``max_undetected_time``).  ``still``: the track moves
    slower than ``still_speed`` (a visible still track is exempt from
    ``max_undetected_time``).
    """
    if state is TrackState.DELETED:
        return state
    if state is TrackState.TENTATIVE:
        if detected:
            return TrackState.CONFIRMED if hits >= config.min_hits else TrackState.TENTATIVE
        if tentative_misses > config.max_tentative_misses or not in_image:
            return TrackState.DELETED
        return TrackState.TENTATIVE
    if detected:
        return TrackState.CONFIRMED
    if state is TrackState.LOST:
        return TrackState.DELETED if lost_time > config.max_lost_time else TrackState.LOST
    if not in_image:
        return TrackState.LOST
    if config.max_undetected_time > 0 and undetected_time > config.max_undetected_time \
            and not (still and (visible or not config.still_needs_visible)):
        return TrackState.LOST
    if visible:
        return TrackState.CONFIRMED
    if unseen_time > config.max_coast_time:
        return TrackState.LOST
    return TrackState.OCCLUDED


@dataclass(frozen=True)
class TrackOutput:
    """What the tracker reports about one track in one frame.

    ``box`` is ``(x, y, w, h)`` at the frame time; ``score`` the match quality this frame
    (multiple-kernel similarity, or the detection score when no refiner runs; 0 when
    coasting); ``velocity`` ``(vx, vy)`` in px/s; ``age`` seconds since the track started;
    ``time_since_detection`` seconds since a detection was last assigned; ``manual`` for a
    track started by hand (:meth:`MultiObjectTracker.start_track`).
    ``velocity_covariance`` and ``position_covariance`` are the velocity ((px/s)^2) and
    centre (px^2) blocks of the Kalman error covariance P(t|t) ((4.3), (4.5)), row-major
    ``(xx, xy, yx, yy)``; the velocity's is that of the filter's own velocity estimate, of
    which ``velocity`` is the exponentially smoothed value.  ``last_match_iou`` is
    :attr:`Track.last_match_iou` (how well the prediction met the last detection).
    """

    id: int
    state: str
    box: tuple[float, float, float, float]
    score: float
    velocity: tuple[float, float]
    age: float
    time_since_detection: float
    hits: int
    manual: bool = False
    velocity_covariance: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    position_covariance: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    last_match_iou: float = 1.0


class Track:
    """Mutable per-track state; the tracker drives it, :func:`next_state` decides its state."""

    def __init__(self, track_id: int, box: np.ndarray, stamp: float, *, score: float,
                 kalman: KalmanConfig, config: LifecycleConfig,
                 state: TrackState = TrackState.TENTATIVE) -> None:
        x, y, w, h = (float(v) for v in box)
        self.id = int(track_id)
        self.config = config
        self.kf = ConstantVelocityKalman.from_config((x + w / 2.0, y + h / 2.0), kalman)
        self.size = np.array([w, h])
        self.state = state
        self.created = float(stamp)
        self.stamp = float(stamp)
        self.last_detection = float(stamp)
        #: the box of the last detection assigned to the track (the observation itself, not
        #: the filtered box), for re-acquisition from the last detection
        self.detected_box = np.array([x, y, w, h])
        self.detected_stamp = float(stamp)     # when detected_box was observed
        self.last_seen = float(stamp)
        self.lost_since: float | None = None
        self.hits = 1
        self.tentative_misses = 0
        #: IoU of the predicted box (4.2) with the detection assigned at the last detected
        #: update, before the correction: how well the motion and size model met the last
        #: observation (1 until a prediction has met one); FrameResult.reported() leaves a
        #: coasting track out below min_reported_coast_match_iou (tracker_config.py)
        self.last_match_iou = 1.0
        self.score = float(score)
        self.smoothed_velocity = np.zeros(2)
        self.target: Any = None            # the refiner's working target (TargetState)
        self.references: list[Any] = []    # frozen appearance models for re-acquisition
        self.target_stamp: float | None = None
        self.refined_box: np.ndarray | None = None
        self.manual = False                # started by hand: no detector needed
        self.held = False                  # coasting at a held position (no prediction)
        # filter and centre at the last frame the track was seen (detected or visible), for
        # the observation-centric re-update
        self.seen_filter: ConstantVelocityKalman | None = None
        self.seen_center: np.ndarray | None = None

    # -- geometry -----------------------------------------------------------------------
    @property
    def center(self) -> np.ndarray:
        return self.kf.center

    @property
    def box(self) -> np.ndarray:
        """Current box ``(x, y, w, h)``: Kalman centre with the smoothed size."""
        cx, cy = self.kf.center
        return np.array(center_to_xywh(cx, cy, self.size[0], self.size[1]))

    def predict(self, stamp: float) -> None:
        """Advance the Kalman filter to ``stamp`` ((4.2)-(4.3)); no-op for dt <= 0.

        A ``held`` track (a coasting track whose prediction became too uncertain to guide a
        search, :meth:`hold_if_uncertain`) keeps its position: only its stamp advances."""
        dt = float(stamp) - self.stamp
        if dt > 0 and not self.held:
            self.kf.predict(dt)
        self.stamp = float(stamp)

    @property
    def position_std(self) -> float:
        """Largest std (px) of the centre estimate, sqrt of the larger diagonal entry of the
        position block of P."""
        p = self.kf.covariance
        return math.sqrt(max(float(p[0, 0]), float(p[1, 1]), 0.0))

    def hold_if_uncertain(self, seen: bool, max_std_widths: float) -> bool:
        """Decide whether the track holds its position from the next frame on.

        A seen track (this frame's measurement corrected it) is not held.  An unseen one is
        held once its position std exceeds ``max_std_widths`` box widths: the constant-
        velocity prediction (4.2) then says less about where the person is than the
        search region around it covers, so extrapolating the old velocity further only
        carries the box away from where the person was last seen.  ``max_std_widths`` 0
        never holds.  Returns the new ``held``."""
        if seen or max_std_widths <= 0.0:
            self.held = False
        elif not self.held:
            self.held = self.position_std > max_std_widths * float(self.size[0])
        return self.held

    def innovation_covariance(self, box_height: float, quality: float = 1.0) -> np.ndarray:
        """``H P H^T + sigma_w^2 I`` with the quality-dependent measurement std."""
        return self.kf.innovation_covariance(measurement_sigma(box_height, quality,
                                                               self.config))

    def correct(self, box: np.ndarray, quality: float, use_size: bool = True,
                size_weight: float = 1.0) -> None:
        """Kalman update (4.4)-(4.5) with the centre of ``box``, and size smoothing.

        The measurement std and the size-smoothing weight both follow ``quality``;
        ``use_size=False`` updates the centre only; ``size_weight`` scales the size update.
        """
        x, y, w, h = (float(v) for v in box)
        q = min(max(float(quality), 0.0), 1.0) if math.isfinite(quality) else 0.0
        self.kf.update((x + w / 2.0, y + h / 2.0),
                       sigma_w=measurement_sigma(h, q, self.config))
        if not use_size:
            return
        alpha = size_weight * self.config.size_smoothing * max(q, self.config.quality_floor)
        self.size = (1.0 - alpha) * self.size + alpha * np.array([w, h])

    def reupdate_from_last_seen(self, box: np.ndarray, stamp: float,
                                frame_interval: float) -> bool:
        """OC-SORT's observation-centric re-update (Cao et al. 2023, Sec. 4.1, "ORU").

        A constant-velocity filter that coasted through an occlusion accumulates the error
        of its last velocity; when the person is detected again, correcting that drifted
        state once leaves a wrong velocity.  Instead the filter is rewound to its state at
        the last frame the track was seen (:attr:`seen_filter`, at :attr:`last_seen`) and
        re-run through virtual observations of the centre on the straight line from
        :attr:`seen_center` to the centre of ``box``, one per ``frame_interval`` of the gap,
        each a predict (4.2)-(4.3) and an update (4.4)-(4.5) with the std of a perfect match
        (:func:`measurement_sigma` at quality 1); it ends at the last virtual frame before
        ``stamp``, so the caller's :meth:`correct` with ``box`` is the final observation.

        Does nothing (returns False) when the gap is at most 1.5 frame intervals, when no
        seen state exists or when ``frame_interval`` is not positive.
        """
        if self.seen_filter is None or self.seen_center is None or frame_interval <= 0:
            return False
        gap = float(stamp) - self.last_seen
        if gap <= 1.5 * frame_interval:
            return False
        x, y, w, h = (float(v) for v in box)
        target = np.array([x + w / 2.0, y + h / 2.0])
        n = max(int(round(gap / frame_interval)), 2)
        kf = copy.deepcopy(self.seen_filter)
        sigma = measurement_sigma(h, 1.0, self.config)
        step = gap / n
        for k in range(1, n):
            kf.predict(step)
            kf.update(self.seen_center + (target - self.seen_center) * (k / n), sigma_w=sigma)
        kf.predict(step)
        self.kf = kf
        return True

    def is_still(self) -> bool:
        """Whether the track's Kalman velocity is below ``still_speed`` box heights per
        second (False when ``still_speed`` is 0)."""
        cfg = self.config
        return cfg.still_speed > 0.0 and \
            float(np.hypot(*self.kf.velocity)) < cfg.still_speed * float(self.size[1])

    def remember_seen(self) -> None:
        """Keep the filter and centre of a frame in which the track was seen."""
        self.seen_filter = copy.deepcopy(self.kf)
        self.seen_center = np.array(self.kf.center, dtype=float)

    def finish_frame(self) -> None:
        """Update the reported (smoothed) velocity after this frame's corrections."""
        a = self.config.velocity_smoothing
        velocity = np.zeros(2) if self.held else self.kf.velocity   # a held box stands still
        self.smoothed_velocity = (1.0 - a) * self.smoothed_velocity + a * velocity

    def output(self) -> TrackOutput:
        b = self.box
        p = self.kf.covariance
        return TrackOutput(id=self.id, state=self.state.value,
                           box=(float(b[0]), float(b[1]), float(b[2]), float(b[3])),
                           score=float(self.score),
                           velocity=(float(self.smoothed_velocity[0]),
                                     float(self.smoothed_velocity[1])),
                           age=self.stamp - self.created,
                           time_since_detection=self.stamp - self.last_detection,
                           hits=self.hits, manual=self.manual,
                           velocity_covariance=(float(p[2, 2]), float(p[2, 3]),
                                                float(p[3, 2]), float(p[3, 3])),
                           position_covariance=(float(p[0, 0]), float(p[0, 1]),
                                                float(p[1, 0]), float(p[1, 1])),
                           last_match_iou=float(self.last_match_iou))
