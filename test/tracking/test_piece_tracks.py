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
from mk_tracker.tracking.piece_tracks import (PieceConfig, due_pieces, nested_in,
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
