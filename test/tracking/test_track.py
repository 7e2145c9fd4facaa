"""Track lifecycle transitions, quality-dependent measurement noise and smoothing."""

import numpy as np
import pytest

from mk_tracker.kalman import KalmanConfig
from mk_tracker.tracking.track import (LifecycleConfig, Track, TrackState, measurement_sigma,
                              next_state)

CFG = LifecycleConfig(min_hits=3, max_tentative_misses=1, max_coast_time=1.0,
                      max_lost_time=4.0)


def step(state, **kw):
    args = dict(detected=False, visible=False, in_image=True, hits=1, tentative_misses=0,
                unseen_time=0.0, lost_time=0.0, config=CFG)
    args.update(kw)
    return next_state(state, **args)


def test_tentative_needs_min_hits():
    assert step(TrackState.TENTATIVE, detected=True, hits=2) is TrackState.TENTATIVE
    assert step(TrackState.TENTATIVE, detected=True, hits=3) is TrackState.CONFIRMED


def test_tentative_deleted_after_misses():
    assert step(TrackState.TENTATIVE, tentative_misses=1) is TrackState.TENTATIVE
    assert step(TrackState.TENTATIVE, tentative_misses=2) is TrackState.DELETED


def test_confirmed_coasts_then_is_lost_then_deleted():
    assert step(TrackState.CONFIRMED, unseen_time=0.5) is TrackState.OCCLUDED
    assert step(TrackState.OCCLUDED, unseen_time=1.01) is TrackState.LOST
    assert step(TrackState.LOST, lost_time=3.9) is TrackState.LOST
    assert step(TrackState.LOST, lost_time=4.01) is TrackState.DELETED
    assert step(TrackState.DELETED, detected=True) is TrackState.DELETED


def test_visible_refinement_keeps_a_track_confirmed():
    assert step(TrackState.OCCLUDED, visible=True, unseen_time=0.0) is TrackState.CONFIRMED


def test_detection_reacquires_lost_track_and_leaving_loses_it():
    assert step(TrackState.LOST, detected=True, lost_time=2.0) is TrackState.CONFIRMED
    assert step(TrackState.CONFIRMED, visible=True, in_image=False) is TrackState.LOST


def test_measurement_sigma_follows_quality():
    cfg = LifecycleConfig(measurement_noise=0.04, min_noise_px=1.0, quality_floor=0.1)
    assert measurement_sigma(100.0, 1.0, cfg) == pytest.approx(4.0)
    assert measurement_sigma(100.0, 0.5, cfg) == pytest.approx(8.0)
    assert measurement_sigma(100.0, 0.0, cfg) == pytest.approx(40.0)
    assert measurement_sigma(10.0, 1.0, cfg) == pytest.approx(1.0)      # floor in px
    assert measurement_sigma(100.0, float("nan"), cfg) == pytest.approx(40.0)


def make_track():
    return Track(1, np.array([100.0, 100.0, 20.0, 50.0]), 0.0, score=1.0,
                 kalman=KalmanConfig(), config=LifecycleConfig(size_smoothing=0.3,
                                                               measurement_noise=0.04))


def test_poor_match_moves_the_track_less():
    good, poor = make_track(), make_track()
    for t in (good, poor):
        t.predict(1 / 30)
    meas = np.array([110.0, 100.0, 20.0, 50.0])        # centre 10 px to the right
    good.correct(meas, 1.0)
    poor.correct(meas, 0.2)
    assert good.center[0] > poor.center[0] > 110.0     # both move right, good moves more
    assert np.trace(good.kf.covariance) < np.trace(poor.kf.covariance)


def test_size_is_smoothed():
    t = make_track()
    t.correct(np.array([95.0, 90.0, 30.0, 70.0]), 1.0)   # size jumps from 20x50 to 30x70
    w, h = t.size
    assert 20.0 < w < 30.0 and 50.0 < h < 70.0
    assert w == pytest.approx(20.0 + 0.3 * 10.0)


