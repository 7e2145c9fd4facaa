"""Observation-centric recovery of drifted active tracks (issue #19,
mk_tracker/tracking/recovery.py): the pure cost and round, and the tracker's step 4b'.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from mk_tracker.parameters import updated
from mk_tracker.tracking.multi_object_tracker import (FrameDetection, MultiObjectTracker,
                                                      MultiObjectTrackerConfig)
from mk_tracker.tracking.recovery import (RecoveryConfig, recover_into, recovery_cost,
                                         recovery_round, restart_filter)
from mk_tracker.tracking.track import TrackState

IMG = np.zeros((480, 640, 3), np.uint8)
DT = 1.0 / 25.0
ON = RecoveryConfig(enabled=True, min_similarity=0.0)   # floor 0.05, speed 0.3, gate 13.8


# -- the pure cost ----------------------------------------------------------------------------

def test_cost_is_the_distance_from_the_last_detection_normalised_by_its_spread():
    # last detected box centre (115, 130), height 60; 0.5 s later the std is
    # 60 sqrt(0.05^2 + (0.3 * 0.5)^2) = 60 sqrt(0.025) px, so spread^2 = 3600 * 0.025 = 90
    last = np.array([[100.0, 100.0, 30.0, 60.0]])
    dets = np.array([[106.0, 108.0, 30.0, 60.0],      # 6, 8 px off: d2 = 100 / 90
                     [140.0, 100.0, 30.0, 60.0],      # 40 px off: d2 = 1600 / 90 > 13.8
                     [100.0, 100.0, 30.0, 100.0]])    # same centre x, 20 px lower, 1.67 x high
    cost = recovery_cost(last, [0.5], dets, ON)
    assert cost[0, 0] == pytest.approx(100.0 / 90.0)
    assert cost[0, 1] == math.inf                     # outside the gate
    assert cost[0, 2] == math.inf                     # height ratio 1.67 > 1.6
    wider = RecoveryConfig(enabled=True, max_size_ratio=1.7)
    assert recovery_cost(last, [0.5], dets[2:], wider)[0, 0] == pytest.approx(400.0 / 90.0)


def test_cost_checks_its_shapes_and_is_off_without_spread():
    with pytest.raises(ValueError, match="elapsed"):
        recovery_cost(np.zeros((2, 4)) + 10.0, [0.1], np.zeros((1, 4)) + 10.0, ON)
    flat = RecoveryConfig(enabled=True, floor=0.0, speed=0.0)
    assert recovery_cost(np.array([[0.0, 0.0, 10.0, 20.0]]), [1.0],
                         np.array([[0.0, 0.0, 10.0, 20.0]]), flat)[0, 0] == math.inf


def _track(state, box=(100.0, 100.0, 30.0, 60.0), detected_stamp=0.0, manual=False):
    return SimpleNamespace(state=state, detected_box=np.array(box), manual=manual,
                           detected_stamp=detected_stamp, is_still=lambda: False)


def test_round_is_one_to_one_by_least_distance_and_off_unless_enabled():
    near = _track(TrackState.CONFIRMED)
    nearer = _track(TrackState.CONFIRMED, box=(106.0, 100.0, 30.0, 60.0))
    dets = [np.array([106.0, 100.0, 30.0, 60.0])]
    # both pass the gate (d2 = 36 / 90 and 0 at 0.5 s); the second one's last detection
    # is exactly there
    assert recovery_round([near, nearer], dets, [None], 0.5, ON) == [(nearer, 0, None)]
    assert recovery_round([near, nearer], dets, [None], 0.5,
                          RecoveryConfig(enabled=False)) == []
    assert recovery_round([near], [], [], 0.5, ON) == []


def test_round_needs_the_appearance_to_match_when_asked():
    a, b = _track(TrackState.CONFIRMED), _track(TrackState.CONFIRMED,
                                                 box=(110.0, 100.0, 30.0, 60.0))
    dets = [np.array([104.0, 100.0, 30.0, 60.0])]
    looks = {id(a): 0.65, id(b): 0.9}
    cfg = RecoveryConfig(enabled=True, min_similarity=0.7)
    # ``a`` is nearer (4 px against 6 px) but looks less alike than 0.7: ``b`` gets it
    assert recovery_round([a, b], dets, [None], 0.5, cfg,
                          lambda t, box: looks[id(t)]) == [(b, 0, None)]
    looks[id(b)] = float("nan")                 # the refiner refused the box: no pair
    assert recovery_round([a, b], dets, [None], 0.5, cfg, lambda t, box: looks[id(t)]) == []
    assert recovery_round([a, b], dets, [None], 0.5, ON,
                          lambda t, box: looks[id(t)]) == [(a, 0, None)]


def test_restart_gives_a_new_filter_at_the_detection_still_or_with_observed_velocity():
    t = _track(TrackState.CONFIRMED, detected_stamp=1.0)      # last centre (115, 130)
    kalman = MultiObjectTrackerConfig().kalman
    restart_filter(t, np.array([125.0, 90.0, 40.0, 80.0]), 1.5, kalman)
    assert t.kf.center == pytest.approx((145.0, 130.0)) and t.kf.velocity == \
        pytest.approx((0.0, 0.0))
    assert t.size == pytest.approx((40.0, 80.0))
    assert t.kf.covariance[0, 0] == pytest.approx(kalman.initial_position_var)
    restart_filter(t, np.array([125.0, 90.0, 40.0, 80.0]), 1.5, kalman,
                   observed_velocity=True)
    # (145 - 115, 130 - 130) px in 0.5 s
    assert t.kf.velocity == pytest.approx((60.0, 0.0))


def test_round_takes_free_and_tentative_detections_for_free_confirmed_tracks_only():
    drifted = _track(TrackState.CONFIRMED)
    busy = _track(TrackState.OCCLUDED, box=(300.0, 100.0, 30.0, 60.0))
    tentative = _track(TrackState.TENTATIVE, box=(101.0, 100.0, 30.0, 60.0))
    hand = _track(TrackState.CONFIRMED, box=(300.0, 100.0, 30.0, 60.0), manual=True)
    dets = [np.array([101.0, 100.0, 30.0, 60.0]),      # held by the tentative track
            np.array([302.0, 100.0, 30.0, 60.0])]      # held by ``busy`` (step 4b matched)
    pairs = recovery_round([drifted, busy, tentative, hand], dets, [tentative, busy], 0.4,
                           ON)
    # ``busy`` holds a detection, the tentative track is no candidate, the hand-started
    # track is never recovered, and a detection held by a confirmed track is not taken
    assert pairs == [(drifted, 0, tentative)]


# -- in the tracker ---------------------------------------------------------------------------

class DriftRefiner:
    """Sees the person well (similarity 0.95) but a little further right each frame:
    ``step`` px per refinement from x = 100 (the kernels sliding off their person)."""

    def __init__(self, step: float):
        self.step = step
        self.calls = 0

    def start(self, image, box):
        return object()

    def refine(self, image, state, predicted_center=None):
        self.calls += 1
        box = (100.0 + self.step * self.calls, 100.0, 30.0, 60.0)
        return SimpleNamespace(box=box, similarity=0.95, lost=False)

    def appearance_similarity(self, image, state, box):
        return 0.9


class DriftRefinerOtherLook(DriftRefiner):
    """The same drift, but the returning box does not look like the track (0.5 < 0.7)."""

    def appearance_similarity(self, image, state, box):
        return 0.5


def _drift_then_return(back_at: tuple, refiner=None, **changes):
    """A person stands at (100, 100, 30, 60), detected for 15 frames; then 10 frames
    without a detection in which the refinement drags the track 3 px a frame to the right
    (30 px = 0.5 box heights); then the detection ``back_at`` for 4 frames.  Returns the
    first track's id, the tracker, the last result and the tracks' centres after each
    of those 4 frames."""
    trk = MultiObjectTracker(updated(MultiObjectTrackerConfig(), changes),
                             refiner=refiner or DriftRefiner(3.0))
    for i in range(15):
        trk.step(IMG, i * DT, [FrameDetection((100.0, 100.0, 30.0, 60.0), 0.9)])
    (tid,) = [t.id for t in trk.tracks]
    for i in range(15, 25):
        r = trk.step(IMG, i * DT, [])
    (t,) = r.tracks
    assert t.state == "confirmed" and t.box[0] > 120.0       # drifted > 20 px, still active
    centres = []
    for i in range(25, 29):
        r = trk.step(IMG, i * DT, [FrameDetection(back_at, 0.9)])
        centres.append({t.id: tuple(t.center) for t in trk.tracks})
    return tid, trk, r, centres


def test_drifted_track_gets_its_returning_detection_instead_of_a_new_track_being_born():
    # the person did not move: 0.44 s after its last detection it is detected at the same
    # place, 0.5 box heights from the drifted track's estimate
    back = (100.0, 100.0, 30.0, 60.0)
    tid, _, r, _ = _drift_then_return(back, **{"recovery.enabled": False})
    assert {t.id for t in r.reported()} - {tid}, "without recovery a new id is born"
    tid, trk, r, centres = _drift_then_return(back)              # the defaults
    assert [t.id for t in r.reported()] == [tid] and len(trk.tracks) == 1
    # restarted at the detection's centre (115, 130), not averaged with the drifted
    # estimate (> 135), and still: after 3 more frames on the same detection it is there
    assert centres[0][tid] == pytest.approx((115.0, 130.0))
    assert centres[3][tid] == pytest.approx((115.0, 130.0), abs=0.5)


def test_returning_detection_that_does_not_look_like_the_track_starts_a_new_one():
    tid, trk, r, _ = _drift_then_return((100.0, 100.0, 30.0, 60.0),
                                        refiner=DriftRefinerOtherLook(3.0))
    assert len({t.id for t in r.reported()} - {tid}) == 1 and len(trk.tracks) == 2


def test_detection_far_from_both_the_estimate_and_the_last_detection_starts_a_track():
    # 130 px right of the last detected centre: d2 = (130 / 8.5)^2 ~ 235 at 0.44 s,
    # far outside the gate; also 100 px from the drifted estimate
    tid, trk, r, _ = _drift_then_return((230.0, 100.0, 30.0, 60.0))
    reported = {t.id for t in r.reported()}
    assert len(reported - {tid}) == 1
    (new,) = [t for t in trk.tracks if t.id != tid]
    assert new.box[0] == pytest.approx(230.0, abs=1.0)


def test_recover_into_updates_the_assignment_and_deletes_the_tentative_holder():
    drifted = _track(TrackState.CONFIRMED)
    drifted.id = 3
    tentative = _track(TrackState.TENTATIVE, box=(101.0, 100.0, 30.0, 60.0))
    tentative.id = 9
    boxes = [np.array([500.0, 100.0, 30.0, 60.0]), np.array([101.0, 100.0, 30.0, 60.0])]
    matched = {1: 9}                     # step 4b gave detection 1 to the tentative track
    events: list[str] = []
    ids = recover_into([drifted, tentative], [0, 1], boxes, matched, 0.4, ON, events, None)
    assert ids == {3} and matched == {1: 3}
    assert tentative.state is TrackState.DELETED
    assert events == ["tentative track 9 is track 3 recovered"]


def test_skip_still_leaves_a_still_track_out_of_the_round():
    # 4 s after its last detection the spread is 60 sqrt(0.05^2 + 1.2^2) = 72.06 px, so a
    # passer-by's detection 120 px (2 box heights) away is in the gate: d2 = 14400 / 5193
    dets = [np.array([220.0, 100.0, 30.0, 60.0])]
    still = _track(TrackState.CONFIRMED)
    still.is_still = lambda: True
    moving = _track(TrackState.CONFIRMED)
    moving.is_still = lambda: False
    uncapped = RecoveryConfig(enabled=True, min_similarity=0.0, still_max_age=0.0)
    skip = RecoveryConfig(enabled=True, min_similarity=0.0, skip_still=True,
                          still_max_age=0.0)
    assert recovery_round([still], dets, [None], 4.0, uncapped) == [(still, 0, None)]
    assert recovery_cost(np.array([still.detected_box]), [4.0], np.array(dets), ON)[0, 0] \
        == pytest.approx(14400.0 / (3600.0 * (0.05 ** 2 + 1.2 ** 2)))
    assert recovery_round([still], dets, [None], 4.0, skip) == []
    assert recovery_round([still, moving], dets, [None], 4.0, skip) == [(moving, 0, None)]


def test_still_max_age_caps_the_radius_of_a_still_track_only():
    # capped at 0.5 s, a still track's spread is that of the first cost test (spread^2 =
    # 90): the passer-by 120 px away is out (d2 = 160), its own detection 6, 8 px off is in
    passer_by = [np.array([220.0, 100.0, 30.0, 60.0])]
    own = [np.array([106.0, 108.0, 30.0, 60.0])]
    still = _track(TrackState.CONFIRMED)
    still.is_still = lambda: True
    moving = _track(TrackState.CONFIRMED)
    moving.is_still = lambda: False
    capped = RecoveryConfig(enabled=True, min_similarity=0.0, still_max_age=0.5)
    assert recovery_round([still], passer_by, [None], 4.0, capped) == []
    assert recovery_round([still], own, [None], 4.0, capped) == [(still, 0, None)]
    assert recovery_round([moving], passer_by, [None], 4.0, capped) == [(moving, 0, None)]
