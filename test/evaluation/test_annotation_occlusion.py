"""The box occlusion statistics of a ground truth (mk_tracker.evaluation.annotation_occlusion),
against areas worked out by hand."""

import pytest

from mk_tracker.evaluation.annotation_occlusion import (IdentityGap, box_visibility,
                                                        covered_area, frame_visibilities,
                                                        identity_gaps)


def test_covered_area_counts_overlapping_covers_once():
    box = (0, 0, 10, 10)
    assert covered_area(box, [(5, 0, 10, 10)]) == pytest.approx(50.0)
    # two covers overlapping each other on 2 x 10 px: 60 + 60 - 20 = 100, the whole box
    assert covered_area(box, [(0, 0, 6, 10), (4, 0, 6, 10)]) == pytest.approx(100.0)
    # an L of two covers: 10 x 4 across the top and 3 x 10 down the left, overlap 3 x 4
    assert covered_area(box, [(-5, -5, 20, 9), (-2, 0, 5, 20)]) == pytest.approx(40 + 30 - 12)


def test_covers_outside_or_degenerate_cover_nothing():
    box = (10, 10, 20, 30)
    assert covered_area(box, []) == 0.0
    assert covered_area(box, [(30, 10, 5, 5), (0, 0, 10, 10), (12, 12, 0, 5)]) == 0.0


def test_visibility_counts_the_part_outside_the_image_as_hidden():
    assert box_visibility((-5, 0, 10, 10), [], (100, 100)) == pytest.approx(0.5)
    assert box_visibility((-5, 0, 10, 10), []) == pytest.approx(1.0)      # no image border
    # half outside, and a cover over 2 x 10 of the inside half
    assert box_visibility((-5, 0, 10, 10), [(3, 0, 10, 10)], (100, 100)) == pytest.approx(0.3)
    assert box_visibility((200, 0, 10, 10), [], (100, 100)) == 0.0


def test_only_boxes_with_a_lower_bottom_edge_hide_a_box():
    boxes = {1: (100, 100, 40, 100),        # bottom 200, far
             2: (90, 90, 60, 150),          # bottom 240, near: covers all of box 1
             3: (120, 100, 40, 100)}        # bottom 200 like box 1: neither hides the other
    vis = frame_visibilities(boxes, (640, 480))
    assert vis[1] == pytest.approx(0.0)
    assert vis[2] == pytest.approx(1.0)     # in front of both
    # box 3: x 120..150 covered by box 2 (x 90..150), 150..160 free: 10 of 40 columns
    assert vis[3] == pytest.approx(0.25)


def test_gaps_are_the_missing_frames_between_annotations_with_interpolated_boxes():
    gt = [{1: (0, 0, 10, 20), 2: (5, 5, 5, 5)}, {2: (5, 5, 5, 5)}, {2: (5, 5, 5, 5)},
          {1: (30, 6, 13, 20)}, {1: (33, 6, 13, 20)}]
    gaps = identity_gaps(gt)
    assert gaps == [IdentityGap(1, 1, 0, 3, (10.0, 2.0, 11.0, 20.0)),
                    IdentityGap(1, 2, 0, 3, (20.0, 4.0, 12.0, 20.0))]
    assert identity_gaps([{1: (0, 0, 1, 1)}] * 4) == []   # an identity that simply ends


@pytest.mark.parametrize("box", [(0, 0, 0, 10), (0, 0, 10, -1), (0, float("nan"), 5, 5),
                                 (1, 2, 3)])
def test_a_malformed_box_is_refused_saying_why(box):
    with pytest.raises(ValueError, match="box"):
        box_visibility(box, [])
    with pytest.raises(ValueError, match="id 7"):
        frame_visibilities({7: box})
