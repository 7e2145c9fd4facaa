"""Duplicate tracks (issues #15, #19): two tracks stacked on one person, never detected as two,
become one; the older id stays and takes the better-supported estimate."""

from __future__ import annotations

import numpy as np
import pytest

from mk_tracker.messages.track_messages import STATE_CODES, tracked_objects
from mk_tracker.kalman import KalmanConfig
from mk_tracker.parameters import ParameterError, updated, validate_config
from mk_tracker.tracking.duplicate_tracks import (DuplicateConfig, due_pairs, merge_into,
                                                  publish_one_of_each, published_of_pair,
                                                  stacked_pairs, survivor,
                                                  update_stacked_since)
from mk_tracker.tracking.multi_object_tracker import (FrameDetection, MultiObjectTracker,
                                                      MultiObjectTrackerConfig)
from mk_tracker.tracking.track import LifecycleConfig, Track

from fake_refiners import LabelRefiner

IMG = np.zeros((480, 640, 3), np.uint8)
DT = 1.0 / 25.0


# -- pure functions ---------------------------------------------------------------------------

def test_stacked_pairs_are_keyed_by_ordered_ids_with_their_iou():
    # IoU by hand: (0,0,10,10)-(2,0,10,10): 80 / 120; (2,0)-(5,0): 70 / 130;
    # (0,0)-(5,0): 50 / 150 = 1/3, below 0.5
    pairs = stacked_pairs([7, 3, 9], [(0, 0, 10, 10), (2, 0, 10, 10), (5, 0, 10, 10)], 0.5)
    assert pairs.keys() == {(3, 7), (3, 9)}
    assert pairs[(3, 7)] == pytest.approx(80 / 120)
    assert pairs[(3, 9)] == pytest.approx(70 / 130)
    assert stacked_pairs([1], [(0, 0, 10, 10)], 0.0) == {}
    with pytest.raises(ValueError, match="2 ids for 1 boxes"):
        stacked_pairs([1, 2], [(0, 0, 10, 10)], 0.5)


def test_the_clock_of_a_pair_runs_while_stacked_and_restarts_when_seen_apart():
    since = {(1, 2): 1.0, (3, 4): 2.0, (7, 8): 0.5}
    out = update_stacked_since(since, stacked=[(2, 1), (5, 6), (3, 4)], detected_apart=[(4, 3)],
                               stamp=3.0)
    # (1, 2) keeps its start; (5, 6) starts now; (3, 4) was seen as two people; (7, 8) is
    # no longer stacked
    assert out == {(1, 2): 1.0, (5, 6): 3.0}


def test_due_pairs_are_those_stacked_long_enough_longest_first():
    since = {(5, 6): 3.0, (1, 2): 1.0, (3, 4): 2.0}
    assert due_pairs(since, 3.5, 0.5) == [(1, 2), (3, 4), (5, 6)]   # 2.5, 1.5, 0.5 s
    assert due_pairs(since, 3.5, 0.75) == [(1, 2), (3, 4)]
    assert due_pairs(since, 3.5, 3.0) == []
    assert due_pairs({(4, 9): 1.0, (2, 3): 1.0}, 2.0, 0.5) == [(2, 3), (4, 9)]   # tie: ids


def test_the_older_track_survives():
    assert survivor(1.0, 5, 2.0, 3) == 5
    assert survivor(2.0, 5, 1.0, 3) == 3
    assert survivor(1.0, 5, 1.0, 3) == 3            # same age: the id given first


def _track(tid, box, stamp):
    return Track(tid, np.array(box, float), stamp, score=0.9, kalman=KalmanConfig(),
                 config=LifecycleConfig())


def test_merge_takes_the_estimate_of_the_more_recently_detected_track():
    keep = _track(1, (100, 100, 30, 60), 0.0)        # centre (115, 130)
    gone = _track(2, (110, 104, 20, 50), 0.5)        # centre (120, 129)
    keep.hits, gone.hits = 12, 4
    keep.last_detection, gone.last_detection = 1.0, 2.0
    keep.last_seen, gone.last_seen = 1.5, 2.0
    merge_into(keep, gone)
    assert keep.id == 1 and keep.created == 0.0
    assert tuple(keep.center) == pytest.approx((120.0, 129.0))
    assert tuple(keep.size) == pytest.approx((20.0, 50.0))
    assert keep.kf is not gone.kf                    # a copy: the gone track keeps its own
    assert (keep.hits, keep.last_detection, keep.last_seen) == (12, 2.0, 2.0)
    # and its last detected box (re-acquisition gates on it, tracking/reacquisition.py)
    assert tuple(keep.detected_box) == (110.0, 104.0, 20.0, 50.0)

    # the surviving track was detected last: its own estimate stays
    keep = _track(1, (100, 100, 30, 60), 0.0)
    gone = _track(2, (110, 104, 20, 50), 0.5)
    keep.last_detection, gone.last_detection = 2.0, 1.0
    keep.hits, gone.hits = 3, 9
    merge_into(keep, gone)
    assert tuple(keep.center) == pytest.approx((115.0, 130.0))
    assert tuple(keep.size) == pytest.approx((30.0, 60.0))
    assert tuple(keep.detected_box) == (100.0, 100.0, 30.0, 60.0)
    assert keep.hits == 9


