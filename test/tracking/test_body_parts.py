"""Body parts (tracking/body_parts.py): a detection of a tracked person's other half (torso /
legs) starts no track.  Expected values are worked out by hand in the comments."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from mk_tracker.parameters import updated
from mk_tracker.tracking.body_parts import BodyPartConfig, is_other_part, stacked_part
from mk_tracker.tracking.multi_object_tracker import (FrameDetection, MultiObjectTracker,
                                                      MultiObjectTrackerConfig)

# the defaults: column 0.6, width ratio 1.5, height ratio 1.6, rows 0.35, gap 0.15, parts at
# most 2.0 times as tall as wide, the union 1.8-4.0 times
CFG = BodyPartConfig()
TORSO = (100.0, 100.0, 60.0, 80.0)          # x 100-160, y 100-180


def test_legs_under_a_torso_are_its_other_part():
    # legs x 105-165, y 185-275: column 160 - 105 = 55 >= 0.6 * 60 = 36; widths equal;
    # rows 180 - 185 = -5, a gap of 5 <= 0.15 * 90 = 13.5; union 65 x 175: 2.69 in [1.8, 4]
    legs = (105.0, 185.0, 60.0, 90.0)
    assert stacked_part(TORSO, legs, CFG)
    assert stacked_part(legs, TORSO, CFG)            # the torso above tracked legs too
    assert is_other_part(legs, [(400.0, 100.0, 60.0, 80.0), TORSO], CFG)


def test_overlapping_rows_up_to_the_limit_still_stack():
    # legs starting 28 px above the torso's bottom: rows 180 - 152 = 28 = 0.35 * 80 (the
    # shorter height); 29 px is one more than the limit
    assert stacked_part(TORSO, (100.0, 152.0, 60.0, 100.0), CFG)
    assert not stacked_part(TORSO, (100.0, 151.0, 60.0, 100.0), CFG)


@pytest.mark.parametrize("box, why", [
    ((170.0, 185.0, 60.0, 90.0), "side by side: columns 160 - 170 = -10 < 36"),
    ((135.0, 185.0, 60.0, 90.0), "column 160 - 135 = 25 < 0.6 * 60 = 36"),
    ((90.0, 185.0, 100.0, 90.0), "widths 100 / 60 = 1.67 > 1.5"),
    ((105.0, 185.0, 60.0, 45.0), "heights 80 / 45 = 1.78 > 1.6 (union 65 x 130 is 2.0: "
                                 "a person's shape; a short box in front, not a half)"),
    ((110.0, 120.0, 50.0, 100.0), "one behind the other: rows 60 > 0.35 * 80 = 28"),
    ((100.0, 200.0, 60.0, 80.0), "gap 20 > 0.15 * 80 = 12"),
])
def test_boxes_that_are_not_stacked_parts(box, why):
    assert not stacked_part(TORSO, box, CFG), why


def test_the_union_must_have_one_upright_persons_shape():
    # a wide torso and legs: union 100 x 125 is 1.25 < 1.8 times as tall as wide
    assert not stacked_part((100.0, 100.0, 100.0, 60.0), (100.0, 165.0, 100.0, 60.0), CFG)
    # two boxes of aspect 2.0 one above the other: union 40 x 165, 4.125 > 4.0
    assert not stacked_part((100.0, 100.0, 40.0, 80.0), (100.0, 185.0, 40.0, 80.0), CFG)
    # the same two boxes pass once the upper bound allows 4.2
    wide = dataclasses.replace(CFG, max_person_aspect=4.2)
    assert stacked_part((100.0, 100.0, 40.0, 80.0), (100.0, 185.0, 40.0, 80.0), wide)


def test_a_whole_person_is_no_part():
    # a detection 60 x 130 under the torso: 130 > 2.0 * 60, taller than a torso or legs
    assert not stacked_part(TORSO, (105.0, 185.0, 60.0, 130.0), CFG)
    # nor is a tracked whole person (60 x 130) the torso of a squat detection below it
    assert not stacked_part((100.0, 50.0, 60.0, 130.0), (105.0, 185.0, 60.0, 90.0), CFG)


def test_disabled_or_degenerate_boxes_are_no_parts():
    legs = (105.0, 185.0, 60.0, 90.0)
    assert CFG.enabled                                      # on by default
    assert not is_other_part(legs, [TORSO], dataclasses.replace(CFG, enabled=False))
    assert not is_other_part(legs, [], CFG)
    assert not stacked_part(TORSO, (105.0, 185.0, 0.0, 90.0), CFG)
    assert not stacked_part(TORSO, (math.nan, 185.0, 60.0, 90.0), CFG)


IMG = np.zeros((480, 640, 3), np.uint8)
DT = 1.0 / 25.0


@pytest.mark.parametrize("enabled", [True, False])
def test_the_tracker_starts_no_track_on_the_legs_of_a_tracked_torso(enabled):
    """A person tracked by the torso box; from frame 10 on the detector also reports the
    legs below it.  With the rule the legs start no track, without it they start one that
    is confirmed after min_hits (3) detections."""
    cfg = updated(MultiObjectTrackerConfig(), {"use_multi_kernel": False,
                                               "parts.enabled": enabled})
    trk = MultiObjectTracker(cfg)
    for i in range(20):
        torso = (100.0 + i, 100.0, 60.0, 80.0)
        dets = [FrameDetection(torso, 0.9)]
        if i >= 10:
            dets.append(FrameDetection((105.0 + i, 185.0, 60.0, 90.0), 0.9))
        result = trk.step(IMG, i * DT, dets)
    reported = result.reported()
    if enabled:
        assert [t.id for t in reported] == [1]
        assert len(trk.tracks) == 1
    else:
        assert sorted(t.id for t in reported) == [1, 2]
        legs = next(t for t in reported if t.id == 2)
        assert legs.box[1] > 180.0                    # the new track is on the legs


def test_a_second_person_beside_the_tracked_one_still_gets_a_track():
    cfg = updated(MultiObjectTrackerConfig(), {"use_multi_kernel": False,
                                               "parts.enabled": True})
    trk = MultiObjectTracker(cfg)
    for i in range(20):
        dets = [FrameDetection((100.0 + i, 100.0, 60.0, 160.0), 0.9)]
        if i >= 10:
            dets.append(FrameDetection((300.0 - i, 100.0, 60.0, 160.0), 0.9))
        result = trk.step(IMG, i * DT, dets)
    assert sorted(t.id for t in result.reported()) == [1, 2]
