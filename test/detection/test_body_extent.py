"""Whole-body boxes: stacked parts of one person joined (mk_tracker.detection.body_extent,
issues #15 and #19).  Expected values are worked out by hand in the comments."""

from __future__ import annotations

import dataclasses

import pytest

from mk_tracker.detection.body_extent import BodyExtentConfig, is_stacked, join_stacked
from mk_tracker.detection.thermal_detector import (ThermalDetection, ThermalDetector,
                                                   ThermalDetectorConfig)
from mk_tracker.parameters import ParameterError

RULE = BodyExtentConfig(join_stacked=True)


def det(box, pixels, score=0.5, object_id=-1, centroid=None):
    x, y, w, h = box
    return ThermalDetection(box=box, centroid=centroid or (x + w / 2, y + h / 2),
                            score=score, pixel_count=pixels, object_id=object_id,
                            filtered_centroid=(float(object_id), 0.0),
                            velocity=(float(object_id), 1.0))


def test_an_upper_and_a_lower_part_are_stacked():
    # columns 10..30 and 12..30 overlap by 18 >= 0.5 * 18; the lower starts 2 px below the
    # upper's bottom (40), 2 <= 0.25 * 40; union 20 x 92, 20 <= 0.6 * 92
    assert is_stacked((10, 0, 20, 40), (12, 42, 18, 50), RULE) == 2.0
    assert is_stacked((12, 42, 18, 50), (10, 0, 20, 40), RULE) == 2.0     # either order
    # overlapping rows: 36..40 is 4 rows <= 0.3 * 40 = 12, the gap is -4
    assert is_stacked((10, 0, 20, 40), (10, 36, 20, 40), RULE) == -4.0


def test_side_by_side_in_front_and_far_apart_are_not_stacked():
    # side by side: the column ranges 0..20 and 22..42 do not overlap
    assert is_stacked((0, 0, 20, 50), (22, 0, 20, 50), RULE) is None
    # one person in front of another: rows 10..50 lie inside 0..60, 40 > 0.3 * 40
    assert is_stacked((0, 0, 20, 60), (5, 10, 20, 40), RULE) is None
    # a gap of 20 rows > 0.25 * 40
    assert is_stacked((0, 0, 20, 40), (0, 60, 20, 40), RULE) is None
    # columns 0..20 and 12..32 overlap by 8 < 0.5 * 20
    assert is_stacked((0, 0, 20, 40), (12, 41, 20, 40), RULE) is None


def test_a_union_wider_than_one_upright_person_is_not_joined():
    # union 40 x 62: 40 > 0.6 * 62 = 37.2; with aspect 0.7 (43.4) it is one person
    a, b = (0, 0, 40, 30), (0, 32, 40, 30)
    assert is_stacked(a, b, RULE) is None
    assert is_stacked(a, b, dataclasses.replace(RULE, aspect=0.7)) == 2.0


def test_joined_detection_takes_the_union_and_the_larger_part():
    upper = det((10, 0, 20, 40), 300, score=0.8, object_id=7, centroid=(20.0, 20.0))
    lower = det((12, 42, 18, 50), 100, score=0.4, object_id=3, centroid=(21.0, 67.0))
    other = det((100, 0, 20, 50), 50, object_id=9)
    out = join_stacked([other, upper, lower], RULE)
    assert len(out) == 2 and out[0] is other           # order of the others kept
    j = out[1]
    assert j.box == (10, 0, 20, 92)
    # centroid (20 * 300 + 21 * 100) / 400 = 20.25, (20 * 300 + 67 * 100) / 400 = 31.75
    assert j.centroid == pytest.approx((20.25, 31.75))
    assert j.score == pytest.approx((0.8 * 300 + 0.4 * 100) / 400)        # 0.7
    assert j.pixel_count == 400
    # id, filtered centroid and velocity of the part with more pixels (the upper, id 7)
    assert j.object_id == 7 and j.filtered_centroid == (7.0, 0.0) and j.velocity == (7.0, 1.0)


def test_head_torso_and_legs_become_one_person():
    head = det((14, 0, 12, 14), 60, object_id=1)
    torso = det((10, 16, 20, 36), 300, object_id=2)     # gap 2 to the head
    legs = det((11, 55, 18, 45), 200, object_id=3)      # gap 3 to the torso
    members: list = []
    out = join_stacked([legs, head, torso], RULE, members)
    assert len(out) == 1 and sorted(members[0]) == [0, 1, 2]
    assert out[0].box == (10, 0, 20, 100) and out[0].pixel_count == 560
    assert out[0].object_id == 2


