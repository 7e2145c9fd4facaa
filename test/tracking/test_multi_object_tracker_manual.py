"""Tracks started by hand (``start_track``) use ``config.manual_track``; tracks born from
detections keep the tracker's own ``kalman`` / ``lifecycle`` / ``multi_kernel`` settings.
Also the visibility statistic (plain mean vs ``sum_i W_i rho_i / N``, Chu et al. (7)-(8))."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mk_tracker.synthetic.presets import crossing_scene, occlusion_scene
from mk_tracker.tracking.multi_kernel import (MultiKernelConfig, MultiKernelTracker,
                                     visibility_similarity)
from mk_tracker.tracking.manual_track import ManualTrackConfig
from mk_tracker.tracking.multi_object_tracker import (FrameDetection, MultiObjectTracker,
                                             MultiObjectTrackerConfig, TrackerInputError)
from mk_tracker.parameters import parameter_specs, updated
from mk_tracker.tracking.track import LifecycleConfig

IMG = np.zeros((480, 640, 3), np.uint8)
DT = 1.0 / 25.0


# -- the visibility statistic ------------------------------------------------------------------

def test_weighted_visibility_of_a_half_occluded_target():
    # rho = (0.8, 0): W = 2 * rho / 0.8 = (2, 0); sum W rho / N = 1.6 / 2
    assert visibility_similarity([0.8, 0.0], statistic="weighted") == pytest.approx(0.8)
    assert visibility_similarity([0.8, 0.0], statistic="mean") == pytest.approx(0.4)


def test_weighted_visibility_of_a_constructed_case():
    # rho = (0.6, 0.2): W = (1.5, 0.5); (1.5 * 0.6 + 0.5 * 0.2) / 2 = 0.5 = (0.36 + 0.04) / 0.8
    assert visibility_similarity([0.6, 0.2], statistic="weighted") == pytest.approx(0.5)
    # four kernels, two hidden: rho = (0.9, 0.7, 0, 0): (0.81 + 0.49) / 1.6
    assert visibility_similarity([0.9, 0.7, 0.0, 0.0], statistic="weighted") == \
        pytest.approx(0.8125)
    # given weights are used as they are (W = I: the plain mean)
    assert visibility_similarity([0.6, 0.2], [1.0, 1.0], "weighted") == pytest.approx(0.4)
    # every kernel hidden: low either way; NaN counts as 0
    assert visibility_similarity([0.0, 0.0], statistic="weighted") == 0.0
    assert visibility_similarity([np.nan, 0.5], statistic="weighted") == pytest.approx(0.5)


def test_visibility_statistic_rejects_bad_input():
    with pytest.raises(ValueError, match="statistic"):
        visibility_similarity([0.5, 0.5], statistic="median")
    with pytest.raises(ValueError, match="weights"):
        visibility_similarity([0.5, 0.5], [1.0, 1.0, 1.0], "weighted")
    with pytest.raises(ValueError):
        visibility_similarity([], statistic="mean")


def test_refinement_result_weighted_similarity_matches_its_kernels():
    scene = occlusion_scene(full=False)
    f0, f1 = scene.frame(0), scene.frame(1)
    box = next(o.box_rgb for o in scene.ground_truth(0) if o.id == 1)
    trk = MultiKernelTracker(MultiKernelConfig(num_kernels=4))
    res = trk.refine(f1.rgb, trk.start(f0.rgb, box))
    rho = np.asarray(res.kernel_similarities)
    assert res.weighted_similarity == pytest.approx(float(np.sum(rho ** 2) / np.sum(rho)))
    assert res.similarity == pytest.approx(float(rho.mean()))


# -- hand-started vs detection-born tracks ---------------------------------------------------

class KernelRefiner:
    """Fake refiner: every refinement matches at ``box`` with kernel similarities ``rho``."""

    def __init__(self, rho, box=(200.0, 100.0, 40.0, 80.0)):
        self.rho = np.asarray(rho, dtype=float)
        self.box = box
        self.started = []

    def start(self, image, box):
        self.started.append(tuple(box))
        return "target"

    def refine(self, image, state, predicted_center=None):
        return type("R", (), {"box": self.box, "similarity": float(self.rho.mean()),
                              "kernel_similarities": self.rho,
                              "weights": self.rho * self.rho.size / self.rho.sum(),
                              "lost": False})()

    def appearance_similarity(self, image, state, box):
        return 0.0


def _config(**manual):
    base = updated(MultiObjectTrackerConfig(), {"lifecycle.min_hits": 1})
    return dataclasses.replace(base, manual_track=ManualTrackConfig(**manual))


def test_hand_started_track_uses_its_visibility_settings_a_detected_one_the_defaults():
    # legs hidden: rho = (0.9, 0.05): plain mean 0.475 (< lifecycle 0.6: occluded),
    # weighted (0.81 + 0.0025) / 0.95 = 0.855 (>= manual_track 0.4: seen)
    cfg = _config(occlusion_similarity=0.4, visibility_statistic="weighted")
    manual = MultiObjectTracker(cfg, refiner=KernelRefiner([0.9, 0.05]))
    tid = manual.start_track(IMG, 0.0, (200, 100, 40, 80))
    r = manual.step(IMG, DT)
    (t,) = r.tracks
    assert (t.id, t.state, t.manual) == (tid, "confirmed", True)
    assert t.score == pytest.approx(0.81 / 0.95 + 0.0025 / 0.95)

    born = MultiObjectTracker(cfg, refiner=KernelRefiner([0.9, 0.05]))
    born.step(IMG, 0.0, [FrameDetection((200, 100, 40, 80), 0.9)])
    r = born.step(IMG, DT, [])                    # no detection: refined, mean 0.475
    (t,) = r.tracks
    assert (t.state, t.manual) == ("occluded", False)


def test_hand_started_track_with_the_plain_mean_is_occluded_like_the_defaults():
    cfg = _config(occlusion_similarity=0.6, visibility_statistic="mean")
    trk = MultiObjectTracker(cfg, refiner=KernelRefiner([0.9, 0.05]))
    trk.start_track(IMG, 0.0, (200, 100, 40, 80))
    (t,) = trk.step(IMG, DT).tracks
    assert t.state == "occluded"


def test_hand_started_track_uses_its_kalman_settings():
    cfg = _config(initial_velocity_var=9.0e4)
    trk = MultiObjectTracker(cfg, refiner=KernelRefiner([0.9, 0.9]))
    trk.start_track(IMG, 0.0, (200, 100, 40, 80))
    trk.step(IMG, 0.0, [FrameDetection((400, 100, 40, 80), 0.9)])
    manual, born = sorted(trk.tracks, key=lambda t: not t.manual)
    assert manual.manual and not born.manual
    assert manual.kf.covariance[2, 2] == pytest.approx(9.0e4)
    assert manual.kf.sigma_u == cfg.kalman.sigma_u
    assert born.kf.covariance[2, 2] == pytest.approx(cfg.kalman.initial_velocity_var)
    assert born.kf.sigma_u == cfg.kalman.sigma_u
    assert manual.config.occlusion_similarity == cfg.manual_track.occlusion_similarity
    assert born.config == cfg.lifecycle


def test_hand_started_track_gets_its_own_kernel_layout():
    scene = crossing_scene()
    frame = scene.frame(0)
    boxes = [o.box_rgb for o in scene.ground_truth(0) if o.kind == "person"]
    cfg = updated(MultiObjectTrackerConfig(), {"lifecycle.min_hits": 1,
                                               "manual_track.num_kernels": 4,
                                               "manual_track.scale_gate_statistic": "mean",
                                               "manual_track.scale_similarity_gate": 0.7})
    trk = MultiObjectTracker(cfg)
    assert trk.manual_refiner is not trk.refiner
    assert trk.manual_refiner.config.num_kernels == 4
    assert trk.manual_refiner.config.scale_similarity_gate == 0.7
    assert trk.refiner.config == cfg.multi_kernel
    trk.start_track(frame.rgb, frame.stamp, boxes[0])
    trk.step(frame.rgb, frame.stamp, [FrameDetection(boxes[1], 0.9)])
    manual, born = sorted(trk.tracks, key=lambda t: not t.manual)
    assert manual.target.num_kernels == 4
    assert born.target.num_kernels == cfg.multi_kernel.num_kernels == 2
    r = trk.step(scene.frame(1).rgb, scene.frame(1).stamp, [])
    assert set(r.kernels) == {manual.id, born.id}
    assert len(r.kernels[manual.id].centres) == 4 and len(r.kernels[born.id].centres) == 2


def test_one_refiner_serves_both_when_the_kernel_settings_agree():
    cfg = updated(MultiObjectTrackerConfig(), {"manual_track.num_kernels": 2,
                                               "manual_track.scale_gate_statistic": "min",
                                               "manual_track.scale_similarity_gate": 0.8,
                                               "manual_track.multi_start_radius": 0.0,
                                               "manual_track.recovery_similarity": 0.0,
                                               "manual_track.recovery_growth": 0.0,
                                               "manual_track.similarity_reference_rate": 0.0,
                                               "manual_track.background_weighting": "none"})
    trk = MultiObjectTracker(cfg)
    assert trk.manual_refiner is trk.refiner


def test_manual_track_parameters_are_declared_and_validated():
    names = {s.name for s in parameter_specs(MultiObjectTrackerConfig())}
    for field in dataclasses.fields(ManualTrackConfig):
        assert f"manual_track.{field.name}" in names
    assert "lifecycle.visibility_statistic" in names
    for bad in ({"num_kernels": 3}, {"visibility_statistic": "median"},
                {"occlusion_similarity": 1.5}, {"undetected_quality_factor": -1.0},
                {"scale_gate_statistic": "max"}, {"initial_velocity_var": 0.0}):
        with pytest.raises(TrackerInputError):
            MultiObjectTracker(_config(**bad))
    with pytest.raises(TrackerInputError):
        MultiObjectTracker(dataclasses.replace(
            MultiObjectTrackerConfig(), lifecycle=LifecycleConfig(visibility_statistic="max")))


def test_similarity_ranges_are_validated():
    for bad in ((0.8, 0.2), (0.5,), (0.2, 1.5), ("a", 0.5)):
        with pytest.raises(TrackerInputError, match="refinement_similarity_range"):
            MultiObjectTracker(_config(refinement_similarity_range=bad))
        with pytest.raises(TrackerInputError, match="refinement_similarity_range"):
            MultiObjectTracker(dataclasses.replace(MultiObjectTrackerConfig(),
                                                   refinement_similarity_range=bad))


class CountingKalmanRefiner(KernelRefiner):
    """Matches 10 px right of wherever the prediction is, with visibility 0.5."""

    def refine(self, image, state, predicted_center=None):
        cx, cy = predicted_center
        self.box = (cx + 10.0 - 20.0, cy - 40.0, 40.0, 80.0)
        return super().refine(image, state, predicted_center)


def test_hand_started_track_trusts_its_refinement_by_its_own_quality_mapping():
    # visibility 0.5 (both kernels 0.5): detection-born mapping (0.5, 0.95) -> quality 0,
    # the floor; the hand-started mapping (0.2, 0.8) -> quality 0.5: a smaller measurement
    # std, so the filter follows the refinement further
    moved = {}
    for low in (0.5, 0.2):
        cfg = _config(refinement_similarity_range=(low, 0.8), occlusion_similarity=0.4,
                      undetected_quality_factor=1.0)
        trk = MultiObjectTracker(cfg, refiner=CountingKalmanRefiner([0.5, 0.5]))
        trk.start_track(IMG, 0.0, (200, 100, 40, 80))
        (t,) = trk.step(IMG, DT).tracks
        assert t.state == "confirmed"
        moved[low] = t.box[0] - 200.0
    assert 0.0 < moved[0.5] < moved[0.2] < 10.0


# -- column coverage and the re-centred search (two-column layouts) ---------------------------

def test_layout_columns_and_column_coverage():
    from mk_tracker.tracking.kernel_layouts import column_coverage, layout_columns
    assert layout_columns(6).tolist() == [0, 1, 0, 1, 0, 1]
    assert layout_columns(4).tolist() == [0, 1, 0, 1]
    assert layout_columns(5).tolist() == [-1, 0, 1, 0, 1]
    assert layout_columns(2).tolist() == [-1, -1]
    # right column on background: best of the right column is 0.1
    assert column_coverage([0.9, 0.0, 0.8, 0.1, 0.7, 0.05], 6) == pytest.approx(0.1)
    # legs hidden, both columns see the torso: min(0.7, 0.8)
    assert column_coverage([0.7, 0.8, 0.6, 0.5, 0.0, 0.0], 6) == pytest.approx(0.7)
    # the full-width head kernel of the 5 layout counts for both columns
    assert column_coverage([0.6, 0.9, 0.0, 0.8, 0.0], 5) == pytest.approx(0.6)
    # no columns: the best kernel; NaN counts as 0
    assert column_coverage([0.3, np.nan], 2) == pytest.approx(0.3)
    with pytest.raises(ValueError):
        column_coverage([0.5, 0.5, 0.5], 4)


class HalfLockRefiner(KernelRefiner):
    """6 kernels, a person at x = 200 (box 40 wide).  A search starting within 5 px of it
    finds it with every kernel (0.6); one starting near x = 218 (0.45 w to the right)
    settles there with the left column on the person's right half (0.9) and the right
    column on background (0): a stable wrong optimum.  Else nothing (0.05)."""

    LOCK = [0.9, 0.0, 0.9, 0.0, 0.9, 0.0]

    def __init__(self):
        super().__init__([0.6] * 6)
        self.starts = []

    def start(self, image, box):
        return {"x": float(box[0])}

    def refine(self, image, state, predicted_center=None):
        x0 = state["x"] if predicted_center is None else predicted_center[0] - 20.0
        self.starts.append(round(x0, 1))
        if abs(x0 - 200.0) <= 5.0:
            x, rho = 200.0, [0.6] * 6
        elif abs(x0 - 218.0) <= 10.0:
            x, rho = 218.0, self.LOCK
        else:
            x, rho = x0, [0.05] * 6
        state["x"] = x
        self.rho, self.box = np.array(rho), (x, 100.0, 40.0, 80.0)
        return super().refine(image, state, predicted_center)


def test_a_box_locked_half_on_the_person_is_moved_onto_it():
    # the weighted visibility of the wrong optimum is 0.9: it is "visible"
    assert visibility_similarity(HalfLockRefiner.LOCK, statistic="weighted") == \
        pytest.approx(0.9)
    boxes = {}
    for recentre in (False, True):
        ref = HalfLockRefiner()
        trk = MultiObjectTracker(_config(column_recentre=recentre),
                                 refiner=ref)
        trk.start_track(IMG, 0.0, (218, 100, 40, 80))       # started on the wrong optimum
        trk.step(IMG, DT)
        t = trk.tracks[0]
        assert t.state.value == "confirmed"
        boxes[recentre] = (float(t.refined_box[0]), float(t.box[0]), ref.starts)
    # without: one search a frame, which stays on the wrong optimum
    assert boxes[False][2] == [218.0] and boxes[False][:2] == (218.0, 218.0)
    # with: a second search 0.45 * 40 = 18 px to the left finds both columns and is kept
    assert boxes[True][2] == [218.0, 200.0]
    assert boxes[True][0] == 200.0 and abs(boxes[True][1] - 200.0) < 5.0


class SideOccludedRefiner(HalfLockRefiner):
    """The person at x = 200 with its right half behind a pillar: the search from there
    sees the left column only (0.9 / 0); a search 18 px further left puts the right column
    on the person's left half and the left column on background (0 / 0.9)."""

    def refine(self, image, state, predicted_center=None):
        x0 = state["x"] if predicted_center is None else predicted_center[0] - 20.0
        self.starts.append(round(x0, 1))
        x, rho = (200.0, self.LOCK) if abs(x0 - 200.0) <= 5.0 else \
            (182.0, [0.0, 0.9, 0.0, 0.9, 0.0, 0.9])
        state["x"] = x
        self.rho, self.box = np.array(rho), (x, 100.0, 40.0, 80.0)
        return KernelRefiner.refine(self, image, state, predicted_center)


