"""Which tracks FrameResult.reported() gives out: the coasting bounds in time and in the
centre's uncertainty relative to the box (``max_reported_coast_std``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mk_tracker.parameters import updated
from mk_tracker.tracking.multi_object_tracker import (FrameDetection, FrameResult,
                                                      MultiObjectTracker,
                                                      MultiObjectTrackerConfig,
                                                      coast_position_std)
from mk_tracker.tracking.track import TrackOutput

IMG = np.zeros((480, 640, 3), np.uint8)
DT = 1.0 / 25.0


def output(track_id, state, box, pxx, pyy, since=0.1, manual=False) -> TrackOutput:
    return TrackOutput(id=track_id, state=state, box=box, score=0.0, velocity=(0.0, 0.0),
                       age=1.0, time_since_detection=since, hits=5, manual=manual,
                       position_covariance=(pxx, 0.0, 0.0, pyy))


def test_coast_position_std_is_the_larger_of_the_std_per_box_side():
    # sqrt(9) / 30 = 0.1 against sqrt(16) / 80 = 0.05
    assert coast_position_std(output(1, "occluded", (0, 0, 30, 80), 9.0, 16.0)) \
        == pytest.approx(0.1)
    # sqrt(1) / 30 = 0.033 against sqrt(64) / 40 = 0.2
    assert coast_position_std(output(1, "occluded", (0, 0, 30, 40), 1.0, 64.0)) \
        == pytest.approx(0.2)
    assert coast_position_std(output(1, "occluded", (0, 0, 0, 40), 1.0, 1.0)) == math.inf


def test_reported_drops_only_coasting_tracks_above_the_bound():
    tracks = [output(1, "occluded", (0, 0, 30, 80), 9.0, 16.0),       # 0.10: kept
              output(2, "occluded", (0, 0, 30, 40), 1.0, 64.0),       # 0.20: dropped
              output(3, "confirmed", (0, 0, 30, 40), 400.0, 400.0),   # seen: kept
              output(4, "occluded", (0, 0, 30, 40), 1.0, 64.0, manual=True),  # by hand
              output(5, "occluded", (0, 0, 30, 80), 9.0, 16.0, since=0.5),    # too long
              output(6, "lost", (0, 0, 30, 80), 0.0, 0.0)]
    result = FrameResult(stamp=1.0, tracks=tracks, max_reported_coast_time=0.3,
                         max_reported_coast_std=0.15)
    assert [t.id for t in result.reported()] == [1, 3, 4]
    # 0 = no bound on the uncertainty: the time bound alone
    result.max_reported_coast_std = 0.0
    assert [t.id for t in result.reported()] == [1, 2, 3, 4]


def _coasting_frames(limit: float, size: tuple[float, float]) -> list[tuple[bool, float]]:
    """A person walking right at 100 px/s, detected for 20 frames, then never again; per
    coasting frame (reported?, the std per box side computed here from the output)."""
    trk = MultiObjectTracker(updated(MultiObjectTrackerConfig(), {
        "use_multi_kernel": False, "max_reported_coast_time": 10.0,
        "lifecycle.max_coast_time": 10.0, "lifecycle.max_undetected_time": 0.0,
        "max_reported_coast_std": limit}))
    w, h = size
    for i in range(20):
        trk.step(IMG, i * DT, [FrameDetection((100 + 4.0 * i, 200, w, h), 0.9)])
    frames = []
    for i in range(20, 60):
        r = trk.step(IMG, i * DT, [])
        (t,) = r.tracks
        assert t.state == "occluded"
        pxx, _, _, pyy = t.position_covariance
        std = max(math.sqrt(pxx) / t.box[2], math.sqrt(pyy) / t.box[3])
        frames.append((t.id in {u.id for u in r.reported()}, std))
    return frames


def test_a_coasting_track_is_reported_while_its_centre_is_certain_to_the_bound():
    frames = _coasting_frames(0.1, (30.0, 60.0))
    reported = [rep for rep, _ in frames]
    # the uncertainty grows while coasting (4.3), so the reported frames come first
    assert reported[0] and not reported[-1]
    assert reported == sorted(reported, reverse=True)
    for rep, std in frames:
        assert rep == (std <= 0.1)
    # without the bound the same track is reported in every coasting frame (time bound 10 s)
    assert all(rep for rep, _ in _coasting_frames(0.0, (30.0, 60.0)))


def test_a_small_person_stops_being_reported_sooner():
    """The same motion and Kalman uncertainty in px: a box a third as large loses the
    overlap it needs three times sooner in px, so it is dropped after fewer frames."""
    small = sum(rep for rep, _ in _coasting_frames(0.1, (20.0, 40.0)))
    large = sum(rep for rep, _ in _coasting_frames(0.1, (60.0, 120.0)))
    assert 0 < small < large < 40


def test_a_coasting_track_of_unknown_uncertainty_is_not_reported():
    """A non-finite covariance says nothing about where the person is: no crash, and the
    coasting box is left out (a confirmed one is still reported)."""
    tracks = [output(1, "occluded", (0, 0, 30, 80), math.nan, 16.0),
              output(2, "occluded", (0, 0, 30, 80), math.inf, 16.0),
              output(3, "confirmed", (0, 0, 30, 80), math.nan, math.nan)]
    result = FrameResult(stamp=1.0, tracks=tracks, max_reported_coast_time=1.0,
                         max_reported_coast_std=0.15)
    assert [t.id for t in result.reported()] == [3]


def _matched(track_id, state, last_match_iou, manual=False) -> TrackOutput:
    return TrackOutput(id=track_id, state=state, box=(0, 0, 30, 80), score=0.0,
                       velocity=(0.0, 0.0), age=1.0, time_since_detection=0.1, hits=5,
                       manual=manual, position_covariance=(1.0, 0.0, 0.0, 1.0),
                       last_match_iou=last_match_iou)


def test_reported_drops_coasting_tracks_whose_prediction_missed_the_last_detection():
    tracks = [_matched(1, "occluded", 0.8),              # met it: kept
              _matched(2, "occluded", 0.4),              # missed it: dropped
              _matched(3, "occluded", 0.5),              # at the bound: kept
              _matched(4, "confirmed", 0.1),             # detected or seen: kept
              _matched(5, "occluded", 0.1, manual=True),  # by hand: kept
              _matched(6, "occluded", math.nan)]         # unknown: dropped
    result = FrameResult(stamp=1.0, tracks=tracks, max_reported_coast_time=0.3,
                         min_reported_coast_match_iou=0.5)
    assert [t.id for t in result.reported()] == [1, 3, 4, 5]
    # 0 = no such bound
    result.min_reported_coast_match_iou = 0.0
    assert [t.id for t in result.reported()] == [1, 2, 3, 4, 5, 6]


def _standing_then_jump(jump_px: float, bound: float) -> list[tuple[float, bool]]:
    """A person standing still at (100, 200, 30, 60) for 10 frames, then one detection
    ``jump_px`` to the right, then none; per frame after the jump (match IoU, reported?).
    The gate is opened wide so that the jumped detection is still assigned to the track."""
    trk = MultiObjectTracker(updated(MultiObjectTrackerConfig(), {
        "use_multi_kernel": False, "association.gate": 1e4, "max_reported_coast_time": 10.0,
        "max_reported_coast_std": 0.0, "lifecycle.max_coast_time": 10.0,
        "lifecycle.max_undetected_time": 0.0, "min_reported_coast_match_iou": bound}))
    for i in range(10):
        trk.step(IMG, i * DT, [FrameDetection((100, 200, 30, 60), 0.9)])
    out = []
    for i in range(10, 14):
        dets = [FrameDetection((100 + jump_px, 200, 30, 60), 0.9)] if i == 10 else []
        r = trk.step(IMG, i * DT, dets)
        (t,) = r.tracks
        out.append((t.last_match_iou, t.id in {u.id for u in r.reported()}))
    return out


def test_the_match_iou_is_the_prediction_against_the_detection_before_the_update():
    # the same box ten times: velocity 0, the prediction is that box, IoU 1
    # a 10 px jump of a 30 x 60 box: overlap 20 x 60 = 1200 of 1800 + 1800 - 1200 -> 0.5
    # a 20 px jump: 10 x 60 = 600 of 3000 -> 0.2
    for jump, expected in ((0.0, 1.0), (10.0, 0.5), (20.0, 0.2)):
        frames = _standing_then_jump(jump, 0.0)
        assert all(m == pytest.approx(expected) for m, _ in frames), (jump, frames)
        assert all(rep for _, rep in frames)      # no bound: detected, then coasting


def test_a_coasting_track_whose_last_detection_jumped_is_not_reported():
    frames = _standing_then_jump(20.0, 0.5)       # match IoU 0.2 < 0.5
    assert frames[0][1]                           # detected in that frame: reported
    assert not any(rep for _, rep in frames[1:])  # coasting after it: left out
    frames = _standing_then_jump(10.0, 0.5)       # 0.5: at the bound, reported
    assert all(rep for _, rep in frames)


def test_a_group_measurement_leaves_the_match_iou_alone():
    """Two people standing side by side at x = 100 and 140 (30 x 60), then one detection
    (105, 200, 60, 60) around both (a group measurement, group_measurement.py: 25 of each
    one's 30 px inside it, twice their area).  A member's measurement is its own predicted
    box moved inside the group box, derived from the prediction, not an observation of it,
    so the match IoU stays that of the last own detection (1: standing still, predicted
    exactly); recorded, the 5 px move would give 25 x 60 / (3600 - 1500) = 0.714."""
    trk = MultiObjectTracker(updated(MultiObjectTrackerConfig(), {"use_multi_kernel": False}))
    for i in range(10):
        r = trk.step(IMG, i * DT, [FrameDetection((100, 200, 30, 60), 0.9),
                                   FrameDetection((140, 200, 30, 60), 0.9)])
    assert sorted(t.state for t in r.tracks) == ["confirmed", "confirmed"]
    r = trk.step(IMG, 10 * DT, [FrameDetection((105, 200, 60, 60), 0.9)])
    assert trk.totals["group_measurements"] == 1
    assert len(r.tracks) == 2
    assert all(t.last_match_iou == pytest.approx(1.0) for t in r.tracks)


def test_reporting_bounds_do_not_change_tracking():
    """benchmarks/coast_rule_grid.py replays the reporting bounds on kept results: that is
    exact only while no bound feeds back into tracking.  Two people crossing with misses:
    the same tracks every frame, different reported sets."""
    bounds = [{"max_reported_coast_time": 10.0, "max_reported_coast_std": 0.0},
              {"max_reported_coast_time": 0.1, "max_reported_coast_std": 0.05,
               "min_reported_coast_match_iou": 0.9}]
    trackers = [MultiObjectTracker(updated(MultiObjectTrackerConfig(), {
        "use_multi_kernel": False, **b})) for b in bounds]
    rng = np.random.default_rng(5)
    differ = 0
    for i in range(60):
        dets = [FrameDetection((100 + 5.0 * i + rng.normal(0, 2), 200, 30, 60), 0.9),
                FrameDetection((400 - 5.0 * i + rng.normal(0, 2), 210, 30, 60), 0.5)]
        dets = [d for k, d in enumerate(dets) if not (20 <= i < 30 and k == 0)
                and not (35 <= i < 45 and k == 1)]
        a, b = (t.step(IMG, i * DT, dets) for t in trackers)
        assert a.tracks == b.tracks
        differ += [t.id for t in a.reported()] != [t.id for t in b.reported()]
    assert differ > 0