def detector(height=240, **rule):
    d = ThermalDetector(ThermalDetectorConfig(body_extent=dataclasses.replace(RULE, **rule)))
    d._shape = (height, 320)       # set by process() from the first frame
    return d


def test_off_by_default_and_nothing_changes_then():
    parts = [det((10, 0, 20, 40), 300, object_id=1), det((12, 42, 18, 50), 100, object_id=2)]
    assert ThermalDetectorConfig().body_extent.join_stacked is False
    assert detector(join_stacked=False)._whole_bodies(parts) is parts
    assert len(detector()._whole_bodies(parts)) == 1


def test_a_part_reported_alone_keeps_its_persons_extent():
    d = detector(extent_frames=15)
    upper = det((10, 20, 20, 40), 300, object_id=1)
    lower = det((12, 62, 18, 50), 100, object_id=2)
    assert [x.box for x in d._whole_bodies([upper, lower])] == [(10, 20, 20, 92)]
    # the person reached 0 heights above the upper part and (112 - 60) / 40 = 1.3 below;
    # alone two frames later, 4 px lower: top 24, bottom 64 + 1.3 * 40 = 116
    alone = det((10, 24, 20, 40), 300, object_id=1)
    assert d._whole_bodies([alone])[0].box == pytest.approx((10, 24, 20, 92))
    # the lower part's memory went when it was not reported (frame above): not grown
    assert d._whole_bodies([lower])[0].box == lower.box
    # extent_frames 0 (the default): a part alone is never grown
    d = detector()
    d._whole_bodies([upper, lower])
    assert d._whole_bodies([alone])[0].box == alone.box


def test_the_extent_is_clipped_to_the_image_and_forgotten_after_extent_frames():
    d = detector(height=100, extent_frames=1)
    d._whole_bodies([det((10, 20, 20, 40), 300, object_id=1),
                     det((12, 62, 18, 50), 100, object_id=2)])
    alone = det((10, 24, 20, 40), 300, object_id=1)
    # bottom 116 clipped to the image's 100 rows: height 76
    assert d._whole_bodies([alone])[0].box == pytest.approx((10, 24, 20, 76))
    assert d._whole_bodies([alone])[0].box == alone.box      # one frame only


def test_a_union_taller_than_the_learnt_height_is_not_joined():
    d = detector(height_ratio=1.2)
    for y_bottom, h in ((100, 50), (150, 75), (200, 100)):     # h = 0.5 * row of the feet
        d.heights.add(y_bottom, h)
    # union (10, 90, 20, 110): bottom row 200, expected 100, 110 <= 1.2 * 100
    out = d._whole_bodies([det((10, 90, 20, 50), 100, object_id=1),
                           det((10, 142, 20, 58), 100, object_id=2)])
    assert [x.box for x in out] == [(10, 90, 20, 110)]
    # union (10, 70, 20, 130): 130 > 120, two people (one behind the other)
    out = d._whole_bodies([det((10, 70, 20, 60), 100, object_id=3),
                           det((10, 132, 20, 68), 100, object_id=4)])
    assert len(out) == 2
    # without the test (height_ratio 0) they are one
    assert len(detector()._whole_bodies([det((10, 70, 20, 60), 100, object_id=3),
                                         det((10, 132, 20, 68), 100, object_id=4)])) == 1


def test_heights_are_learnt_from_reported_person_shaped_boxes_only_with_the_test():
    upright = det((10, 100, 20, 80), 100, object_id=1)   # 20 / 80 = 0.25: person-shaped
    wide = det((50, 100, 60, 80), 100, object_id=2)      # 0.75: not
    d = detector(height_ratio=1.2)
    d._whole_bodies([upright, wide])
    assert d.heights.samples == pytest.approx(1.0)
    d = detector()
    d._whole_bodies([upright, wide])
    assert d.heights.samples == 0.0


def test_detector_config_refuses_values_out_of_range():
    with pytest.raises(ParameterError):
        ThermalDetector(ThermalDetectorConfig(body_extent=BodyExtentConfig(aspect=0.0)))
    with pytest.raises(ParameterError):
        ThermalDetector(ThermalDetectorConfig(body_extent=BodyExtentConfig(
            column_overlap=1.5)))