def test_a_side_occluded_target_keeps_its_one_column_result():
    ref = SideOccludedRefiner()
    trk = MultiObjectTracker(_config(column_recentre=True), refiner=ref)
    trk.start_track(IMG, 0.0, (200, 100, 40, 80))
    trk.step(IMG, DT)
    t = trk.tracks[0]
    # the re-centred search ran (18 px left) but saw one column only: not kept
    assert ref.starts == [200.0, 182.0]
    assert t.state.value == "confirmed" and float(t.refined_box[0]) == 200.0


# -- bounded coasting of hand-started tracks (manual_track.max_coast_position_std) ----------

STEP = 4.0      # px per frame: 100 px/s at 25 fps


class ScriptedRefiner(KernelRefiner):
    """Sees a 40x80 person walking right at 100 px/s (x = 200 + 4 k in frame k) up to frame
    ``hidden_from``, and nothing (every kernel similarity 0.02) after it; the test sets
    ``frame``."""

    def __init__(self, hidden_from):
        super().__init__([0.9, 0.9])
        self.hidden_from = hidden_from
        self.frame = 0

    def refine(self, image, state, predicted_center=None):
        self.box = (200.0 + STEP * self.frame, 100.0, 40.0, 80.0)
        self.rho = np.array([0.9, 0.9]) if self.frame < self.hidden_from \
            else np.full(2, 0.02)
        return super().refine(image, state, predicted_center)


