"""Multi-object tracker: Kalman filtering + multiple-kernel refinement + detection association.

This is the core of ``tracker_node`` (a pure library: no rclpy).  One call of
:meth:`MultiObjectTracker.step` per RGB frame does, in order:

1. **Input checks.**  A time stamp that goes backwards (a bag played in a loop) resets the
   tracker and says so in ``events``; so does a frame whose size differs from the previous
   one (a camera that changed resolution: the old boxes mean nothing in the new frame), and
   the tracker then tracks at the new size (``resets`` counts both, ``totals["size_resets"]``
   the latter).
2. **Detections to the frame.**  Each detection carries a box, a score, a stamp and an image
   plane.  Thermal-plane boxes are mapped into the RGB plane by the configured 3x3 homography
   (:func:`mk_tracker.boxes.transform_box`); boxes with NaN or non-positive sizes, or
   entirely outside the image, are skipped and counted; detections whose stamp differs from
   the frame's by more than ``stale_tolerance`` are dropped and counted; the others are
   brought to the frame time with each track's Kalman velocity (constant-velocity model
   (2.1)-(2.2) of Schizas et al. 2018); :mod:`mk_tracker.tracking.detection_input`.
3. **Prediction.**  With ``camera_motion.enabled``, every track is first moved by the image
   motion since the previous frame (:mod:`mk_tracker.tracking.camera_motion`); then its
   Kalman filter is advanced to the frame time, (4.2)-(4.3).
4. **Association** (:mod:`mk_tracker.tracking.association`): Hungarian assignment of detections to
   tentative/confirmed/occluded tracks on overlap + Kalman-gated distance (and, with
   ``association.max_height_ratio``, a gate on the height ratio); 4b' a second
   round from the last detected boxes of the tracks left without one, checked by
   appearance (:mod:`mk_tracker.tracking.recovery`: drifted estimates); then the
   remaining detections (and those of still-tentative tracks) against *lost* tracks, gated
   by the Kalman prediction or by the track's last detection (whose spread grows with the
   time since it, :mod:`mk_tracker.tracking.reacquisition`), where the appearance model
   must also match (re-acquisition with the old id).  Remaining detections start tentative
   tracks, unless live tracks explain them: mostly covered (group measurements) or the
   other half, torso or legs, of a tracked person (:mod:`mk_tracker.tracking.body_parts`).
5. **Multiple-kernel refinement** (Chu et al. 2013, Sec. IV-D): for each confirmed or
   occluded track with an appearance model and no detection this frame (or every such track
   with ``refine_when_detected``), the Kalman prediction initialises the multiple-kernel
   search whose result is a Kalman measurement.  Its visibility statistic
   (``lifecycle.visibility_statistic``: the plain mean of the kernel similarities or
   ``sum_i W_i rho_i / N``, :func:`mk_tracker.tracking.multi_kernel.visibility_similarity`) sets the
   measurement noise (:func:`mk_tracker.tracking.track.measurement_sigma`) and, below
   ``lifecycle.occlusion_similarity``, marks the track occluded (coasting).  Tracks started
   by hand (:meth:`MultiObjectTracker.start_track`) use the settings of
   :class:`~mk_tracker.tracking.manual_track.ManualTrackConfig` instead (their own refiner, Kalman prior and visibility), and
   a result of theirs that sees the target with one kernel column only is searched again
   half a box width towards the seeing column (``MultiObjectTracker._refine``).
6. **Update and lifecycle** (:mod:`mk_tracker.tracking.track`); then two reported tracks
   stacked on one person for ``duplicates.min_time`` without being detected as two people
   (and, with ``duplicates.min_similarity``, alike by their appearance models) are merged
   into the older one (:mod:`mk_tracker.tracking.duplicate_tracks`); until then such a pair
   is reported as one track (``duplicates.report_one``; the other is in
   ``FrameResult.suppressed_ids``).

The refiner is any object with ``start(image, box) -> target``,
``refine(image, target, predicted_center=None) -> result`` (with ``box``, ``similarity``
and ``lost``) and ``appearance_similarity(image, target, box) -> float``:
:class:`mk_tracker.tracking.multi_kernel.MultiKernelTracker` in production, a fake in unit tests.
Per-frame work is proportional to the number of tracks; pixels are only touched by the
refiner, inside each target's search region.
"""

from __future__ import annotations

import copy
import math
from dataclasses import replace
from typing import Any, Iterable, Protocol, Sequence

import numpy as np

from mk_tracker.tracking.association import assign, association_cost, mahalanobis_matrix
from mk_tracker.tracking.body_parts import is_other_part
from mk_tracker.tracking.camera_motion import CameraMotionEstimator, compensate
# FrameDetection, PLANES and TrackerInputError are re-exported from here
from mk_tracker.tracking.detection_input import (PLANES, FrameDetection,  # noqa: F401
                                                 PreparedDetection, TrackerInputError,
                                                 detection_geometry, homography_matrix,
                                                 prepare_detections)
from mk_tracker.boxes import InvalidBoxError, as_box, iou, iou_matrix
from mk_tracker.kalman import KalmanConfig
# FrameResult, TrackKernels and coast_position_std are re-exported from here
from mk_tracker.tracking.frame_result import (FrameResult, TrackKernels,  # noqa: F401
                                              coast_position_std, track_kernels)