def test_output_reports_age_and_time_since_detection():
    t = make_track()
    t.predict(0.5)
    out = t.output()
    assert out.age == pytest.approx(0.5)
    assert out.time_since_detection == pytest.approx(0.5)
    assert out.state == "tentative"
    assert out.box[2:] == (20.0, 50.0)


def test_refinement_alone_keeps_a_track_only_for_max_undetected_time():
    cfg = LifecycleConfig(max_undetected_time=1.5)
    kw = dict(detected=False, visible=True, in_image=True, hits=5, tentative_misses=0,
              unseen_time=0.0, lost_time=0.0, config=cfg)
    assert next_state(TrackState.CONFIRMED, undetected_time=1.4, **kw) is TrackState.CONFIRMED
    assert next_state(TrackState.CONFIRMED, undetected_time=1.6, **kw) is TrackState.LOST
    unlimited = dict(kw, config=LifecycleConfig(max_undetected_time=0.0))
    assert next_state(TrackState.CONFIRMED, undetected_time=99.0, **unlimited) is \
        TrackState.CONFIRMED


def test_a_visible_still_track_is_exempt_from_max_undetected_time():
    cfg = LifecycleConfig(max_undetected_time=1.5, max_coast_time=1.0)
    kw = dict(detected=False, in_image=True, hits=5, tentative_misses=0, lost_time=0.0,
              config=cfg, undetected_time=9.0)
    # standing still and still matched by the kernels: kept however long undetected
    assert next_state(TrackState.CONFIRMED, visible=True, unseen_time=0.0, still=True,
                      **kw) is TrackState.CONFIRMED
    # moving and undetected: the limit applies
    assert next_state(TrackState.CONFIRMED, visible=True, unseen_time=0.0, still=False,
                      **kw) is TrackState.LOST
    # still but the appearance says the person is gone: coasts, then lost by max_coast_time
    assert next_state(TrackState.CONFIRMED, visible=False, unseen_time=0.5, still=True,
                      **kw) is TrackState.LOST
    kw["undetected_time"] = 0.5
    assert next_state(TrackState.CONFIRMED, visible=False, unseen_time=0.5, still=True,
                      **kw) is TrackState.OCCLUDED
    assert next_state(TrackState.OCCLUDED, visible=False, unseen_time=1.2, still=True,
                      **kw) is TrackState.LOST


def test_an_unseen_track_holds_its_position_once_its_std_exceeds_the_bound():
    # box 20 px wide, centre (100, 100) at 50 px/s; initial position variance 4 (std 2 px)
    t = make_track()
    for k in range(1, 6):                              # walk right, measured every frame
        t.predict(k * 0.04)
        t.correct(np.array([90.0 + 2.0 * k, 75.0, 20.0, 50.0]), 1.0)
    assert t.position_std < 0.5 * 20.0
    assert not t.hold_if_uncertain(False, 0.5)         # unseen, but std below 10 px
    stamp = 0.2
    while t.position_std <= 0.5 * 20.0:                # coast until the std passes 10 px
        stamp += 0.04
        t.predict(stamp)
        assert not t.held
        t.hold_if_uncertain(False, 0.5)
    assert t.held and t.position_std == pytest.approx(
        np.sqrt(max(t.kf.covariance[0, 0], t.kf.covariance[1, 1])))
    centre, cov = t.center, t.kf.covariance
    t.predict(stamp + 1.0)                             # held: neither moves nor grows
    assert np.array_equal(t.center, centre) and np.array_equal(t.kf.covariance, cov)
    assert t.stamp == pytest.approx(stamp + 1.0)
    for _ in range(30):
        t.finish_frame()                               # the reported velocity decays to 0
    assert np.allclose(t.smoothed_velocity, 0.0, atol=1e-6)
    assert not t.hold_if_uncertain(True, 0.5)          # seen again: predicts again
    t.predict(stamp + 1.04)
    assert not np.array_equal(t.center, centre)


