"""Multi-object tracker: bad input, cross-modal geometry, lifecycle, and synthetic scenes.

Detections on synthetic scenes are derived from the scene's ground truth (visible people with
seeded noise), which isolates the tracker from any detector.
"""

from __future__ import annotations

import dataclasses
from collections import Counter

import numpy as np
import pytest

from mk_tracker.synthetic.presets import (CROSS_MODAL_HOMOGRAPHY, cross_modal_scene, crossing_scene,
                                          enter_leave_scene, occlusion_scene)
from mk_tracker.evaluation.metrics import MotRow, mot_metrics
from mk_tracker.tracking.multi_object_tracker import (FrameDetection, MultiObjectTracker,
                                             MultiObjectTrackerConfig, TrackerInputError)
from mk_tracker.parameters import parameter_specs, updated
from mk_tracker.tracking.track import LifecycleConfig

from fake_refiners import LabelRefiner

IMG = np.zeros((480, 640, 3), np.uint8)
DT = 1.0 / 25.0


def plain(**changes) -> MultiObjectTrackerConfig:
    """Config without the multiple-kernel refiner (geometry-only unit tests)."""
    return updated(MultiObjectTrackerConfig(), {"use_multi_kernel": False, **changes})


def walk(trk, frames, boxes_at, start=0, stamp0=0.0, **det_kw):
    """Feed ``frames`` frames whose detections are ``boxes_at(i)``; returns the results."""
    out = []
    for i in range(start, start + frames):
        dets = [FrameDetection(b, 0.9, **det_kw) for b in boxes_at(i)]
        out.append(trk.step(IMG, stamp0 + i * DT, dets))
    return out


# -- configuration ----------------------------------------------------------------------------

def test_every_constant_is_a_declared_parameter():
    names = {s.name for s in parameter_specs(MultiObjectTrackerConfig())}
    for expected in ("lifecycle.min_hits", "lifecycle.max_lost_time", "association.gate",
                     "kalman.sigma_u", "multi_kernel.num_kernels", "homography",
                     "stale_tolerance", "reacquire_similarity"):
        assert expected in names
    assert all(s.description for s in parameter_specs(MultiObjectTrackerConfig()))


def test_singular_homography_is_a_clear_error():
    cfg = dataclasses.replace(plain(), homography=(1.0, 2.0, 0.0, 2.0, 4.0, 0.0, 0.0, 0.0, 1.0))
    with pytest.raises(TrackerInputError, match="singular"):
        MultiObjectTracker(cfg)


def test_bad_image_and_stamp_are_clear_errors():
    trk = MultiObjectTracker(plain())
    with pytest.raises(TrackerInputError):
        trk.step("not an image", 0.0)
    with pytest.raises(TrackerInputError):
        trk.step(IMG, float("nan"))


# -- bad detections ---------------------------------------------------------------------------

def test_bad_detections_are_skipped_and_counted():
    trk = MultiObjectTracker(plain())
    dets = [FrameDetection((float("nan"), 10, 20, 40)),
            FrameDetection((10, 10, -20, 40)),
            FrameDetection((900, 900, 20, 40)),          # outside the 640x480 image
            FrameDetection((10, 10, 20, 40), plane="depth"),
            FrameDetection((100, 100, 30, 60), 0.9)]
    r = trk.step(IMG, 0.0, dets)
    assert r.skipped_bad_detections == 4
    assert len(r.tracks) == 1 and r.tracks[0].box == pytest.approx((100, 100, 30, 60))
    assert any("skipped 4 bad" in e for e in r.events)
    assert trk.totals["skipped_bad_detections"] == 4


def test_stale_detections_are_dropped_and_counted():
    trk = MultiObjectTracker(plain(stale_tolerance=0.5))
    r = trk.step(IMG, 10.0, [FrameDetection((100, 100, 30, 60), 0.9, stamp=9.2),
                             FrameDetection((300, 100, 30, 60), 0.9, stamp=9.8)])
    assert r.dropped_stale == 1
    assert [t.box[0] for t in r.tracks] == pytest.approx([300.0])


