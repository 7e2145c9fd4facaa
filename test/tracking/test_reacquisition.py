"""Re-acquisition from the last detection (issues #15 / #19): the pure gate distance and the
tracker's use of it (``reacquire_last_detection_floor`` / ``_speed``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from mk_tracker.parameters import updated
from mk_tracker.tracking.multi_object_tracker import (FrameDetection, MultiObjectTracker,
                                                      MultiObjectTrackerConfig)
from mk_tracker.tracking.reacquisition import last_detection_distance2, nearer_of_both

from fake_refiners import LabelRefiner

IMG = np.zeros((480, 640, 3), np.uint8)
DT = 1.0 / 25.0
LAST_DETECTION_GATE = {"reacquire_last_detection_floor": 0.1,
                       "reacquire_last_detection_speed": 0.3}
KALMAN_GATE_ONLY = {"reacquire_last_detection_floor": 0.0,
                    "reacquire_last_detection_speed": 0.0}


def config(**changes) -> MultiObjectTrackerConfig:
    """No refiner (geometry only); a track coasts 0.2 s before it is lost."""
    return updated(MultiObjectTrackerConfig(), {"use_multi_kernel": False,
                                                "lifecycle.max_coast_time": 0.2, **changes})


# -- the pure distance ------------------------------------------------------------------------

def test_distance_is_normalised_by_height_floor_and_time():
    # |z - c|^2 = 10^2 + 0 = 100; spread^2 = 100^2 (0.05^2 + (0.1 * 2)^2) = 10000 * 0.0425
    d2 = last_detection_distance2(np.array([[10.0, 0.0], [0.0, 0.0]]), np.array([0.0, 0.0]),
                                  100.0, 2.0, 0.05, 0.1)
    assert d2 == pytest.approx([100.0 / 425.0, 0.0])
    # after 4 s the spread^2 is 100^2 (0.0025 + 0.16) = 1625
    assert last_detection_distance2(np.array([[10.0, 0.0]]), np.zeros(2), 100.0, 4.0, 0.05,
                                    0.1)[0] == pytest.approx(100.0 / 1625.0)


def test_distance_counts_negative_time_as_zero_and_is_off_without_spread():
    # floor 0.1 of a 100 px box = 10 px std: a point 10 px away is at d2 = 1
    assert last_detection_distance2(np.array([[13.0, 24.0]]), np.array([3.0, 24.0]), 100.0,
                                    -1.0, 0.1, 0.5)[0] == pytest.approx(1.0)
    assert last_detection_distance2(np.array([[3.0, 4.0]]), np.zeros(2), 100.0, 1.0, 0.0,
                                    0.0)[0] == math.inf
    assert last_detection_distance2(np.array([[3.0, 4.0]]), np.zeros(2), 0.0, 1.0, 0.1,
                                    0.1)[0] == math.inf


# -- in the tracker ---------------------------------------------------------------------------

def _walk_hide_return(trk, hidden_frames: int, back_at: tuple) -> tuple[int, set[int]]:
    """A person walks right at 100 px/s for 15 frames (detected), is missed for
    ``hidden_frames`` frames, then is detected at ``back_at``; returns the first track's id
    and the ids of the tracks that are not lost after the return."""
    for i in range(15):
        trk.step(IMG, i * DT, [FrameDetection((100 + 4.0 * i, 100, 30, 60), 0.9)])
    (tid,) = [t.id for t in trk.tracks]
    for i in range(15, 15 + hidden_frames):
        trk.step(IMG, i * DT, [])
    r = trk.step(IMG, (15 + hidden_frames) * DT, [FrameDetection(back_at, 0.9)])
    return tid, {t.id for t in r.tracks if t.state != "lost"}


def test_person_back_where_last_detected_keeps_its_id_only_with_the_last_detection_gate():
    # last detection at x = 156; hidden 1 s, the prediction ran on 100 px: the person turned
    # back and is found 2 px behind the last detection
    back = (154.0, 100.0, 30.0, 60.0)
    tid, ids = _walk_hide_return(MultiObjectTracker(config(**KALMAN_GATE_ONLY)), 25, back)
    assert tid not in ids and len(ids) == 1            # a new id: the Kalman gate refused
    trk = MultiObjectTracker(config(**LAST_DETECTION_GATE))
    tid, ids = _walk_hide_return(trk, 25, back)
    assert ids == {tid}
    (t,) = [t for t in trk.tracks if t.id == tid]
    # restarted at the detection (centre 169, 130) with the 1 px measurement std
    assert t.center == pytest.approx((169.0, 130.0), abs=1.0)


def test_last_detection_gate_widens_with_the_time_unseen():
    # 80 px behind the last detection (centre 171 -> 91), box height 60, floor 0.1, speed
    # 0.3 box heights/s: after 0.6 s unseen spread^2 = 3600 (0.01 + 0.0324) = 152.6, d2 = 41.9
    # > 13.8; after 2.0 s spread^2 = 3600 (0.01 + 0.36) = 1332, d2 = 4.8 < 13.8
    back = (156.0 - 80.0, 100.0, 30.0, 60.0)
    tid, ids = _walk_hide_return(MultiObjectTracker(config(**LAST_DETECTION_GATE)), 14, back)
    assert tid not in ids
    tid, ids = _walk_hide_return(MultiObjectTracker(config(**LAST_DETECTION_GATE)), 49, back)
    assert ids == {tid}


def test_nearer_of_both_takes_the_smaller_distance_per_track():
    kalman = np.array([[50.0, 0.5], [50.0, 50.0]])
    points = np.array([[10.0, 0.0], [300.0, 0.0]])
    # track 0 last detected at centre (0, 0) height 100, 2 s ago: spread^2 = 425 (see above)
    # track 1 at centre (300, 0) height 50, 0 s ago: spread^2 = 2500 * 0.0025 = 6.25
    boxes = np.array([[-20.0, -50.0, 40.0, 100.0], [290.0, -25.0, 20.0, 50.0]])
    out = nearer_of_both(kalman, points, boxes, np.array([2.0, 0.0]), 0.05, 0.1)
    assert out == pytest.approx(np.array([[100.0 / 425.0, 0.5], [50.0, 0.0]]))
    assert nearer_of_both(kalman, points, boxes, np.array([2.0, 0.0]), 0.0, 0.0) == \
        pytest.approx(kalman)


class MismatchRefiner:
    """No refinement (always lost) and no appearance match: every person looks different."""

    def start(self, image, box):
        return object()

    def refine(self, image, state, predicted_center=None):
        return type("R", (), {"box": None, "similarity": 0.0, "lost": True})()

    def appearance_similarity(self, image, state, box):
        return 0.0


def _confirmed_after(back_at: float, **changes) -> int:
    """Frames until a new person's detection at x = ``back_at`` is reported, 1.04 s after a
    track walking right at 100 px/s lost its detections at x = 156 (appearance never
    matches: no re-acquisition)."""
    trk = MultiObjectTracker(config(**LAST_DETECTION_GATE, **changes),
                             refiner=MismatchRefiner())
    for i in range(15):
        trk.step(IMG, i * DT, [FrameDetection((100 + 4.0 * i, 100, 30, 60), 0.9)])
    for i in range(15, 40):
        trk.step(IMG, i * DT, [])
    for k in range(30):
        r = trk.step(IMG, (40 + k) * DT, [FrameDetection((back_at, 100, 30, 60), 0.9)])
        if r.reported():
            return k + 1
    return -1


def test_only_the_kalman_gate_holds_a_new_track_back():
    """With reacquire_hold_time > 0, a tentative track on a detection inside a lost track's
    Kalman gate waits up to that time (the person may come back part-occluded); one that is
    only near the lost track's last detection is confirmed at min_hits (3) as before."""
    assert _confirmed_after(154.0, reacquire_hold_time=0.6) == 3   # last detection x = 156
    # on the prediction (x = 156 + 100 * 1.04 s): held for reacquire_hold_time 0.6 s
    assert _confirmed_after(260.0, reacquire_hold_time=0.6) > 3 + 10