def test_every_constant_is_a_validated_parameter():
    cfg = MultiObjectTrackerConfig()
    assert cfg.duplicates == DuplicateConfig()
    with pytest.raises(ParameterError):
        validate_config(updated(cfg, {"duplicates.min_iou": 1.5}))
    with pytest.raises(ParameterError):
        validate_config(updated(cfg, {"duplicates.min_time": -0.1}))


# -- in the tracker ---------------------------------------------------------------------------

def config(**changes) -> MultiObjectTrackerConfig:
    """Defaults with ``changes``; a coasting track stays reported for 1 s, whatever its
    uncertainty (the default 0.2 s and ``max_reported_coast_std`` would hide the undetected
    duplicate from ``reported()`` before the rule acts)."""
    return updated(MultiObjectTrackerConfig(), {"max_reported_coast_time": 1.0,
                                                "max_reported_coast_std": 0.0, **changes})


def _one_person_two_tracks(trk, frames_after=12):
    """Person B walks in from x = 140 (track born first) towards person A at x = 100 (born
    second), 1 px a frame, both detected, B's last detection at x = 111 (IoU 19/41, not
    stacked); then the detector reports only A's box, and B's track coasts on onto it:
    stacked (IoU > 0.5) from the second frame after (x = 109, IoU 21/39).  Returns (id of
    B, id of A, the results from the frame B's detections stop)."""
    a, b = (100, 100, 30, 60), lambda i: (140 - i, 100, 30, 60)
    for i in range(30):
        dets = [FrameDetection(b(i), 0.9)] + ([FrameDetection(a, 0.9)] if i >= 2 else [])
        r = trk.step(IMG, i * DT, dets)
        if i >= 16:     # two people, detected as two: never merged
            assert len(r.reported()) == 2, (i, r.events)
    by_x = sorted(r.reported(), key=lambda t: t.box[0])
    id_a, id_b = by_x[0].id, by_x[1].id
    assert id_b < id_a
    out = [trk.step(IMG, i * DT, [FrameDetection(a, 0.9)])
           for i in range(30, 30 + frames_after)]
    return id_b, id_a, out


def test_two_tracks_stacked_on_one_detection_become_the_older_one():
    cfg = config(**{"use_multi_kernel": False, "duplicates.min_similarity": 0.0,
                    "duplicates.report_one": "none"})      # both reported while waiting
    id_b, id_a, out = _one_person_two_tracks(MultiObjectTracker(cfg))
    # stacked from out[1]; 0.3 s of stacking at 25 fps: still two tracks up to 0.28 s
    # later (out[8]), one from 0.32 s on (out[9]: 8 intervals of 0.04 s after out[1])
    for r in out[:8]:
        assert {t.id for t in r.reported()} == {id_a, id_b}
    merged = [k for k, r in enumerate(out) if any("merged" in e for e in r.events)]
    assert merged == [9], [r.events for r in out]
    assert f"track {id_a} merged into track {id_b}" in out[9].events[0]
    for r in out[9:]:
        (t,) = r.reported()
        assert t.id == id_b
        # the survivor took the estimate of the detected track: on A's box
        assert t.box[0] + t.box[2] / 2 == pytest.approx(115.0, abs=1.5)


def test_without_the_rule_the_undetected_duplicate_stays():
    cfg = config(**{"use_multi_kernel": False, "duplicates.enabled": False})
    id_b, id_a, out = _one_person_two_tracks(MultiObjectTracker(cfg))
    for r in out:
        assert {t.id for t in r.reported()} == {id_a, id_b}


