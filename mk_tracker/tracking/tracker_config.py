"""Every constant of the multi-object tracker (:mod:`mk_tracker.tracking.multi_object_tracker`)
in one frozen dataclass; nested configurations flatten to dotted ROS parameter names
(``lifecycle.min_hits``, ``group.enabled``, ...).
"""

from __future__ import annotations

from dataclasses import dataclass

from mk_tracker.kalman import KalmanConfig
from mk_tracker.parameters import parameter
from mk_tracker.tracking.association import AssociationConfig
from mk_tracker.tracking.body_parts import BodyPartConfig
from mk_tracker.tracking.camera_motion import CameraMotionConfig
from mk_tracker.tracking.duplicate_tracks import DuplicateConfig
from mk_tracker.tracking.group_measurement import GroupConfig
from mk_tracker.tracking.manual_track import ManualTrackConfig
from mk_tracker.tracking.multi_kernel_config import MultiKernelConfig
from mk_tracker.tracking.recovery import RecoveryConfig
from mk_tracker.tracking.track import LifecycleConfig

__all__ = ["IDENTITY_HOMOGRAPHY", "MultiObjectTrackerConfig"]

IDENTITY_HOMOGRAPHY = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)


@dataclass(frozen=True)
class MultiObjectTrackerConfig:
    """Every constant of the multi-object tracker (nested configs flatten with dots)."""

    kalman: KalmanConfig = parameter(KalmanConfig(), "Constant-velocity Kalman filter")
    association: AssociationConfig = parameter(AssociationConfig(),
                                               "Detection-to-track assignment")
    lifecycle: LifecycleConfig = parameter(LifecycleConfig(), "Track states and smoothing")
    group: GroupConfig = parameter(GroupConfig(), "Detections around several tracks "
                                   "(group measurements)")
    duplicates: DuplicateConfig = parameter(
        DuplicateConfig(), "Two tracks stacked on one person (track-level suppression)")
    recovery: RecoveryConfig = parameter(
        RecoveryConfig(), "Second association round of drifted active tracks from their last "
        "detection (OC-SORT's observation-centric recovery)")
    parts: BodyPartConfig = parameter(
        BodyPartConfig(), "A detection of a tracked person's other half (torso / legs) "
        "starts no track (tracking/body_parts.py)")
    multi_kernel: MultiKernelConfig = parameter(MultiKernelConfig(),
                                                "Multiple-kernel refinement (Chu et al. 2013)")
    manual_track: ManualTrackConfig = parameter(
        ManualTrackConfig(), "Tracks started by hand (initial_box, ~/start_track): their own "
        "Kalman, visibility and kernel settings")
    camera_motion: CameraMotionConfig = parameter(
        CameraMotionConfig(), "Camera-motion compensation: the image motion between frames "
        "moves every track before the prediction (tracking/camera_motion.py)")
    use_multi_kernel: bool = parameter(
        True, "Refine every confirmed/occluded track with the multiple-kernel tracker "
        "(Sec. IV-D); false = detections and Kalman prediction only")
    homography: tuple = parameter(
        IDENTITY_HOMOGRAPHY, "Row-major 3x3 homography mapping thermal pixels to RGB pixels")
    stale_tolerance: float = parameter(
        0.5, "Detections whose stamp differs from the frame's by more than this many seconds "
        "are dropped", minimum=0.0, maximum=1e4)
    backwards_tolerance: float = parameter(
        1e-6, "A frame stamp earlier than the previous one by more than this (s) resets the "
        "tracker", minimum=0.0, maximum=1e4)
    min_detection_score: float = parameter(
        -1e9, "Detections with a lower score are ignored", minimum=-1e12, maximum=1e12)
    new_track_score: float = parameter(
        0.0, "A detection needs at least this score to start a track", minimum=-1e12,
        maximum=1e12)
    new_track_max_iou: float = parameter(
        0.6, "An unassigned detection overlapping a live track by more than this IoU does "
        "not start a new track (duplicate)", minimum=0.0, maximum=1.0)
    refine_consistency_iou: float = parameter(
        0.3, "A refinement is fused with the assigned detection only if their boxes overlap "
        "by at least this IoU", minimum=0.0, maximum=1.0)
    reacquire_gate: float = parameter(
        13.8, "Chi-square gate (2 dof) for a detection to re-acquire a lost track",
        minimum=0.1, maximum=1e4)
    reacquire_last_detection_floor: float = parameter(
        0.05, "Std (box heights) of a lost track's last detected centre when it gates a "
        "re-acquiring detection besides the Kalman prediction (observation-centric, "
        "mk_tracker/tracking/reacquisition.py); 0 together with "
        "reacquire_last_detection_speed = the Kalman gate only", minimum=0.0, maximum=100.0)
    reacquire_last_detection_speed: float = parameter(
        0.3, "Growth of that std in box heights per second since the last detection; at "
        "the 13.8 gate (3.7 std) the radius grows by 1.1 box heights/s, about walking "
        "speed", minimum=0.0, maximum=100.0)
    reacquire_similarity: float = parameter(
        0.4, "Appearance similarity a detection needs to re-acquire a lost track",
        minimum=0.0, maximum=1.0)
    reacquire_margin: float = parameter(
        -1.0, "A lost track re-acquires a detection only if its appearance similarity there "
        "beats, by at least this much, its similarity at every other detection it could "
        "take and every other lost track's similarity at that detection (a distinct best "
        "match both ways, tracking/reacquisition.py); where people look alike the id is "
        "not given back.  Negative = off", minimum=-1.0, maximum=1.0)
    reacquire_rivals: int = parameter(
        3, "With reacquire_margin: the lost track's similarity must also beat, by the "
        "margin, its similarity at the boxes of this many other people of the frame nearest "
        "to the detection (does its model tell the people there apart?); 0 = candidates "
        "only", minimum=0, maximum=100)
    reacquire_distance_weight: float = parameter(
        0.5, "Weight of the gated distance (d2 / gate) next to 1 - appearance similarity in "
        "the re-acquisition cost", minimum=0.0, maximum=100.0)
    reacquire_hold_time: float = parameter(
        0.0, "A new track on a detection inside a lost track's gate stays tentative for up "
        "to this many seconds, so the lost person can take its id back once its appearance "
        "matches (it may come back part-occluded).  0 (default, chosen by every "
        "leave-one-sequence-out fold of benchmarks/bench_multi_object.py): never held; on "
        "TUD-Stadtmitte the three longest-held tracks never took a lost id back, and their "
        "people went unreported for 15-16 frames each", minimum=0.0, maximum=1e4)
    reacquire_max_size_ratio: float = parameter(
        1.6, "Largest height ratio between a lost track and a re-acquiring detection",
        minimum=1.0, maximum=100.0)
    refinement_similarity_range: tuple = parameter(
        (0.5, 0.95), "Multiple-kernel similarities (low, high) mapped linearly to match "
        "quality 0..1; the quality sets the refinement's measurement noise")
    refine_when_detected: bool = parameter(
        False, "Also run the multiple-kernel refinement for tracks with an assigned detection "
        "(slower; fused with the detection at fused_quality_factor)")
    fused_quality_factor: float = parameter(
        0.25, "Factor on a refinement's quality when it is fused with an assigned detection "
        "(the detection sees the whole person; the kernels may see only its visible part)",
        minimum=0.0, maximum=1.0)
    undetected_quality_factor: float = parameter(
        0.5, "Factor on a refinement's quality in frames where no detection confirms the "
        "track (a part-occluded target still matches its visible kernels well)",
        minimum=0.0, maximum=1.0)
    refiner_size_from_detection: bool = parameter(
        False, "Each detection of a track rescales its multiple-kernel target so that the "
        "kernels' box has the detection's height (the detection measures the size; without "
        "it the kernels keep the size of the last appearance refresh and their scale "
        "update (9)-(11) runs on its own; not in the paper)")
    max_refined_size_ratio: float = parameter(
        0.0, "The kernels of a track are held to at most this factor above or below its last "
        "detected height (a bound on the scale update (9)-(11) of an undetected track; not "
        "in the paper); 0 = no bound", minimum=0.0, maximum=100.0)
    appearance_update_interval: float = parameter(
        1.0, "Seconds between refreshes of a track's appearance model from an isolated "
        "detection (0 = every frame)", minimum=0.0, maximum=1e4)
    appearance_update_similarity: float = parameter(
        0.8, "Multiple-kernel similarity a track needs for its appearance model to be "
        "refreshed from its detection", minimum=0.0, maximum=1.0)
    isolation_iou: float = parameter(
        0.05, "A detection overlapping another track by more than this IoU is not used to "
        "refresh an appearance model", minimum=0.0, maximum=1.0)
    max_reported_coast_time: float = parameter(
        0.2, "FrameResult.reported() includes an occluded (coasting) track for at most this "
        "many seconds after its last detection; it stays tracked (and in tracks) for longer",
        minimum=0.0, maximum=1e4)
    max_reported_coast_std: float = parameter(
        0.12, "FrameResult.reported() also drops an occluded (coasting) track once the std "
        "of its predicted centre exceeds this fraction of its box (max of sqrt(P_xx) / w "
        "and sqrt(P_yy) / h of the Kalman covariance (4.3)): such a box is likely off the "
        "person by the IoU it needs to count (chosen by 3 of 4 leave-one-sequence-out "
        "folds of benchmarks/bench_multi_object.py); 0 = only max_reported_coast_time",
        minimum=0.0, maximum=100.0)
    min_reported_coast_match_iou: float = parameter(
        0.0, "FrameResult.reported() also drops an occluded (coasting) track whose Kalman "
        "prediction (4.2) met its last detection at an IoU below this (the filter's "
        "innovation at its last update, in the IoU the scoring uses): a filter that already "
        "missed the one-frame-ahead observation (a box around two people, a person turning) "
        "extrapolates a box off the person; 0 = no such bound", minimum=0.0, maximum=1.0)
    max_tracks: int = parameter(500, "Upper bound on live tracks; extra detections are "
                                "not started", minimum=1, maximum=100000)