def test_by_default_a_new_track_is_not_held_back_by_a_lost_one():
    """The default reacquire_hold_time 0 (chosen by every leave-one-sequence-out fold of
    benchmarks/bench_multi_object.py): the detection on the lost track's prediction is
    reported at min_hits (3), like any other new person."""
    assert MultiObjectTrackerConfig().reacquire_hold_time == 0.0
    assert _confirmed_after(260.0) == 3


def test_a_track_keeps_its_last_detection_box_itself_not_the_filtered_one():
    trk = MultiObjectTracker(config())
    for i in range(6):
        trk.step(IMG, i * DT, [FrameDetection((100 + 4.0 * i, 100, 30 + i, 60), 0.9)])
    (t,) = trk.tracks
    assert tuple(t.detected_box) == (120.0, 100.0, 35.0, 60.0)
    assert t.size[0] != 35.0                         # the smoothed size lags behind
    trk.step(IMG, 6 * DT, [])                        # a missed frame leaves it as it was
    assert tuple(t.detected_box) == (120.0, 100.0, 35.0, 60.0)


def test_distinct_best_is_a_ratio_test_both_ways():
    from mk_tracker.tracking.reacquisition import distinct_best
    nan = float("nan")
    sims = np.array([[0.9, 0.5, nan],
                     [0.85, nan, 0.3]])
    # (0, 0): beats its row (0.5) by 0.4 but its column (0.85) by 0.05 only
    assert distinct_best(sims, 0.0).tolist() == [[True, False, False],
                                                 [False, False, False]]
    assert not distinct_best(sims, 0.1)[0, 0]
    # (1, 2) has no rival in its column, but its row's 0.85 beats it; a lone candidate has
    # no rival at all: distinct at any margin
    assert distinct_best(np.array([[0.45]]), 0.5).tolist() == [[True]]
    assert distinct_best(np.array([[nan]]), 0.0).tolist() == [[False]]