def _walk_then_hide(max_std=None, frames=100, hidden_from=20, born=False):
    manual = {} if max_std is None else {"max_coast_position_std": max_std}
    cfg = _config(occlusion_similarity=0.4, visibility_statistic="weighted", **manual)
    ref = ScriptedRefiner(hidden_from)
    trk = MultiObjectTracker(cfg, refiner=ref)
    if born:
        trk.step(IMG, 0.0, [FrameDetection((200, 100, 40, 80), 0.9)])
    else:
        trk.start_track(IMG, 0.0, (200, 100, 40, 80))
    out = []
    for k in range(1, frames):
        ref.frame = k
        r = trk.step(IMG, k * DT, [FrameDetection((200 + STEP * k, 100, 40, 80), 0.9)]
                     if born and k < hidden_from else [])
        out.append(r.tracks[0] if r.tracks else None)
    return out, trk


def test_a_coasting_hand_started_track_holds_its_position_instead_of_running_away():
    assert ManualTrackConfig().max_coast_position_std == 1.0
    held, trk = _walk_then_hide()               # the default bound: 1 box width (40 px)
    free, _ = _walk_then_hide(0.0, frames=120)
    last_seen_x = 200.0 + STEP * 19
    # both coast (occluded) from frame 20 on; without the bound the box runs on at 100 px/s
    # until its centre leaves the 640 px image (lost)
    assert held[17].state == free[17].state == "confirmed"
    assert free[79].state == "occluded" and free[79].box[0] > last_seen_x + 240.0
    assert free[-1].state == "lost"
    # with it the box stops once the position std passes 40 px (the filter is sure of the
    # velocity after 20 exact measurements: ~1.7 s of coasting, ~170 px), stays occluded
    # (still searched for) and stands still
    assert all(t.state == "occluded" for t in held[19:])
    assert held[-1].box[0] < last_seen_x + 200.0
    assert held[-1].box == held[-30].box
    assert held[-1].velocity == pytest.approx((0.0, 0.0), abs=1e-3)
    (t,) = trk.tracks
    assert t.held and t.position_std > 40.0