def test_late_detection_is_moved_to_the_frame_time():
    """A detection 0.2 s old of a target moving at 100 px/s lands 20 px ahead of its box."""
    trk = MultiObjectTracker(plain())
    speed = 100.0
    walk(trk, 30, lambda i: [(50 + speed * i * DT, 200, 30, 60)])   # velocity learned
    t_now = 30 * DT
    old_stamp = t_now - 0.2
    box_then = (50 + speed * old_stamp, 200, 30, 60)
    r = trk.step(IMG, t_now, [FrameDetection(box_then, 0.9, stamp=old_stamp)])
    (track,) = r.reported()
    true_now = 50 + speed * t_now
    assert abs(track.box[0] - true_now) < 3.0
    assert abs(track.box[0] - box_then[0]) > 15.0


# -- time and frame size ----------------------------------------------------------------------

def test_time_going_backwards_resets_and_says_so():
    trk = MultiObjectTracker(plain())
    walk(trk, 5, lambda i: [(100, 100, 30, 60)], stamp0=100.0)
    old_ids = {t.id for t in trk.tracks}
    r = trk.step(IMG, 96.8, [FrameDetection((300, 100, 30, 60), 0.9)])
    assert r.resets == 1
    assert any("backwards by 3.360 s: reset" in e for e in r.events)
    assert len(r.tracks) == 1 and r.tracks[0].box[0] == pytest.approx(300.0)
    assert r.tracks[0].id > max(old_ids)          # ids are never reused, even after reset
    assert trk.totals["resets"] == 1


def test_frame_of_another_size_resets_once_and_tracks_at_the_new_size():
    """A camera that changes resolution: the tracker resets once (old tracks cleared, event,
    counted) and then tracks at the new size instead of skipping every later frame."""
    trk = MultiObjectTracker(plain())
    walk(trk, 5, lambda i: [(100, 100, 30, 60)])
    old_ids = {t.id for t in trk.step(IMG, 5 * DT, [FrameDetection((100, 100, 30, 60))]).tracks}
    assert old_ids
    small = np.zeros((240, 320, 3), np.uint8)
    r = trk.step(small, 6 * DT, [FrameDetection((50, 40, 15, 30))])
    assert r.resets == 1
    assert any("frame 320x240 differs from the previous 640x480: reset" in e for e in r.events)
    assert not old_ids & {t.id for t in r.tracks}         # old tracks are gone
    assert [tuple(t.box) for t in r.tracks] == [pytest.approx((50, 40, 15, 30))]
    assert trk.totals["resets"] == 1 and trk.totals["size_resets"] == 1
    assert trk.frame_size == (240, 320)
    # later frames at the new size are tracked (no further reset): the new track confirms
    results = [trk.step(small, (7 + i) * DT, [FrameDetection((50 + 2 * i, 40, 15, 30))])
               for i in range(5)]
    assert all(res.resets == 0 for res in results)
    assert trk.totals["resets"] == 1
    reported = results[-1].reported()
    assert len(reported) == 1 and reported[0].id not in old_ids
    assert reported[0].box[0] == pytest.approx(58.0, abs=2.0)


# -- lifecycle --------------------------------------------------------------------------------

def test_tentative_until_min_hits_and_false_positive_never_reported():
    trk = MultiObjectTracker(plain())
    results = walk(trk, 3, lambda i: [(100, 100, 30, 60)] + ([(400, 50, 30, 60)] if i == 0
                                                              else []))
    assert [len(r.reported()) for r in results] == [0, 0, 1]
    assert results[-1].reported()[0].state == "confirmed"
    assert all(t.box[0] < 200 for r in results for t in r.reported())
    # the one-frame false positive was deleted after max_tentative_misses (1) + 1 frames
    assert 2 in results[2].deleted_ids or 2 in results[1].deleted_ids