def test_a_zero_bound_never_holds():
    t = make_track()
    t.predict(100.0)                                   # std in the thousands of px
    assert not t.hold_if_uncertain(False, 0.0)


# -- OC-SORT's observation-centric re-update (Cao et al. 2023, Sec. 4.1) ----------------------

def _oru_track():
    life = LifecycleConfig(measurement_noise=1e-4, min_noise_px=1e-3)
    kal = KalmanConfig(sigma_u=30.0, initial_position_var=1e-6, initial_velocity_var=1e-6)
    t = Track(1, np.array([80.0, 60.0, 40.0, 80.0]), 0.0, score=1.0, kalman=kal, config=life)
    t.remember_seen()                                  # seen at centre (100, 100), v = 0
    return t


def test_reupdate_rewinds_to_the_last_seen_state_and_follows_the_line():
    # seen at x = 100 at t = 0 standing still; unseen for 1 s (10 frames of 0.1 s), then
    # detected at x = 200.  Virtual observations every 0.1 s on the line (nearly exact, std
    # 1e-3 px) make the filter move at (200 - 100) / 1 s = 100 px/s, ending at x = 190 at
    # t = 0.9 predicted to t = 1.0: x = 200.
    t = _oru_track()
    t.predict(1.0)
    assert t.kf.center[0] == pytest.approx(100.0)      # the coasting prediction stood still
    assert t.reupdate_from_last_seen(np.array([180.0, 60.0, 40.0, 80.0]), 1.0, 0.1)
    assert t.kf.velocity[0] == pytest.approx(100.0, rel=0.02)
    assert t.kf.velocity[1] == pytest.approx(0.0, abs=0.5)
    assert t.kf.center[0] == pytest.approx(200.0, abs=1.0)


def test_reupdate_needs_a_gap_of_more_than_one_and_a_half_frames():
    t = _oru_track()
    t.predict(0.15)
    assert not t.reupdate_from_last_seen(np.array([90.0, 60.0, 40.0, 80.0]), 0.15, 0.1)
    assert t.kf.center[0] == pytest.approx(100.0)
    assert not _oru_track().reupdate_from_last_seen(np.array([90.0, 60.0, 40.0, 80.0]),
                                                      1.0, 0.0)


def test_tracker_reupdates_after_a_gap_only_when_enabled():
    import dataclasses

    from mk_tracker.tracking.multi_object_tracker import (FrameDetection, MultiObjectTracker,
                                                          MultiObjectTrackerConfig)
    img = np.zeros((480, 640, 3), np.uint8)
    velocities = []
    for on in (False, True):
        cfg = MultiObjectTrackerConfig(use_multi_kernel=False)
        cfg = dataclasses.replace(cfg, lifecycle=dataclasses.replace(
            cfg.lifecycle, observation_centric_reupdate=on))
        trk = MultiObjectTracker(cfg)
        for i in range(5):                       # standing at x = 100 for 5 frames of 0.1 s
            trk.step(img, 0.1 * i, [FrameDetection((80.0, 60.0, 40.0, 80.0), 0.9)])
        for i in range(5, 9):                    # unseen for 4 frames
            trk.step(img, 0.1 * i, [])
        res = trk.step(img, 0.9, [FrameDetection((100.0, 60.0, 40.0, 80.0), 0.9)])
        assert [t.id for t in res.tracks] == [1]      # the same track took the detection
        velocities.append(res.tracks[0].velocity[0])
    # re-update: the virtual path is 20 px in 0.5 s = 40 px/s (a little less: the filter
    # starts from v = 0, the measurement std is 1.6 px, the last correction adds its own); the
    # reported velocity is smoothed with weight 0.5 from about 0: about 20.  Without it one
    # correction of the standing prediction gives another value.
    assert 18.0 < velocities[1] < 22.0
    assert abs(velocities[1] - velocities[0]) > 0.5