def test_reacquire_margin_gives_no_id_back_between_indistinguishable_candidates():
    """Without a refiner every similarity is 1: two detections in the lost track's gate
    cannot be told apart, so with a positive margin neither takes the id back; one alone
    still does."""
    back, beside = (154.0, 100.0, 30.0, 60.0), (190.0, 100.0, 30.0, 60.0)
    for margin, extra, keeps in ((-1.0, [beside], True), (0.05, [beside], False),
                                 (0.05, [], True)):
        trk = MultiObjectTracker(config(reacquire_margin=margin, **LAST_DETECTION_GATE))
        for i in range(15):
            trk.step(IMG, i * DT, [FrameDetection((100 + 4.0 * i, 100, 30, 60), 0.9)])
        (tid,) = [t.id for t in trk.tracks]
        for i in range(15, 40):
            trk.step(IMG, i * DT, [])
        r = trk.step(IMG, 40 * DT, [FrameDetection(b, 0.9) for b in [back] + extra])
        took = any("re-acquired" in e for e in r.events)
        assert took is keeps, (margin, extra)


def test_nearest_others_leaves_the_box_itself_out():
    from mk_tracker.tracking.reacquisition import nearest_others
    boxes = np.array([[0.0, 0, 10, 10], [50, 0, 10, 10], [20, 0, 10, 10], [90, 0, 10, 10]])
    near = nearest_others(boxes[0], boxes, 2)
    assert near.tolist() == [[20, 0, 10, 10], [50, 0, 10, 10]]
    assert nearest_others(boxes[0], boxes, 0).shape == (0, 4)
    assert nearest_others(boxes[0], boxes[:1], 3).shape == (0, 4)


@pytest.mark.parametrize("bystander, rivals, keeps", [
    ("red", 0, True),      # the candidate alone is a distinct best match
    ("red", 1, False),     # a look-alike bystander: the model does not tell them apart
    ("blue", 1, True)])    # a bystander in other clothes is no rival
def test_reacquire_rivals_are_the_people_around(bystander, rivals, keeps):
    ref = LabelRefiner({100.0: "red", 154.0: "red", 300.0: bystander})
    trk = MultiObjectTracker(config(reacquire_margin=0.05, reacquire_rivals=rivals,
                                    **LAST_DETECTION_GATE), refiner=ref)
    other = FrameDetection((300.0, 100.0, 30.0, 60.0), 0.9)
    for i in range(15):
        trk.step(IMG, i * DT, [FrameDetection((100 + 4.0 * i, 100, 30, 60), 0.9), other])
    tid = min(t.id for t in trk.tracks)
    for i in range(15, 40):
        trk.step(IMG, i * DT, [other])
    assert [t.state for t in trk.tracks if t.id == tid] == ["lost"]
    r = trk.step(IMG, 40 * DT, [FrameDetection((154.0, 100.0, 30.0, 60.0), 0.9), other])
    assert any(f"track {tid} re-acquired" in e for e in r.events) is keeps