def test_frames_without_a_detector_report_are_not_tentative_misses():
    """A thermal detector at a third of the RGB rate: two of three frames have no
    detection message (``None``), which is not a detection missed (``[]``)."""
    def run(absent):
        trk = MultiObjectTracker(plain())
        results = []
        for i in range(9):
            dets = [FrameDetection((100 + 3 * i, 100, 30, 60), 0.9)] if i % 3 == 0 \
                else absent
            results.append(trk.step(IMG, i * DT, dets))
        return results
    slow = run(None)
    assert [len(r.reported()) for r in slow] == [0] * 6 + [1] * 3      # third detection
    empty = run([])
    assert all(len(r.reported()) == 0 for r in empty)                 # deleted each time
    assert any(empty[i].deleted_ids for i in range(9))


def test_coasting_lost_and_deleted_after_timeouts_ids_never_reused():
    life = LifecycleConfig(max_coast_time=0.4, max_lost_time=1.0)
    trk = MultiObjectTracker(dataclasses.replace(plain(), lifecycle=life))
    walk(trk, 10, lambda i: [(100 + 2 * i, 100, 30, 60)])
    (tid,) = [t.id for t in trk.tracks]
    states = {}
    deleted_at = None
    for i in range(10, 60):
        r = trk.step(IMG, i * DT, [])
        for t in r.tracks:
            states.setdefault(t.state, i)
        if tid in r.deleted_ids:
            deleted_at = i
            break
    last_detection = 9 * DT
    assert (states["occluded"] - 9) * DT <= 0.04 + 1e-9
    assert states["lost"] * DT - last_detection == pytest.approx(0.44, abs=0.041)
    assert deleted_at * DT - states["lost"] * DT == pytest.approx(1.04, abs=0.041)
    r = trk.step(IMG, 60 * DT, [FrameDetection((100, 100, 30, 60))])
    assert r.tracks[0].id > tid


def test_output_carries_velocity_age_and_time_since_detection():
    trk = MultiObjectTracker(plain())
    walk(trk, 40, lambda i: [(100 + 75.0 * i * DT, 100, 30, 60)])       # 75 px/s
    r = trk.step(IMG, 40 * DT, [])
    (t,) = r.reported()
    assert t.velocity[0] == pytest.approx(75.0, abs=5.0)
    assert abs(t.velocity[1]) < 5.0
    assert t.age == pytest.approx(40 * DT)
    assert t.time_since_detection == pytest.approx(DT)
    assert t.state == "occluded" and t.score == 0.0


def test_reacquisition_needs_the_appearance_to_match():
    life = LifecycleConfig(max_coast_time=0.2, max_lost_time=3.0)
    cfg = dataclasses.replace(plain(), lifecycle=life, reacquire_hold_time=0.0)
    for label, expect_same in (("red", True), ("blue", False)):
        ref = LabelRefiner()
        trk = MultiObjectTracker(cfg, refiner=ref)
        ref.labels_at = {100.0: "red"}
        walk(trk, 10, lambda i: [(100, 100, 30, 60)])
        (tid,) = [t.id for t in trk.tracks]
        for i in range(10, 30):                    # hidden for 0.8 s: coast, then lost
            r = trk.step(IMG, i * DT, [])
        assert r.tracks[0].state == "lost"
        ref.labels_at = {100.0: label}
        r = trk.step(IMG, 30 * DT, [FrameDetection((102, 101, 30, 60), 0.9)])
        ids = {t.id for t in r.tracks if t.state != "lost"}
        if expect_same:
            assert ids == {tid} and any("re-acquired" in e for e in r.events)
        else:
            assert tid not in ids and len(ids) == 1


