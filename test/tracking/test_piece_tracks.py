"""Piece tracks (tracking/piece_tracks.py): a track whose box lies inside a larger track's
box is a piece of that person.  Expected values are worked out by hand in the comments."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from mk_tracker.boxes import iou
from mk_tracker.parameters import updated
from mk_tracker.tracking.group_measurement import coverage_matrix
from mk_tracker.tracking.multi_object_tracker import (FrameDetection, MultiObjectTracker,
                                                      MultiObjectTrackerConfig)
from mk_tracker.tracking.piece_tracks import (PieceConfig, born_beside, due_pieces,
                                              hits_to_confirm, nested_in,
                                              update_nested_since)

# coverage 0.8, area ratio 1.5, 0.3 s
CFG = dataclasses.replace(PieceConfig(), enabled=True)
BODY = (100.0, 100.0, 60.0, 160.0)          # x 100-160, y 100-260, area 9600


def test_a_head_inside_a_body_is_nested_in_it():
    # head x 115-145, y 100-130: wholly inside (coverage 1 >= 0.8), area 900: 9600 / 900 =
    # 10.7 >= 1.5; the body is inside nothing
    assert nested_in([1, 2], [BODY, (115.0, 100.0, 30.0, 30.0)], CFG) == {2: 1}


def test_the_rule_is_off_by_default():
    assert not PieceConfig().enabled
    assert nested_in([1, 2], [BODY, (115.0, 100.0, 30.0, 30.0)], PieceConfig()) == {}


@pytest.mark.parametrize("box, why", [
    ((140.0, 100.0, 40.0, 40.0), "x 140-180: 20 of 40 columns inside, coverage 0.5 < 0.8"),
    ((130.0, 100.0, 40.0, 40.0), "x 130-170: 30 of 40 columns, coverage 0.75 < 0.8"),
    ((102.0, 102.0, 55.0, 150.0), "inside, but 9600 / 8250 = 1.16 < 1.5: a duplicate"),
])
def test_not_nested(box, why):
    assert nested_in([1, 2], [BODY, box], CFG) == {}, why


def test_coverage_at_the_limit_is_nested():
    # x 128-168: 32 of 40 columns inside = 0.8 exactly; area 1600, 9600 / 1600 = 6
    box = (128.0, 100.0, 40.0, 40.0)
    assert coverage_matrix([box], [BODY])[0, 0] == pytest.approx(0.8)
    assert nested_in([1, 2], [BODY, box], CFG) == {2: 1}


def test_a_chain_goes_to_the_outermost_container():
    # head (400) in torso (4000) in body (9600): torso 9600 / 4000 = 2.4 >= 1.5, so the
    # torso is nested in the body, and the head, inside both, is the body's too
    head, torso = (115.0, 100.0, 20.0, 20.0), (105.0, 100.0, 50.0, 80.0)
    assert nested_in([7, 8, 9], [head, torso, BODY], CFG) == {7: 9, 8: 9}
    assert nested_in([8, 7, 9], [torso, head, BODY], CFG) == {7: 9, 8: 9}


def test_bad_boxes_are_neither_nested_nor_containers():
    head = (115.0, 100.0, 30.0, 30.0)
    assert nested_in([1, 2], [(math.nan, 100.0, 60.0, 160.0), head], CFG) == {}
    assert nested_in([1, 2], [(100.0, 100.0, 0.0, 160.0), head], CFG) == {}
    assert nested_in([1, 2], [BODY, (115.0, 100.0, -30.0, 30.0)], CFG) == {}
    assert nested_in([1], [BODY], CFG) == {}


def test_the_clock_starts_when_nested_and_restarts_after_a_break():
    since = update_nested_since({}, {2: 1}, 10.0)
    assert since == {2: 10.0}
    since = update_nested_since(since, {2: 1, 3: 1}, 10.2)      # 2 keeps 10.0
    assert since == {2: 10.0, 3: 10.2}
    assert due_pieces(since, 10.29, 0.3) == []                  # 0.29 s < 0.3
    assert due_pieces(since, 10.3, 0.3) == [2]
    assert due_pieces(since, 10.5, 0.3) == [2, 3]
    since = update_nested_since(since, {3: 1}, 10.6)            # 2 not nested: dropped
    assert since == {3: 10.2}
    assert update_nested_since(since, {2: 1}, 10.7) == {2: 10.7}


IMG = np.zeros((480, 640, 3), np.uint8)
DT = 1.0 / 25.0


@pytest.mark.parametrize("enabled", [True, False])
def test_the_tracker_hides_and_ends_a_track_that_moves_inside_another(enabled):
    """A person detected still at BODY; a small box (a piece) detected from x = 300 moves
    left 10 px a frame until x = 110 (frame 19) and stays there, wholly inside the body's
    box.  With the rule the piece's track is never reported while nested, and is deleted
    after 0.3 s nested (8 frames at 25 Hz: 7 * 0.04 = 0.28 < 0.3); without it both stay."""
    cfg = updated(MultiObjectTrackerConfig(), {"use_multi_kernel": False,
                                               "pieces.enabled": enabled})
    trk = MultiObjectTracker(cfg)
    piece_boxes = []
    for i in range(40):
        x = max(300.0 - 10.0 * i, 110.0)
        result = trk.step(IMG, i * DT, [FrameDetection(BODY, 0.9),
                                        FrameDetection((x, 120.0, 30.0, 60.0), 0.9)])
        reported = {t.id: t.box for t in result.reported()}
        if 2 in reported:
            piece_boxes.append(reported[2])
    assert piece_boxes                              # reported while it was outside
    if enabled:
        assert [t.id for t in trk.tracks] == [1]
        assert trk.totals["retired_pieces"] == 1
        # never reported while 0.8 of it was inside the body's box
        assert max(coverage_matrix(piece_boxes, [BODY])[:, 0]) < 0.8
        # and the detection left inside the body's box starts no new track
        assert [t.id for t in result.reported()] == [1]
    else:
        assert sorted(t.id for t in result.reported()) == [1, 2]
        assert trk.totals["retired_pieces"] == 0
        assert iou(result.reported()[1].box, (110.0, 120.0, 30.0, 60.0)) > 0.5


BESIDE = dataclasses.replace(PieceConfig(), min_hits_beside=15)     # coverage 0.2


def test_born_beside_needs_the_reported_boxes_to_cover_enough_of_it():
    # a box x 140-200 beside BODY x 100-160: the 12 x 12 sample grid has columns at
    # 142.5, 147.5, ..., 197.5; 4 of them (up to 157.5) are under BODY: 4 / 12 = 0.33 >= 0.2
    assert born_beside((140.0, 100.0, 60.0, 160.0), [BODY], BESIDE)
    # x 155-215: one column (157.5) of 12 = 0.083 < 0.2
    assert not born_beside((155.0, 100.0, 60.0, 160.0), [BODY], BESIDE)
    assert not born_beside((140.0, 100.0, 60.0, 160.0), [], BESIDE)
    assert not born_beside((math.nan, 100.0, 60.0, 160.0), [BODY], BESIDE)
    # off by default (min_hits_beside 0): never beside
    assert not born_beside((140.0, 100.0, 60.0, 160.0), [BODY], PieceConfig())


def test_hits_to_confirm():
    assert hits_to_confirm(3, True, BESIDE) == 15
    assert hits_to_confirm(3, False, BESIDE) == 3
    assert hits_to_confirm(3, True, dataclasses.replace(BESIDE, min_hits_beside=2)) == 3
    assert hits_to_confirm(3, True, PieceConfig()) == 3


def _first_reported(beside: int, detected) -> int | None:
    """A person detected at BODY in every frame; a second box beside it (x 140-200, a
    third of it under BODY) from frame 10 in the frames ``detected(i)`` says.  The frame in
    which a track other than the person's (id 1) is first reported, or None."""
    cfg = updated(MultiObjectTrackerConfig(), {"use_multi_kernel": False,
                                               "pieces.min_hits_beside": beside})
    trk = MultiObjectTracker(cfg)
    for i in range(40):
        dets = [FrameDetection(BODY, 0.9)]
        if i >= 10 and detected(i):
            dets.append(FrameDetection((140.0, 100.0, 60.0, 160.0), 0.9))
        if {t.id for t in trk.step(IMG, i * DT, dets).reported()} - {1}:
            return i
    return None


def test_a_track_born_beside_a_reported_one_needs_min_hits_beside_detections():
    # steady: hit 1 at frame 10, so min_hits 3 is reached at frame 12 and 15 at frame 24
    assert _first_reported(0, lambda i: True) == 12
    assert _first_reported(15, lambda i: True) == 24


def test_a_piece_detected_unsteadily_is_never_confirmed_beside_a_reported_track():
    # detected five frames out of six: three in a row confirm it at min_hits 3 (frame 12);
    # at 15 every miss ends the tentative track (max_tentative_misses 0) before its 15th hit
    steady_five = lambda i: (i - 10) % 6 != 5        # noqa: E731
    assert _first_reported(0, steady_five) == 12
    assert _first_reported(15, steady_five) is None
