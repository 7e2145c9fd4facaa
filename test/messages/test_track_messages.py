"""mk_tracker.messages.track_messages: the tracker's live tracks -> TrackedObjectArray, and
the tracker-side values it publishes (Kalman covariances of TrackOutput, stop_track)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mk_tracker.frame_processing import tracks_to_detections
from mk_tracker.kalman import KalmanConfig
from mk_tracker.messages.detection_messages import Detection
from mk_tracker.messages.track_messages import (STATE_CODES, duration_fields,
                                                make_tracked_object_array,
                                                ros_track_message_types, tracked_objects)
from mk_tracker.tracking.multi_object_tracker import (FrameDetection, MultiObjectTracker,
                                                      MultiObjectTrackerConfig)
from mk_tracker.tracking.track import LifecycleConfig, Track, TrackOutput


def _output(**overrides) -> TrackOutput:
    values = dict(id=7, state="occluded", box=(10.0, 20.0, 30.0, 60.0), score=1.3,
                  velocity=(12.5, -4.0), age=2.25, time_since_detection=0.5, hits=9,
                  manual=False, velocity_covariance=(40.0, 1.5, 1.5, 30.0),
                  position_covariance=(9.0, 0.25, 0.25, 16.0))
    values.update(overrides)
    return TrackOutput(**values)


def test_duration_fields_split_seconds_into_sec_and_nanosec():
    assert duration_fields(0.0) == (0, 0)
    assert duration_fields(2.25) == (2, 250_000_000)
    assert duration_fields(1e-9) == (0, 1)
    # negative: nanosec stays in [0, 1e9) as builtin_interfaces/Duration requires
    assert duration_fields(-0.25) == (-1, 750_000_000)
    with pytest.raises(ValueError, match="not finite"):
        duration_fields(math.nan)


def test_state_codes_are_the_message_constants():
    t = ros_track_message_types().TrackedObject
    assert STATE_CODES == {"tentative": t.TENTATIVE, "confirmed": t.CONFIRMED,
                           "occluded": t.OCCLUDED, "lost": t.LOST}


def test_one_track_becomes_its_fields():
    [f] = tracked_objects([_output()], "person", [7])
    assert f.detection == Detection((10.0, 20.0, 30.0, 60.0), 1.0, "person", "7")
    assert f.state == 2
    assert f.velocity == (12.5, -4.0)
    assert f.velocity_covariance == (40.0, 1.5, 1.5, 30.0)
    assert f.position_covariance == (9.0, 0.25, 0.25, 16.0)
    assert f.age == (2, 250_000_000)
    assert f.time_since_detected == (0, 500_000_000)
    assert f.hits == 9
    assert f.started_by_hand is False
    assert f.published is True
    # not among the ids on `tracks` this frame: not published
    assert tracked_objects([_output()], "person", [6, 8])[0].published is False


def test_every_state_is_published_but_deleted_and_non_finite_tracks_are_not():
    tracks = [_output(id=1, state="tentative"), _output(id=2, state="confirmed"),
              _output(id=3, state="occluded"), _output(id=4, state="lost"),
              _output(id=5, state="deleted"),
              _output(id=6, box=(math.nan, 0.0, 10.0, 10.0)),
              _output(id=8, velocity=(math.inf, 0.0)),
              _output(id=9, velocity_covariance=(math.nan, 0.0, 0.0, 1.0))]
    out = tracked_objects(tracks, "person", [2, 3])
    assert [(f.detection.id, f.state, f.published) for f in out] == [
        ("1", 0, False), ("2", 1, True), ("3", 2, True), ("4", 3, False)]


def test_the_detection_is_the_one_tracks_publishes():
    tracks = [_output(id=3, state="confirmed", score=0.42),
              _output(id=4, state="occluded", score=-0.1, manual=True)]
    assert [f.detection for f in tracked_objects(tracks, "pedestrian", [3, 4])] == \
        tracks_to_detections(tracks, "pedestrian")


def test_track_output_carries_the_kalman_covariance_blocks():
    kalman = KalmanConfig(sigma_u=30.0, sigma_w=2.0, initial_position_var=4.0,
                          initial_velocity_var=2500.0)
    track = Track(1, np.array([100.0, 50.0, 20.0, 40.0]), 0.0, score=0.9, kalman=kalman,
                  config=LifecycleConfig())
    out = track.output()
    assert out.position_covariance == (4.0, 0.0, 0.0, 4.0)
    assert out.velocity_covariance == (2500.0, 0.0, 0.0, 2500.0)
    track.predict(0.5)
    out = track.output()
    # P = A P A^T + Sigma_u (4.3), dt = 0.5, sigma_u^2 = 900:
    # velocity: 2500 + 900 * 0.5; position: 4 + 0.25 * 2500 + 900 * 0.125 / 3
    assert out.velocity_covariance == pytest.approx((2950.0, 0.0, 0.0, 2950.0))
    assert out.position_covariance == pytest.approx((666.5, 0.0, 0.0, 666.5))
    assert out.age == 0.5 and out.time_since_detection == 0.5


def test_message_array_holds_the_fields_and_the_header():
    from mk_tracker.messages.message_types import ros_message_types
    types = ros_message_types()
    header = types.Header(stamp=types.Time(sec=5, nanosec=6), frame_id="rgb")
    fields = tracked_objects([_output(manual=True), _output(id=8, state="tentative")],
                             "person", [7])
    msg = make_tracked_object_array(fields, header, types, ros_track_message_types())
    assert msg.header.frame_id == "rgb" and msg.header.stamp.sec == 5
    first, second = msg.tracks
    assert first.detection.id == "7" and first.detection.header.frame_id == "rgb"
    assert (first.detection.bbox.center.position.x, first.detection.bbox.center.position.y,
            first.detection.bbox.size_x, first.detection.bbox.size_y) == (25.0, 50.0, 30.0,
                                                                          60.0)
    assert first.detection.results[0].hypothesis.score == 1.0
    assert first.state == first.OCCLUDED and second.state == second.TENTATIVE
    assert (first.velocity_x, first.velocity_y) == (12.5, -4.0)
    assert list(first.velocity_covariance) == [40.0, 1.5, 1.5, 30.0]
    assert list(first.position_covariance) == [9.0, 0.25, 0.25, 16.0]
    assert (first.age.sec, first.age.nanosec) == (2, 250_000_000)
    assert (first.time_since_detected.sec, first.time_since_detected.nanosec) == \
        (0, 500_000_000)
    assert first.hits == 9 and first.started_by_hand and not second.started_by_hand
    assert first.published and not second.published


# -- the tracker side ---------------------------------------------------------------------------

def _textured(seed: int = 3) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 255, (240, 320, 3), dtype=np.uint8)


def test_tentative_tracks_reach_the_detailed_output_but_not_tracks():
    tracker = MultiObjectTracker(MultiObjectTrackerConfig(use_multi_kernel=False))
    result = tracker.step(_textured(), 0.0, [FrameDetection((50, 60, 20, 40), 0.9)])
    assert result.reported() == []
    [f] = tracked_objects(result.tracks, "person", (t.id for t in result.reported()))
    assert f.state == STATE_CODES["tentative"] and not f.published
    assert f.hits == 1 and f.age == (0, 0) and not f.started_by_hand


def test_stop_track_removes_a_live_track_and_refuses_an_unknown_id():
    tracker = MultiObjectTracker(MultiObjectTrackerConfig(use_multi_kernel=False))
    image = _textured()
    kept = tracker.start_track(image, 0.0, (40, 40, 30, 60))
    stopped = tracker.start_track(image, 0.0, (200, 100, 30, 60))
    assert tracker.stop_track(stopped) is True
    assert tracker.stop_track(stopped) is False          # already gone
    assert tracker.stop_track(12345) is False
    result = tracker.step(image, 0.04)
    assert [t.id for t in result.tracks] == [kept]
    assert [(f.started_by_hand, f.published) for f in tracked_objects(
        result.tracks, "person", (t.id for t in result.reported()))] == [(True, True)]
    # ids are never reused
    assert tracker.start_track(image, 0.08, (200, 100, 30, 60)) > stopped