def test_a_smaller_bound_holds_the_box_sooner():
    stops = {}
    for bound in (1.0, 0.5, 0.25):
        out, _ = _walk_then_hide(bound)
        stops[bound] = out[-1].box[0]
    assert 200.0 + STEP * 19 < stops[0.25] < stops[0.5] < stops[1.0]


def test_a_held_hand_started_track_follows_the_target_when_it_is_seen_again():
    cfg = _config(max_coast_position_std=0.5, occlusion_similarity=0.4,
                  visibility_statistic="weighted")
    ref = ScriptedRefiner(hidden_from=20)
    trk = MultiObjectTracker(cfg, refiner=ref)
    trk.start_track(IMG, 0.0, (200, 100, 40, 80))
    for k in range(1, 80):
        ref.frame = k
        trk.step(IMG, k * DT)
    assert trk.tracks[0].held
    ref.hidden_from, ref.frame = 10 ** 6, 80    # seen again, at x = 200 + 4 * 80
    (t,) = trk.step(IMG, 80 * DT).tracks
    assert t.state == "confirmed" and not trk.tracks[0].held
    assert t.box[0] == pytest.approx(200.0 + STEP * 80, abs=5.0)


def test_detection_born_tracks_ignore_the_coasting_bound():
    # a bound of 0.05 box widths (2 px) holds a hand-started track within a few frames
    manual, _ = _walk_then_hide(0.05, frames=45)
    assert manual[25].box == manual[40].box
    a, trk = _walk_then_hide(0.05, frames=45, born=True)
    b, _ = _walk_then_hide(0.0, frames=45, born=True)
    assert [t and (t.state, t.box) for t in a] == [t and (t.state, t.box) for t in b]
    # the detection-born track coasts on the prediction until it is lost
    # (lifecycle.max_undetected_time 0.5 s), never held
    assert a[25].state == "occluded" and a[25].box[0] > 200.0 + STEP * 25 - 10.0
    assert a[25].box[0] > a[22].box[0] + 2.0 * STEP
    assert a[40].state == "lost"
    assert not any(t.held for t in trk.tracks)