@pytest.mark.parametrize("same_look", [True, False])
def test_the_appearance_of_both_tracks_must_match_for_a_merge(same_look):
    cfg = config(**{"duplicates.min_similarity": 0.3})
    labels = {100.0: "grey"} if same_look else {100.0: "red", 104.0: "blue"}
    trk = MultiObjectTracker(cfg, refiner=LabelRefiner(labels))
    id_b, id_a, out = _one_person_two_tracks(trk)
    ids = {t.id for t in out[-1].reported()}
    # two people who look different and occlude each other keep both ids
    assert ids == ({id_b} if same_look else {id_a, id_b})
    assert trk.totals["merged_duplicates"] == (1 if same_look else 0)


def test_no_refiner_and_an_appearance_test_merges_nothing():
    cfg = config(use_multi_kernel=False)
    assert cfg.duplicates.min_similarity > 0.0
    id_b, id_a, out = _one_person_two_tracks(MultiObjectTracker(cfg))
    assert {t.id for t in out[-1].reported()} == {id_a, id_b}


def test_tracks_started_by_hand_are_never_merged():
    cfg = config(**{"use_multi_kernel": False, "duplicates.min_similarity": 0.0})
    trk = MultiObjectTracker(cfg)
    manual = trk.start_track(IMG, 0.0, (104, 100, 30, 60))
    for i in range(1, 60):          # a detected person walks onto the hand-started box
        r = trk.step(IMG, i * DT, [FrameDetection((max(140 - 2 * i, 100), 100, 30, 60), 0.9)])
    ids = {t.id for t in r.reported()}
    assert manual in ids and len(ids) == 2
    assert trk.totals["merged_duplicates"] == 0


# -- a pair waiting for min_time is published as one (duplicates.report_one) -------------------

class _T:
    def __init__(self, tid, created, last_detection):
        self.id, self.created, self.last_detection = tid, created, last_detection


@pytest.mark.parametrize("mode, expected", [
    ("survivor", (3, 8, 3)),          # the older track keeps its id and its own box
    ("detected", (8, 3, 8)),          # the one detected last, with its box
    ("merged", (3, 8, 8)),            # older id, box of the one detected last (merge_into)
])
def test_published_of_pair_by_mode(mode, expected):
    old, young = _T(3, 1.0, 2.0), _T(8, 1.5, 2.5)      # the younger was detected last
    for a, b in ((old, young), (young, old)):            # the order of the pair is irrelevant
        shown, hidden, box_from = published_of_pair(a, b, mode)
        assert (shown.id, hidden.id, box_from.id) == expected
    assert published_of_pair(old, young, "none") is None
    # the survivor detected last: every mode shows it with its own box
    recent_old = _T(3, 1.0, 3.0)
    for mode in ("survivor", "detected", "merged"):
        shown, hidden, box_from = published_of_pair(young, recent_old, mode)
        assert (shown.id, hidden.id, box_from.id) == (3, 8, 3)
    with pytest.raises(ValueError, match="unknown"):
        published_of_pair(old, young, "both")


def test_publish_one_of_each_pair_hides_one_track_per_waiting_pair():
    def t(tid, created, last, state="confirmed"):
        u = _T(tid, created, last)
        u.state, u.box = state, (tid * 10.0, 0.0, 5.0, 10.0)
        return u
    tracks = {1: t(1, 0.0, 1.0), 2: t(2, 0.5, 2.0), 3: t(3, 0.7, 1.5), 4: t(4, 0.1, 0.9),
              5: t(5, 0.2, 3.0, "deleted"), 6: t(6, 0.3, 1.0), 7: t(7, 0.4, 1.2)}
    pairs = [(1, 2), (2, 3), (4, 5), (6, 7)]
    alike = lambda a, b: (a.id, b.id) != (6, 7)        # noqa: E731  6 and 7: two people
    hidden, boxes = publish_one_of_each(pairs, tracks, alike, "merged")
    # (1, 2): 1 shown with 2's box (2 detected last), 2 hidden; (2, 3): 2 is hidden already,
    # so 3 stays; (4, 5): 5 was merged away this frame; (6, 7): they look different
    assert hidden == {2}
    assert boxes.keys() == {1} and tuple(boxes[1]) == (20.0, 0.0, 5.0, 10.0)
    hidden, boxes = publish_one_of_each(pairs, tracks, alike, "detected")
    # (1, 2): 2 (detected at 2.0) shown, 1 hidden; (2, 3): 2 again, detected after 3 (1.5)
    assert hidden == {1, 3} and boxes == {}
    assert publish_one_of_each(pairs, tracks, alike, "none") == (set(), {})


def test_report_one_is_a_validated_choice():
    with pytest.raises(ParameterError):
        validate_config(updated(MultiObjectTrackerConfig(), {"duplicates.report_one": "all"}))