def test_start_track_by_hand_is_confirmed_at_once():
    ref = LabelRefiner()
    ref.labels_at = {200.0: "green"}
    trk = MultiObjectTracker(plain(), refiner=ref)
    tid = trk.start_track(IMG, 0.0, (200, 100, 40, 80))
    r = trk.step(IMG, DT, [])
    assert [(t.id, t.state) for t in r.tracks] == [(tid, "occluded")]
    assert ref.refined == 1                      # the prediction initialised a refinement
    for i in range(2, 100):                      # 4 s without a match: still coasting, reported
        r = trk.step(IMG, i * DT, [])
    assert [(t.id, t.state, t.manual) for t in r.reported()] == [(tid, "occluded", True)]
    with pytest.raises(TrackerInputError):
        trk.start_track(IMG, 0.0, (0, 0, -5, 10))


# -- synthetic scenes with the real multiple-kernel refiner ------------------------------------

def gt_detections(frame, rng, *, min_visible=0.5, noise=2.0, plane="rgb"):
    dets = []
    for o in frame.objects:
        if o.kind != "person" or o.visible_fraction < min_visible:
            continue
        box = o.box_rgb if plane == "rgb" else o.box_thermal
        if not o.in_frame_rgb:
            continue
        scale = 1.0 if plane == "rgb" else 0.5
        x, y, w, h = box
        dets.append(FrameDetection((x + rng.normal(0, noise * scale),
                                    y + rng.normal(0, noise * scale),
                                    w * (1 + rng.normal(0, 0.02)), h * (1 + rng.normal(0, 0.02))),
                                   0.9, frame.stamp, plane))
    return dets


def run_scene(scene, config=None, seed=0, plane="rgb"):
    rng = np.random.default_rng(seed)
    trk = MultiObjectTracker(config or MultiObjectTrackerConfig())
    gt, hyp, results = [], [], []
    for i in range(len(scene)):
        f = scene.frame(i)
        r = trk.step(f.rgb, f.stamp, gt_detections(f, rng, plane=plane))
        results.append((f, r))
        for o in f.objects:
            if o.in_frame_rgb and o.visible_fraction > 0.0:
                gt.append(MotRow(i + 1, o.id, o.box_rgb))
        for t in r.reported():
            hyp.append(MotRow(i + 1, t.id, t.box))
    return results, gt, hyp


def matched_id(f, r, object_id, min_iou=0.3):
    """The reported track id overlapping the object's true box most (None if none)."""
    from mk_tracker.boxes import iou
    box = f.object(object_id).box_rgb
    best = max(r.reported(), key=lambda t: iou(t.box, box), default=None)
    if best is None or iou(best.box, box) < min_iou:
        return None
    return best.id


def test_crossing_people_keep_their_ids():
    scene = crossing_scene()
    results, gt, hyp = run_scene(scene)
    hidden = [i for i, (f, _) in enumerate(results) if f.object(2).visible_fraction < 0.05]
    assert hidden, "the scene must contain a full occlusion"
    first = {k: matched_id(*results[5], k) for k in (1, 2)}
    last = {k: matched_id(*results[-1], k) for k in (1, 2)}
    assert None not in first.values() and first[1] != first[2]
    assert last == first
    m = mot_metrics(gt, hyp)
    assert m["num_switches"] == 0
    assert m["idf1"] > 0.9


def test_person_behind_pillar_longer_than_coasting_is_reacquired():
    scene = occlusion_scene(hidden_frames=40)
    cfg = MultiObjectTrackerConfig()
    results, gt, hyp = run_scene(scene, cfg)
    hidden = [f.stamp for f, _ in results if f.object(1).visible_fraction == 0.0]
    assert hidden[-1] - hidden[0] > cfg.lifecycle.max_coast_time
    states = [t.state for _, r in results for t in r.tracks]
    assert "lost" in states                        # the Kalman filter alone gave up
    before = matched_id(*results[10], 1)
    after = matched_id(*results[-1], 1)
    assert before is not None and after == before
    assert any("re-acquired" in e for _, r in results for e in r.events)
    assert mot_metrics(gt, hyp)["num_switches"] == 0