from mk_tracker.tracking.duplicate_tracks import (due_pairs, merge_into, publish_one_of_each,
                                                  stacked_pairs, survivor,
                                                  update_stacked_since)
from mk_tracker.tracking.group_measurement import (constrain_inside, explained_fraction,
                                                   find_groups)
from mk_tracker.tracking.tracker_config import IDENTITY_HOMOGRAPHY, MultiObjectTrackerConfig
from mk_tracker.tracking.reacquisition import (nearer_of_both, reacquire_check,
                                               reacquisition_matches, reference_similarity)
from mk_tracker.tracking.recovery import recover_into, restart_filter
from mk_tracker.tracking.image_border import clip_to_image, overlaps_image, whole_person_box
from mk_tracker.tracking.manual_track import (columns_cover, manual_track_kalman,
                                              manual_track_lifecycle,
                                              manual_track_multi_kernel, recentre_shift)
from mk_tracker.tracking.multi_kernel import MultiKernelTracker, visibility_similarity
from mk_tracker.tracking.scale_estimation import fit_height
from mk_tracker.parameters import ParameterError, validate_config
from mk_tracker.stamps import checked_stamp
from mk_tracker.tracking.track import (OUTPUT_STATES, LifecycleConfig, Track, TrackOutput, TrackState,
                              next_state)


class Refiner(Protocol):
    def start(self, image_bgr: np.ndarray, box: Sequence[float]) -> Any: ...

    def refine(self, image_bgr: np.ndarray, state: Any,
               predicted_center: Sequence[float] | None = None) -> Any: ...

    def appearance_similarity(self, image_bgr: np.ndarray, state: Any,
                              box: Sequence[float]) -> float: ...


def _check_similarity_range(name: str, value: Any) -> None:
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError) as exc:
        raise TrackerInputError(f"{name} must be two numbers (low, high), got {value!r}") \
            from exc
    if not (0.0 <= lo < hi <= 1.0):
        raise TrackerInputError(f"{name} must satisfy 0 <= low < high <= 1, got {value!r}")


def _visibility(result: Any, statistic: str) -> float:
    """The visibility statistic of a refinement result (:func:`visibility_similarity`) from
    its ``kernel_similarities`` and ``weights``; a result without them (a refiner that is
    not multiple-kernel) is judged by its ``similarity``."""
    sims = getattr(result, "kernel_similarities", None)
    if statistic == "mean" or sims is None:
        return float(getattr(result, "similarity", 0.0))
    try:
        return visibility_similarity(sims, getattr(result, "weights", None), statistic)
    except (TypeError, ValueError):
        return float(getattr(result, "similarity", 0.0))


def _quality(score: float) -> float:
    return min(max(float(score), 0.0), 1.0)