@pytest.mark.parametrize("mode", ["survivor", "detected", "merged"])
def test_a_waiting_pair_is_reported_once_until_it_is_merged(mode):
    cfg = config(**{"use_multi_kernel": False, "duplicates.min_similarity": 0.0,
                    "duplicates.report_one": mode})
    id_b, id_a, out = _one_person_two_tracks(MultiObjectTracker(cfg))
    # while both were detected both were reported (asserted in the helper), and in the
    # first frame with A's box alone (not stacked yet); then the pair waits 8 frames,
    # reported as one track
    assert len(out[0].reported()) == 2 and not out[0].suppressed_ids
    for r in out[1:9]:
        (t,) = r.reported()
        assert {o.id for o in r.tracks} >= {id_a, id_b}        # both are still tracked
        assert r.suppressed_ids == {id_a, id_b} - {t.id}
        # A (the younger, id_a) is detected: "detected" shows it; the others the older id
        assert t.id == (id_a if mode == "detected" else id_b)
        centre = t.box[0] + t.box[2] / 2
        if mode == "survivor":       # B's own box, coasting left from x = 109 (centre 124)
            assert centre > 116.5
        else:                        # A's box, centred at 100 + 15 = 115
            assert centre == pytest.approx(115.0, abs=0.5)
    assert any("merged" in e for e in out[9].events)
    for r in out[9:]:
        (t,) = r.reported()
        assert t.id == id_b and not r.suppressed_ids


def test_two_people_who_look_different_are_both_reported_while_stacked():
    cfg = config(**{"duplicates.min_similarity": 0.3, "duplicates.report_one": "merged"})
    trk = MultiObjectTracker(cfg, refiner=LabelRefiner({100.0: "red", 104.0: "blue"}))
    id_b, id_a, out = _one_person_two_tracks(trk)
    for r in out:
        assert {t.id for t in r.reported()} == {id_a, id_b} and not r.suppressed_ids


def test_the_hidden_track_is_reported_again_once_both_are_detected():
    cfg = config(**{"use_multi_kernel": False, "duplicates.min_similarity": 0.0,
                    "duplicates.min_time": 10.0})                # never merged here
    trk = MultiObjectTracker(cfg)
    id_b, id_a, out = _one_person_two_tracks(trk, frames_after=4)
    assert cfg.duplicates.report_one == "detected"               # the default
    assert len(out[0].reported()) == 2                           # not stacked yet
    for r in out[1:]:                                            # A detected: only A shown
        assert [t.id for t in r.reported()] == [id_a] and r.suppressed_ids == {id_b}
        # ~/tracks_detailed still lists the hidden twin, marked as not published
        detailed = {f.detection.id: f for f in tracked_objects(
            r.tracks, "person", (t.id for t in r.reported()))}
        # (live: coasting, as nothing refines it without multiple kernels)
        assert detailed[str(id_b)].state == STATE_CODES["occluded"]
        assert not detailed[str(id_b)].published and detailed[str(id_a)].published
    # both detected again as two people (boxes at IoU 18/42): both reported at once
    r = trk.step(IMG, 34 * DT, [FrameDetection((100, 100, 30, 60), 0.9),
                                FrameDetection((112, 100, 30, 60), 0.9)])
    assert {t.id for t in r.reported()} == {id_a, id_b} and not r.suppressed_ids


def test_two_detections_of_one_person_do_not_keep_its_two_tracks_apart():
    """B walks up to A and both stay detected, but their two boxes overlap by IoU 26/34:
    the detector's two boxes of one person (a pair of tracks given detections that are
    stacked themselves is not seen as two people), so the pair merges while both are
    detected; two boxes at IoU 18/42 would keep them apart."""
    cfg = config(**{"use_multi_kernel": False, "duplicates.min_similarity": 0.0,
                    "duplicates.report_one": "none"})
    trk = MultiObjectTracker(cfg)
    a, b = (100, 100, 30, 60), lambda i: (max(140 - 2 * i, 104), 100, 30, 60)
    merged_at = None
    for i in range(40):
        dets = [FrameDetection(b(i), 0.9)] + ([FrameDetection(a, 0.9)] if i >= 2 else [])
        r = trk.step(IMG, i * DT, dets)
        if merged_at is None and any("merged" in e for e in r.events):
            merged_at = i
    # B reaches x = 104 at frame 18; the tracks are stacked (IoU > 0.5) from x < 110, about
    # frame 16; merged 0.3 s later, with both detections still coming
    assert merged_at is not None and 22 <= merged_at <= 26, merged_at
    assert len(r.reported()) == 1 and trk.totals["merged_duplicates"] == 1