def test_entering_person_gets_a_new_id_and_leaving_person_is_deleted():
    scene = enter_leave_scene()
    life = LifecycleConfig(max_coast_time=0.5, max_lost_time=1.0)
    cfg = dataclasses.replace(MultiObjectTrackerConfig(), lifecycle=life)
    results, _, _ = run_scene(scene, cfg)
    # person 2 starts inside: its id comes first; person 1 enters later and gets a new one
    id2 = matched_id(*results[5], 2)
    entered = next(i for i, (f, r) in enumerate(results) if matched_id(f, r, 1) is not None)
    id1 = matched_id(*results[entered], 1)
    assert id2 is not None and id1 is not None and id1 != id2
    assert matched_id(*results[-1], 1) == id1
    # person 2 leaves: once its centre is out of the image the track is lost, and deleted
    # max_lost_time later
    centre_out = next(f.stamp for f, _ in results
                      if f.object(2).box_rgb[0] + f.object(2).box_rgb[2] / 2 >= 640)
    deleted = [f.stamp for f, r in results if id2 in r.deleted_ids]
    assert len(deleted) == 1
    lost_at = next(f.stamp for f, r in results
                   if any(t.id == id2 and t.state == "lost" for t in r.tracks))
    assert 0.0 <= lost_at - centre_out <= 0.3      # the (coasting) prediction left too
    assert deleted[0] - lost_at == pytest.approx(life.max_lost_time, abs=DT + 1e-9)
    assert all(id2 not in {t.id for t in r.tracks} for f, r in results if f.stamp > deleted[0])
    assert all(id2 not in {t.id for t in r.reported()} for f, r in results
               if f.stamp >= lost_at)


def test_thermal_detections_land_on_the_rgb_targets():
    from mk_tracker.boxes import iou
    scene = cross_modal_scene(frames=40)
    cfg = updated(MultiObjectTrackerConfig(), {"homography": CROSS_MODAL_HOMOGRAPHY})
    results, gt, hyp = run_scene(scene, cfg, plane="thermal")
    f, r = results[-1]
    for o in f.objects:
        best = max(iou(t.box, o.box_rgb) for t in r.reported())
        assert best > 0.7
    assert mot_metrics(gt, hyp)["mota"] > 0.85
    # the same detections read as RGB-plane boxes (identity homography) miss the targets
    _, gt_id, hyp_id = run_scene(scene, MultiObjectTrackerConfig(), plane="thermal")
    assert mot_metrics(gt_id, hyp_id)["mota"] < 0.2


def test_grey_frames_do_not_break_the_colour_refiner():
    """The multiple-kernel refiner needs BGR; on grey frames the tracker runs on detections."""
    trk = MultiObjectTracker(MultiObjectTrackerConfig())
    grey = np.full((480, 640), 90, np.uint8)
    for i in range(6):
        r = trk.step(grey, i * DT, [FrameDetection((100 + 2 * i, 100, 30, 60), 0.9)])
    assert [(t.id, t.state) for t in r.reported()] == [(1, "confirmed")]
    r = trk.step(grey, 6 * DT, [])
    assert r.tracks[0].state == "occluded"


# -- kernels for the debug image ---------------------------------------------------------------