class MultiObjectTracker:
    """Tracks people through occlusion; see the module docstring for one step's work."""

    def __init__(self, config: MultiObjectTrackerConfig | None = None, *,
                 refiner: Refiner | None = None,
                 manual_refiner: Refiner | None = None) -> None:
        """``refiner`` serves tracks born from detections, ``manual_refiner`` tracks started
        by hand; by default :class:`MultiKernelTracker` with ``multi_kernel`` and with
        :func:`manual_track_multi_kernel` (the same object when those agree).  A given
        ``refiner`` without ``manual_refiner`` serves both."""
        self.config = config or MultiObjectTrackerConfig()
        try:
            validate_config(self.config)
        except ParameterError as exc:
            raise TrackerInputError(str(exc)) from exc
        self.homography = homography_matrix(self.config.homography)
        for name, cfg in (("refinement_similarity_range", self.config),
                          ("manual_track.refinement_similarity_range", self.config.manual_track)):
            _check_similarity_range(name, cfg.refinement_similarity_range)
        if manual_refiner is None:
            if refiner is None and self.config.use_multi_kernel:
                manual_cfg = manual_track_multi_kernel(self.config)
                if manual_cfg != self.config.multi_kernel:
                    manual_refiner = MultiKernelTracker(manual_cfg)
            elif refiner is not None:
                manual_refiner = refiner
        if refiner is None and self.config.use_multi_kernel:
            refiner = MultiKernelTracker(self.config.multi_kernel)
        self.refiner = refiner
        self.manual_refiner = manual_refiner if manual_refiner is not None else refiner
        self._manual_kalman = manual_track_kalman(self.config)
        self._manual_lifecycle = manual_track_lifecycle(self.config)
        self._next_id = 1
        self.tracks: list[Track] = []
        self.last_stamp: float | None = None
        #: pairs of track ids stacked on one another since (stamp), duplicates.*
        self._stacked_since: dict[tuple[int, int], float] = {}
        #: this frame's published box of a track whose stacked twin was detected last
        self._published_box: dict[int, np.ndarray] = {}
        self._frame_interval = 0.0       # seconds between the last two frames
        #: whether a detector reported for this frame (``step(..., detections=None)``: not)
        self._detector_reported = True
        self.frame_size: tuple[int, int] | None = None
        self.camera_motion = CameraMotionEstimator(self.config.camera_motion) \
            if self.config.camera_motion.enabled else None
        self.totals = {"frames": 0, "dropped_stale": 0, "skipped_bad_detections": 0,
                       "resets": 0, "size_resets": 0, "group_measurements": 0,
                       "merged_duplicates": 0, "camera_motion_fallbacks": 0}

    # -- public API -----------------------------------------------------------------------
    def reset(self) -> None:
        """Forget every track and the previous frame (ids keep counting up, never reused)."""
        self.tracks = []
        self.last_stamp = None
        self.frame_size = None
        self._stacked_since = {}
        if self.camera_motion is not None:
            self.camera_motion.reset()

    def start_track(self, image_bgr: np.ndarray, stamp: float, box: Sequence[float]) -> int:
        """Start a confirmed track on ``box`` by hand (single-target protocol); returns its id."""
        self._check_image(image_bgr)
        try:
            b = as_box(box)
        except InvalidBoxError as exc:
            raise TrackerInputError(str(exc)) from exc
        stamp = self._check_stamp(stamp)
        target = None
        refiner = self.manual_refiner
        # a sliver at a side border is the visible part of a person partly outside the
        # image: kernels on the whole person (image_border.py; None when off or not a sliver)
        m = self.config.manual_track
        whole = whole_person_box(b, image_bgr.shape[1], image_bgr.shape[0],
                                 m.border_person_aspect, m.border_margin_px) \
            if isinstance(refiner, MultiKernelTracker) else None
        if whole is not None:
            try:
                target = refiner.start(image_bgr, whole, outside=True)
                b = np.asarray(whole, dtype=np.float64)
            except ValueError:          # a kernel with no pixel in the image: as before
                whole = None
        if refiner is not None and target is None:
            try:
                target = refiner.start(image_bgr, tuple(float(v) for v in b))
            except ValueError as exc:
                raise TrackerInputError(f"cannot start a target on {tuple(b)}: {exc}") from exc
        # its own Kalman and lifecycle settings (config.manual_track)
        track = self._new_track(b, stamp, 1.0, TrackState.CONFIRMED,
                                kalman=self._manual_kalman, lifecycle=self._manual_lifecycle)
        track.hits = self.config.lifecycle.min_hits
        track.manual = True
        track.target, track.target_stamp = target, stamp
        if target is not None:
            track.references.append(refiner.start(image_bgr, tuple(float(v) for v in b),
                                                  **({"outside": True} if whole else {})))
        if self.frame_size is None:
            self.frame_size = image_bgr.shape[:2]
        if self.camera_motion is not None:
            self.camera_motion.remember(image_bgr)     # the motion is measured from here
        return track.id

    def stop_track(self, track_id: int) -> bool:
        """Delete the live track ``track_id`` (by hand); False when no live track has it.

        It is gone at once: the next :meth:`step` neither updates nor reports it, and its
        id is never reused; the other tracks are not touched."""
        for t in self.tracks:
            if t.id == track_id and t.state is not TrackState.DELETED:
                t.state = TrackState.DELETED
                self.tracks = [u for u in self.tracks if u is not t]
                return True
        return False

    def step(self, image_bgr: np.ndarray, stamp: float,
             detections: Iterable[Any] | None = ()) -> FrameResult:
        """Process one RGB frame at ``stamp`` (seconds) with its detections.

        ``detections=None``: no detector reported for this frame (a thermal camera slower
        than the RGB one), which is not "the detector found nobody" (an empty list): the
        tracks are refined and coast as in any frame without a detection, but a tentative
        track does not count the frame as a miss (``lifecycle.max_tentative_misses``), or
        at 9 Hz beside 25 fps no track would ever be confirmed."""
        self._detector_reported = detections is not None
        if detections is None:
            detections = ()
        self._check_image(image_bgr)
        stamp = self._check_stamp(stamp)
        result = FrameResult(stamp=stamp,
                             max_reported_coast_time=self.config.max_reported_coast_time,
                             max_reported_coast_std=self.config.max_reported_coast_std,
                             min_reported_coast_match_iou=(
                                 self.config.min_reported_coast_match_iou))
        self.totals["frames"] += 1
        size = tuple(image_bgr.shape[:2])
        if self.last_stamp is not None and \
                stamp < self.last_stamp - self.config.backwards_tolerance:
            result.events.append(f"time went backwards by {self.last_stamp - stamp:.3f} s: reset")
            result.resets = 1
            self.reset()
        if self.frame_size is not None and size != self.frame_size:
            # skipping every later frame would stop tracking silently; the old tracks'
            # boxes are in the old pixel grid, so they go, and tracking restarts here
            result.events.append(f"frame {size[1]}x{size[0]} differs from the previous "
                                 f"{self.frame_size[1]}x{self.frame_size[0]}: reset")
            result.resets = 1
            self.totals["size_resets"] += 1
            self.reset()
        self.frame_size = size
        if self.last_stamp is not None and stamp > self.last_stamp:
            self._frame_interval = stamp - self.last_stamp
        self.last_stamp = stamp
        height, width = size

        dets = self._prepare(detections, stamp, width, height, result)
        live = [t for t in self.tracks if t.state is not TrackState.DELETED]
        if self.camera_motion is not None and not live:
            self.camera_motion.remember(image_bgr)     # nothing to move: no estimate
        elif self.camera_motion is not None:
            # the boxes are still those of the previous frame: left out of the estimate
            motion = self.camera_motion.estimate(image_bgr, [t.box for t in live])
            self.totals["camera_motion_fallbacks"] += int(motion.fallback)
            compensate(live, motion)
        for t in live:
            t.predict(stamp)

        # 4a. detections around several confirmed tracks are group measurements
        # (mk_tracker.tracking.group_measurement): assigned to none of them
        active = [t for t in live if t.state is not TrackState.LOST]
        pool = [t for t in active if t.state in (TrackState.CONFIRMED, TrackState.OCCLUDED)]
        groups = find_groups([t.box for t in pool], [d.box for d in dets], self.config.group)
        group_of = {pool[i].id: k for k, members in groups.items() for i in members}
        self.totals["group_measurements"] += len(groups)
        # 4b. the other detections vs tentative / confirmed / occluded tracks
        matched_track: dict[int, int] = {}          # detection index -> track id
        single = [k for k in range(len(dets)) if k not in groups]
        free = [t for t in active if t.id not in group_of]
        if free and single:
            a = self._match(free, [dets[k] for k in single], self.config.association.gate)
            for r, k in a.matches:
                matched_track[single[k]] = free[r].id
        # 4b'. drifted tracks vs the rest, from their last detection (tracking/recovery.py)
        recovered = recover_into(free, single, [d.box for d in dets], matched_track, stamp,
                                 self.config.recovery, result.events, lambda t, box:
                                 reference_similarity(t, box, image_bgr,
                                                      self._refiner_for(t))[0])
        # 4c. remaining detections vs lost tracks (re-acquisition)
        # A person reappearing part-occluded may first be seen by a new tentative track (its
        # appearance does not match yet); its detections stay candidates until it is
        # confirmed, and when one re-acquires a lost track the tentative track is dropped.
        lost = [t for t in live if t.state is TrackState.LOST]
        tentative = {t.id: t for t in live if t.state is TrackState.TENTATIVE}
        remaining = [k for k in single
                     if k not in matched_track or matched_track[k] in tentative]
        held: set[int] = set()             # tentative tracks not confirmed this frame
        if lost and remaining:
            matches, contested = self._reacquire(lost, [dets[k] for k in remaining], image_bgr,
                                                 dets)
            for k in contested:
                tid = matched_track.get(remaining[k])
                if tid in tentative and stamp - tentative[tid].created < \
                        self.config.reacquire_hold_time:
                    held.add(tid)
            for r, k in matches:
                previous = matched_track.get(remaining[k])
                if previous is not None:
                    tentative[previous].state = TrackState.DELETED
                    result.events.append(f"tentative track {previous} is lost track "
                                         f"{lost[r].id} coming back")
                matched_track[remaining[k]] = lost[r].id
                result.events.append(f"track {lost[r].id} re-acquired")
        live = [t for t in live if t.state is not TrackState.DELETED]

        by_id = {t.id: t for t in live}
        detected: dict[int, PreparedDetection] = {by_id[tid].id: dets[k]
                                          for k, tid in matched_track.items()}
        det_boxes_now = {tid: self._at_frame_time(by_id[tid], d)
                         for tid, d in detected.items()}
        # 5. multiple-kernel refinement from the Kalman prediction (Chu et al. Sec. IV-D)
        # for the tracks no detection was assigned to this frame (missed, part- or fully
        # occluded), or for all with refine_when_detected.  Keeps the per-frame cost to the
        # hard cases.
        refined: dict[int, tuple[np.ndarray, float, bool]] = {}
        for t in live:
            t.refined_box = None
            refiner = self._refiner_for(t)
            if (refiner is None or t.target is None
                    or t.state not in (TrackState.CONFIRMED, TrackState.OCCLUDED)
                    or not self._inside(t, width, height)):
                continue
            if t.id in det_boxes_now and not self.config.refine_when_detected:
                continue
            try:
                found = self._refine(t, refiner, image_bgr)
            except ValueError as exc:       # the refiner's own input errors
                result.events.append(f"track {t.id}: refinement failed: {exc}")
                continue
            k = self.config.max_refined_size_ratio
            if found is not None and k > 0 and t.detected_box is not None and \
                    self._fit_refiner(t, t.detected_box[3] / k, t.detected_box[3] * k):
                found = (np.asarray(t.target.box, dtype=np.float64), found[1], found[2])
            if found is not None:
                refined[t.id] = found
                t.refined_box = found[0]

        # 6. updates and lifecycle
        # boxes other tracks may block an appearance refresh with (computed once per frame)
        blockers = dict(det_boxes_now)
        blockers.update({t.id: t.box for t in live
                         if t.id not in blockers and t.state in OUTPUT_STATES})
        for t in live:
            if t.id in group_of:
                # a member of a group: its refined (else predicted) box, moved inside the
                # group's box, is its detection, at a lower quality
                g = dets[group_of[t.id]]
                found = refined.get(t.id)
                base = found[0] if found is not None and found[2] else t.box
                box = constrain_inside(base, self._at_frame_time(t, g))
                member = PreparedDetection(box=box, score=_quality(g.score)
                                   * self.config.group.quality_factor, lag=0.0)
                self._update_track(t, stamp, image_bgr, box, member, None, width, height,
                                   blockers, group=True)
                continue
            self._update_track(t, stamp, image_bgr, det_boxes_now.get(t.id),
                               detected.get(t.id), refined.get(t.id), width, height,
                               blockers, hold=t.id in held, restart=t.id in recovered)
        # 6b. two tracks stacked on one person become one (tracking/duplicate_tracks.py)
        self._merge_duplicates(live, {tid: dets[k].box for k, tid in matched_track.items()},
                               image_bgr, stamp, result)
        live = [t for t in live if t.state is not TrackState.DELETED]
        # new tentative tracks
        live_boxes = np.array([t.box for t in live if t.state is not TrackState.DELETED
                               and t.state is not TrackState.LOST]).reshape(-1, 4)
        # (a detection of a tracked person's other half is explained too: body_parts.py)
        reported_boxes = [t.box for t in live if t.state in OUTPUT_STATES]
        candidates = [k for k in single if k not in matched_track
                      and dets[k].score >= self.config.new_track_score
                      and explained_fraction(dets[k].box, live_boxes)
                      < self.config.group.explained_coverage
                      and not is_other_part(dets[k].box, reported_boxes, self.config.parts)]
        overlap = iou_matrix(np.array([dets[k].box for k in candidates]).reshape(-1, 4),
                             live_boxes)
        started: list[np.ndarray] = []
        for row, k in enumerate(candidates):
            d = dets[k]
            if len(live) >= self.config.max_tracks:
                result.events.append("max_tracks reached: detection not started")
                break
            if (overlap.shape[1] and overlap[row].max() > self.config.new_track_max_iou) or \
                    (started and iou_matrix(d.box[None], np.array(started)).max()
                     > self.config.new_track_max_iou):
                continue
            t = self._new_track(d.box, stamp, d.score, TrackState.TENTATIVE)
            live.append(t)
            started.append(t.box)
            if self.config.lifecycle.min_hits <= 1:
                t.state = TrackState.CONFIRMED
                self._refresh_appearance(t, image_bgr, d.box, stamp, force=True)
        for t in self.tracks:
            if t.state is TrackState.DELETED:
                result.deleted_ids.append(t.id)
        self.tracks = [t for t in self.tracks if t.state is not TrackState.DELETED]
        result.tracks = [t.output() for t in self.tracks]
        if self.config.manual_track.border_person_aspect > 0:    # image_border.py
            manual = {t.id for t in self.tracks if t.manual}
            result.tracks = [replace(o, box=clip_to_image(o.box, width, height))
                             if o.id in manual else o for o in result.tracks]
        if self._published_box:
            result.tracks = [replace(o, box=tuple(float(v) for v in self._published_box[o.id]))
                             if o.id in self._published_box else o for o in result.tracks]
            self._published_box = {}
        for t in self.tracks:
            k = track_kernels(t)
            if k is not None:
                result.kernels[t.id] = k
        self._count(result)
        return result

    # -- internals ------------------------------------------------------------------------
    def _merge_duplicates(self, live: list[Track], detected: dict[int, Any], image: np.ndarray,
                          stamp: float, result: FrameResult) -> None:
        """Track-level suppression of duplicates (:mod:`~mk_tracker.tracking.duplicate_tracks`):
        reported tracks stacked for ``duplicates.min_time`` without being detected as two
        people (``detected``: track id -> box of its detection this frame), and
        (``duplicates.min_similarity`` > 0) each matching the other's box by its appearance
        model, are merged into the older one; the other is deleted."""
        cfg = self.config.duplicates
        if not cfg.enabled:
            self._stacked_since = {}
            return
        pool = [t for t in live if t.state in OUTPUT_STATES and not t.manual]
        stacked = stacked_pairs([t.id for t in pool], [t.box for t in pool], cfg.min_iou)
        # seen as two people: each given a detection, and the two detections not stacked
        # themselves (a detector's two boxes of one person do not separate the pair)
        apart = [p for p in stacked if p[0] in detected and p[1] in detected
                 and iou(detected[p[0]], detected[p[1]]) <= cfg.min_iou]
        self._stacked_since = update_stacked_since(self._stacked_since, stacked, apart, stamp)
        by_id = {t.id: t for t in pool}
        for a_id, b_id in due_pairs(self._stacked_since, stamp, cfg.min_time):
            a, b = by_id[a_id], by_id[b_id]
            if a.state is TrackState.DELETED or b.state is TrackState.DELETED:
                continue
            if cfg.min_similarity > 0.0 and not self._look_alike(a, b, image,
                                                                  cfg.min_similarity):
                continue
            keep, gone = (a, b) if survivor(a.created, a.id, b.created, b.id) == a.id \
                else (b, a)
            merge_into(keep, gone)
            gone.state = TrackState.DELETED
            self._stacked_since.pop((a_id, b_id), None)
            self.totals["merged_duplicates"] += 1
            result.events.append(f"track {gone.id} merged into track {keep.id} "
                                 "(stacked on one person)")
        # pairs still waiting are published as one (duplicate_tracks.publish_one_of_each)
        hidden, boxes = publish_one_of_each(
            [p for p in self._stacked_since if p[0] in by_id and p[1] in by_id], by_id,
            lambda a, b: cfg.min_similarity <= 0.0 or self._look_alike(a, b, image,
                                                                       cfg.min_similarity),
            cfg.report_one)
        result.suppressed_ids |= hidden
        self._published_box = boxes

    def _look_alike(self, a: Track, b: Track, image: np.ndarray, floor: float) -> bool:
        """Each track's appearance model matches the other's box with at least ``floor``
        (:meth:`Refiner.appearance_similarity`); False when a model is missing."""
        refiner = self.refiner
        if refiner is None or a.target is None or b.target is None:
            return False
        try:
            sims = (float(refiner.appearance_similarity(image, a.target, tuple(b.box))),
                    float(refiner.appearance_similarity(image, b.target, tuple(a.box))))
        except ValueError:
            return False
        return all(math.isfinite(v) and v >= floor for v in sims)

    def _fit_refiner(self, t: Track, low: float, high: float) -> bool:
        """Rescale the track's multiple-kernel target so its box height is in ``[low, high]``
        (:func:`~mk_tracker.tracking.scale_estimation.fit_height`); False for other refiners."""
        cfg = getattr(self._refiner_for(t), "config", None)
        if not isinstance(getattr(t.target, "scale", None), float) or cfg is None:
            return False
        return fit_height(t.target, low, high, cfg.min_scale, cfg.max_scale)

    def _refiner_for(self, t: Track) -> Refiner | None:
        """The refiner of a track: ``manual_refiner`` for tracks started by hand."""
        return self.manual_refiner if t.manual else self.refiner

    def _judge(self, t: Track, res: Any) -> tuple[np.ndarray, float, bool] | None:
        """``(box, visibility statistic, visible)`` of a refinement result (visible: the
        statistic is at least the track's ``occlusion_similarity``), or None when it is lost
        or not finite."""
        sim = _visibility(res, t.config.visibility_statistic)
        box = getattr(res, "box", None)
        if (getattr(res, "lost", False) or box is None or not math.isfinite(sim)
                or not all(math.isfinite(float(v)) for v in box)):
            return None
        return np.asarray(box, dtype=np.float64), sim, sim >= t.config.occlusion_similarity

    def _refine(self, t: Track, refiner: Refiner, image: np.ndarray
                ) -> tuple[np.ndarray, float, bool] | None:
        """Multiple-kernel search of one track from its Kalman prediction (Sec. IV-D), and
        for a track started by hand a second search when the first one sees the target with
        one kernel column only.

        A two-column layout (4-6 kernels) has a stable wrong optimum: one column on the
        person's half whose colours look like the other half, the other column on
        background (rho ~ 0).  The weighted visibility ``sum rho_i^2 / sum rho_i`` follows
        the seeing kernels and calls it visible, and a box 0.45 w off becomes the track's
        only measurement.  Side occlusion (the other column behind a pillar) gives the same
        similarities, so the first result is not rejected; instead the search is repeated
        from the box moved towards the seeing column
        (:func:`~mk_tracker.tracking.manual_track.recentre_shift`), and that result is kept
        (with its target state) only if it is visible and both of its columns see the target
        (:func:`~mk_tracker.tracking.manual_track.columns_cover`,
        ``manual_track.column_recentre``).  Cost: one more refinement in the frames with a
        one-column result.  A still track (``lifecycle.still_contrast`` > 0) that the level
        calls unseen is seen when the geometric mean of its level and of its peak's
        contrast to a ring of displaced copies (:meth:`MultiKernelTracker.peak_contrast`)
        reaches ``still_contrast``: on 26 real clips the product separated on-person from
        off-person searches better than either alone (docs/failure_analysis.md, "Does the
        peak stand out?").  Returns :meth:`_judge` of the kept result.
        """
        res = refiner.refine(image, t.target, predicted_center=tuple(t.center))
        found = self._judge(t, res)
        contrast_level = t.config.still_contrast
        if found is not None and not found[2] and contrast_level > 0.0 and not t.manual \
                and t.is_still() and hasattr(refiner, "peak_contrast") and \
                math.sqrt(max(found[1], 0.0) * refiner.peak_contrast(image, t.target, res)) \
                >= contrast_level:
            found = (found[0], found[1], True)      # a still person in another light
        floor = self.config.manual_track.min_column_similarity
        if t.manual and self.config.manual_track.column_recentre and found is not None \
                and found[2] and not columns_cover(res, floor):
            shift = recentre_shift(res, found[0])
            if shift != 0.0:
                moved = copy.deepcopy(t.target)
                centre = found[0][:2] + found[0][2:] / 2.0
                alt_res = refiner.refine(image, moved,
                                         predicted_center=(centre[0] + shift, centre[1]))
                alt = self._judge(t, alt_res)
                if alt is not None and alt[2] and columns_cover(alt_res, floor):
                    t.target, found = moved, alt
        return found

    def _count(self, result: FrameResult) -> None:
        self.totals["dropped_stale"] += result.dropped_stale
        self.totals["skipped_bad_detections"] += result.skipped_bad_detections
        self.totals["resets"] += result.resets

    @staticmethod
    def _check_image(image: Any) -> None:
        if not isinstance(image, np.ndarray) or image.ndim not in (2, 3) \
                or image.shape[0] < 1 or image.shape[1] < 1:
            raise TrackerInputError(f"image must be an HxW or HxWxC numpy array, got "
                                    f"{getattr(image, 'shape', type(image).__name__)}")

    @staticmethod
    def _check_stamp(stamp: Any) -> float:
        return checked_stamp(stamp, TrackerInputError)

    def _new_track(self, box: np.ndarray, stamp: float, score: float, state: TrackState,
                   kalman: KalmanConfig | None = None,
                   lifecycle: LifecycleConfig | None = None) -> Track:
        t = Track(self._next_id, box, stamp, score=_quality(score),
                  kalman=self.config.kalman if kalman is None else kalman,
                  config=self.config.lifecycle if lifecycle is None else lifecycle,
                  state=state)
        self._next_id += 1
        self.tracks.append(t)
        return t

    def _prepare(self, detections: Iterable[Any], stamp: float, width: int, height: int,
                 result: FrameResult) -> list[PreparedDetection]:
        return prepare_detections(detections, stamp, width, height, self.homography,
                                  self.config.stale_tolerance,
                                  self.config.min_detection_score, result)

    def _inside(self, t: Track, width: int, height: int) -> bool:
        """In the image for refinement and lifecycle: the centre (:meth:`_in_image`), or for
        a track started by hand with the border as an occluder (``border_person_aspect``)
        any part of its box, as a person entering or leaving at an edge."""
        if t.manual and self.config.manual_track.border_person_aspect > 0:
            return overlaps_image(t.box, width, height)
        return self._in_image(t, width, height)

    @staticmethod
    def _in_image(t: Track, width: int, height: int) -> bool:
        cx, cy = t.center
        return 0.0 <= cx < width and 0.0 <= cy < height

    @staticmethod
    def _det_geometry(tracks: list[Track], dets: list[PreparedDetection]
                      ) -> tuple[np.ndarray, np.ndarray]:
        """:func:`~mk_tracker.tracking.detection_input.detection_geometry` for ``tracks``."""
        return detection_geometry(np.array([t.kf.velocity for t in tracks]), dets)

    def _innovation_covs(self, tracks: list[Track]) -> np.ndarray:
        return np.array([t.innovation_covariance(t.size[1]) for t in tracks]).reshape(-1, 2, 2)

    def _match(self, tracks: list[Track], dets: list[PreparedDetection], gate: float):
        boxes, centres = self._det_geometry(tracks, dets)
        maha = mahalanobis_matrix(np.array([t.center for t in tracks]),
                                  self._innovation_covs(tracks), centres)
        track_boxes = np.array([t.box for t in tracks])
        cost = association_cost(track_boxes, boxes, maha, self.config.association)
        return assign(cost, self.config.association.max_cost)

    def _reacquire(self, lost: list[Track], dets: list[PreparedDetection], image: np.ndarray,
                   frame_dets: list[PreparedDetection] = ()
                   ) -> tuple[list[tuple[int, int]], set[int]]:
        """Matches ``(lost index, det index)`` by gated distance, size and appearance
        (:meth:`_reacquire_check`).  The distance is the smaller of the Kalman one and, with
        ``reacquire_last_detection_*``, the one from the track's last detection
        (:func:`~mk_tracker.tracking.reacquisition.nearer_of_both`).

        Also returns the detections inside some lost track's Kalman gate (whatever their
        appearance): a tentative track on one of those is not confirmed for up to
        ``reacquire_hold_time``, so the lost person coming back part-occluded gets a few
        frames to match its appearance (0 by default: on TUD-Stadtmitte the three
        longest-held tracks never took a lost id back and went unreported meanwhile).  The
        last-detection gate does not hold tentative tracks: where a person left the image
        another one often enters, and holding those cost MOTA on the 7 fps RGB sequence.
        """
        boxes, centres = self._det_geometry(lost, dets)
        maha = mahalanobis_matrix(np.array([t.center for t in lost]),
                                  self._innovation_covs(lost), centres)
        # observation-centric: the last detection gates too (tracking/reacquisition.py)
        gated = nearer_of_both(maha, centres, np.array([t.detected_box for t in lost]),
                               self.last_stamp - np.array([t.last_detection for t in lost]),
                               self.config.reacquire_last_detection_floor,
                               self.config.reacquire_last_detection_speed)
        return reacquisition_matches(
            lost, dets, maha, gated, image, self.config, self._reacquire_check,
            lambda t, box: reference_similarity(t, box, image, self._refiner_for(t))[0],
            # the people around, for reacquire_margin's rivals (built only when it is on)
            np.array([d.box for d in frame_dets]).reshape(-1, 4)
            if self.config.reacquire_margin >= 0.0 else None)

    def _reacquire_check(self, t: Track, d: PreparedDetection, maha: float, image: np.ndarray
                         ) -> tuple[str | None, float, int | None]:
        """One lost track against one detection in :meth:`_reacquire`
        (:func:`~mk_tracker.tracking.reacquisition.reacquire_check`)."""
        return reacquire_check(t, d.box, maha, image, self.config, self._refiner_for(t))

    @staticmethod
    def _at_frame_time(t: Track, d: PreparedDetection) -> np.ndarray:
        box = d.box.copy()
        box[:2] += t.kf.velocity * d.lag
        return box

    def _refresh_appearance(self, t: Track, image: np.ndarray, box: np.ndarray, stamp: float,
                            force: bool = False) -> None:
        refiner = self._refiner_for(t)
        if refiner is None:
            return
        due = (t.target is None or force or t.target_stamp is None
               or stamp - t.target_stamp >= self.config.appearance_update_interval)
        if due:
            try:
                t.target = refiner.start(image, tuple(float(v) for v in box))
                fresh = refiner.start(image, tuple(float(v) for v in box))
            except ValueError:
                # e.g. a uniform-colour or mostly out-of-image box: keep the old model (if
                # any) and try again on a later detection
                return
            t.target_stamp = stamp
            # frozen models for re-acquisition: the first one and the latest clean one (the
            # working target's models are blended by the refiner frame after frame)
            if not t.references:
                t.references.append(fresh)
            elif len(t.references) == 1:
                t.references.append(fresh)
            else:
                t.references[1] = fresh

    def _update_track(self, t: Track, stamp: float, image: np.ndarray,
                      det_box: np.ndarray | None, det: PreparedDetection | None,
                      refined: tuple[np.ndarray, float, bool] | None, width: int, height: int,
                      blockers: dict[int, np.ndarray], hold: bool = False,
                      group: bool = False, restart: bool = False) -> None:
        """Kalman update and lifecycle of one track; ``group``: its detection is its place
        inside a group measurement (no OC-SORT re-update, no appearance refresh);
        ``restart``: recovered from its last detection (a new filter at the detection)."""
        cfg = t.config            # the tracker's lifecycle, or manual_track's for hand-started
        was = t.state
        sim = refined[1] if refined is not None else None
        visible = refined is not None and refined[2]
        # a track started by hand maps its refinement to quality by its own settings
        measurement = self.config.manual_track if t.manual else self.config
        lo, hi = measurement.refinement_similarity_range
        quality = 0.0 if sim is None else min(max((sim - lo) / max(hi - lo, 1e-9), 0.0), 1.0)
        if det_box is not None:
            if not group:
                # the prediction (4.2) against the observation, before any correction
                t.last_match_iou = iou(t.box, det_box)
            if restart and self.config.recovery.restart != "correct":   # (recovery.py)
                restart_filter(t, det_box, stamp, self.config.kalman,
                               self.config.recovery.restart == "observations")
            elif was is TrackState.LOST:
                # re-acquired: restart the filter's position at the detection, keep velocity
                t.kf.update(det_box[:2] + det_box[2:] / 2.0, sigma_w=cfg.min_noise_px)
                t.size = det_box[2:].copy()
            else:
                if cfg.observation_centric_reupdate and not t.manual and not group \
                        and was is not TrackState.TENTATIVE:
                    t.reupdate_from_last_seen(det_box, stamp, self._frame_interval)
                t.correct(det_box, _quality(det.score))
                if refined is not None and iou(refined[0], det_box) >= \
                        self.config.refine_consistency_iou:
                    t.correct(refined[0], quality * self.config.fused_quality_factor,
                              use_size=False)            # the detection gives the size
            if self.config.refiner_size_from_detection and not group:
                self._fit_refiner(t, det_box[3], det_box[3])
            t.hits += 1
            t.tentative_misses = 0
            t.last_detection = stamp
            if not group:
                t.detected_box = np.array(det_box, dtype=np.float64)
                t.detected_stamp = stamp
            t.last_seen = stamp
            t.score = sim if sim is not None else _quality(det.score)
        else:
            if self._detector_reported:
                t.tentative_misses += 1
            if visible:
                t.correct(refined[0], quality * measurement.undetected_quality_factor,
                          size_weight=cfg.refinement_size_weight)
                t.last_seen = stamp
            t.score = sim if sim is not None else 0.0
        if cfg.observation_centric_reupdate and not t.manual and \
                (det_box is not None or visible):
            t.remember_seen()
        if t.manual:
            t.hold_if_uncertain(det_box is not None or visible,
                                self.config.manual_track.max_coast_position_std)
        new = next_state(was, detected=det_box is not None, visible=visible,
                         in_image=self._inside(t, width, height), hits=t.hits,
                         tentative_misses=t.tentative_misses,
                         # a track started by hand has no detector to come back with: it
                         # coasts (and keeps refining) until it leaves the image
                         unseen_time=0.0 if t.manual else stamp - t.last_seen,
                         lost_time=0.0 if t.lost_since is None else stamp - t.lost_since,
                         config=cfg,
                         undetected_time=0.0 if t.manual else stamp - t.last_detection,
                         still=t.is_still())
        if hold and new is TrackState.CONFIRMED and was is TrackState.TENTATIVE:
            new = TrackState.TENTATIVE
        if new is TrackState.LOST and was is not TrackState.LOST:
            t.lost_since = stamp
        if new is not TrackState.LOST:
            t.lost_since = None
        t.state = new
        if det_box is not None and new is TrackState.CONFIRMED and not group and \
                self._refiner_for(t) is not None:
            # refresh only from a clean view: not next to another person, and (when the
            # refiner ran) a good match, so an occluder's pixels never enter the model; a
            # re-acquired track keeps the model that just proved to match
            due = t.target_stamp is None or \
                stamp - t.target_stamp >= self.config.appearance_update_interval
            clean = sim is None or sim >= self.config.appearance_update_similarity
            if t.target is None:
                self._refresh_appearance(t, image, det_box, stamp, force=True)
            elif due and clean and was is not TrackState.LOST:
                others = [b for tid, b in blockers.items() if tid != t.id]
                if not others or float(iou_matrix(det_box[None], np.array(others)).max()) \
                        <= self.config.isolation_iou:
                    self._refresh_appearance(t, image, det_box, stamp)
        t.finish_frame()