def test_frame_result_exposes_each_tracks_kernels_for_drawing():
    from mk_tracker.frame_processing import kernel_drawings
    rng = np.random.default_rng(3)
    img = np.full((240, 320, 3), 40, np.uint8)
    box = (120.0, 60.0, 40.0, 100.0)
    img[60:160, 120:160] = rng.integers(0, 255, (100, 40, 3), dtype=np.uint8)
    img[60:110, 120:160, 2] = 230                      # red top half, textured bottom
    cfg = MultiObjectTrackerConfig()
    trk = MultiObjectTracker(cfg)
    results = [trk.step(img, i * DT, [FrameDetection(box, 0.9)]) for i in range(6)]
    r = results[-1]
    (track,) = r.reported()
    k = r.kernels[track.id]
    assert k.track_id == track.id
    assert len(k.centres) == len(k.half_axes) == cfg.multi_kernel.num_kernels
    for (cx, cy), (ax, ay) in zip(k.centres, k.half_axes):
        assert box[0] - 1 <= cx <= box[0] + box[2] + 1 and box[1] - 1 <= cy <= box[1] + box[3] + 1
        assert 0 < ax <= box[2] and 0 < ay <= box[3]
    assert 0.0 <= k.similarity <= 1.0
    # the debug image's ellipses are read from the result, not from tracker internals
    ellipses = kernel_drawings(r)
    assert [e.center for e in ellipses[track.id]] == list(k.centres)
    assert [e.axes for e in ellipses[track.id]] == list(k.half_axes)
    # without a refiner no track has kernels
    plain_trk = MultiObjectTracker(plain())
    out = [plain_trk.step(img, i * DT, [FrameDetection(box, 0.9)]) for i in range(4)][-1]
    assert out.reported() and out.kernels == {} and kernel_drawings(out) == {}


# -- size validation gate (association.max_height_ratio) -------------------------------------

def _short_detection_case(**assoc):
    """A person walked for 10 frames, then a too-short detection of it (40 of 60 px high,
    centre 6 px higher: ratio 1.5); the recovery round (which has its own size ratio) is
    off so that the first round decides.  Returns the person's live tracks."""
    cfg = plain(**{"recovery.enabled": False,
                   **{f"association.{k}": v for k, v in assoc.items()}})
    trk = MultiObjectTracker(cfg)
    walk(trk, 10, lambda i: [(100, 100, 30, 60)])
    walk(trk, 1, lambda i: [(100, 104, 30, 40)], start=10)
    return [t for t in trk.tracks if t.state.name != "DELETED"]


def test_off_size_detection_is_not_matched_with_the_gate_on():
    off = _short_detection_case()
    assert len(off) == 1 and off[0].last_detection == pytest.approx(10 * DT)
    assert off[0].center[1] < 129.0 and off[0].size[1] < 55.0     # pulled by the short box
    # ratio 1.5 > 1.4: the pair is forbidden, the track coasts on its own prediction
    on = _short_detection_case(max_height_ratio=1.4)
    assert len(on) == 1                           # the short box starts no track either
    assert on[0].last_detection == pytest.approx(9 * DT)
    assert on[0].center[1] == pytest.approx(130.0, abs=0.5) and on[0].size[1] == 60.0
    # ratio 1.5 < 1.6: matched as without the gate
    loose = _short_detection_case(max_height_ratio=1.6)
    assert loose[0].center == pytest.approx(off[0].center) and \
        loose[0].size == pytest.approx(off[0].size)


def test_gate_that_never_fires_changes_nothing():
    """Off (0) is today's tracker; a ratio no detection exceeds gives the same tracks."""
    rng = np.random.default_rng(3)
    boxes = [[(100 + 3 * i + rng.normal(0, 2), 100 + rng.normal(0, 2), 30,
               60 + rng.normal(0, 2)), (400 - 2 * i, 120, 32, 64)] for i in range(30)]
    runs = []
    for ratio in (None, 0.0, 3.0):
        cfg = plain() if ratio is None else plain(**{"association.max_height_ratio": ratio})
        trk = MultiObjectTracker(cfg)
        res = walk(trk, 30, lambda i: boxes[i] if i % 7 else boxes[i][:1])
        runs.append([[(o.id, tuple(np.round(o.box, 9))) for o in r.tracks] for r in res])
    assert runs[0] == runs[1] == runs[2]
    assert len(runs[0][-1]) == 2
