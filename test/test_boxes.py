"""Boxes: every expected value below is worked out by hand in the comment beside it.

``boxes.iou`` is the measuring stick of many behaviour tests, so it is checked here on
rectangles (width != height, so that a swapped width and height shows), on disjoint,
touching, overlapping and contained pairs, and against ``iou_matrix`` entry by entry.
"""

import math

import numpy as np
import pytest

from mk_tracker.boxes import (InvalidBoxError, as_box, box_center, center_to_xywh, clip_box,
                              intersection_area, iou, iou_matrix, is_valid_box,
                              transform_box, xywh_to_center)

# (a, b, intersection area, IoU), all by hand.
PAIRS = [
    # a: x 0..4, y 0..2 (area 8); b: x 1..5, y 1..5 (area 16)
    # overlap x 1..4 (3), y 1..2 (1) -> 3; union 8 + 16 - 3 = 21
    ((0, 0, 4, 2), (1, 1, 4, 4), 3.0, 3.0 / 21.0),
    # b (x 0..2, y 0..2, area 4) inside a (x 0..4, y 0..2, area 8), sharing three edges:
    # overlap 4; union 8 + 4 - 4 = 8
    ((0, 0, 4, 2), (0, 0, 2, 2), 4.0, 0.5),
    # b inside a: a x 0..10, y 0..6 (area 60), b x 2..5, y 1..3 (area 6): 6 / 60
    ((0, 0, 10, 6), (2, 1, 3, 2), 6.0, 0.1),
    # the same pair the other way round
    ((2, 1, 3, 2), (0, 0, 10, 6), 6.0, 0.1),
    # a x 2..8, y 1..4 (area 18); b x 5..7, y 0..10 (area 20)
    # overlap x 5..7 (2), y 1..4 (3) -> 6; union 18 + 20 - 6 = 32
    ((2, 1, 6, 3), (5, 0, 2, 10), 6.0, 6.0 / 32.0),
    # disjoint in x only (a ends at x 3, b starts at x 4; y ranges overlap)
    ((0, 0, 3, 5), (4, 1, 2, 2), 0.0, 0.0),
    # disjoint in y only (a ends at y 2, b starts at y 7; x ranges overlap)
    ((0, 0, 6, 2), (1, 7, 3, 1), 0.0, 0.0),
    # disjoint in both
    ((0, 0, 1, 2), (5, 5, 3, 1), 0.0, 0.0),
    # touching along an edge (a ends at x 4, b starts at x 4): no area in common
    ((0, 0, 4, 2), (4, 0, 3, 2), 0.0, 0.0),
    # touching at a corner only
    ((0, 0, 4, 2), (4, 2, 1, 1), 0.0, 0.0),
    # identical rectangles
    ((1.5, 2.5, 3, 7), (1.5, 2.5, 3, 7), 21.0, 1.0),
    # fractional coordinates: a x 0.5..2.5, y 0..1 (area 2), b x 2..3, y 0.25..0.75 (0.5)
    # overlap x 2..2.5 (0.5), y 0.25..0.75 (0.5) -> 0.25; union 2 + 0.5 - 0.25 = 2.25
    ((0.5, 0, 2, 1), (2, 0.25, 1, 0.5), 0.25, 0.25 / 2.25),
]


@pytest.mark.parametrize("a, b, inter, expected", PAIRS)
def test_intersection_area_by_hand(a, b, inter, expected):
    assert intersection_area(a, b) == pytest.approx(inter, abs=1e-12)
    assert intersection_area(b, a) == pytest.approx(inter, abs=1e-12)


@pytest.mark.parametrize("a, b, inter, expected", PAIRS)
def test_iou_by_hand(a, b, inter, expected):
    assert iou(a, b) == pytest.approx(expected, abs=1e-12)
    assert iou(b, a) == pytest.approx(expected, abs=1e-12)


def test_iou_matrix_by_hand_on_rectangles():
    # every entry is one of the PAIRS above, so its value is the hand-computed one
    a = np.array([p[0] for p in PAIRS], float)
    b = np.array([p[1] for p in PAIRS], float)
    m = iou_matrix(a, b)
    assert m.shape == (len(PAIRS), len(PAIRS))
    np.testing.assert_allclose(np.diag(m), [p[3] for p in PAIRS], atol=1e-12)
    mt = iou_matrix(b, a)
    np.testing.assert_allclose(np.diag(mt), [p[3] for p in PAIRS], atol=1e-12)


def test_iou_matrix_reads_width_and_height_of_both_sides():
    # a: x 0..4, y 0..1 (area 4); b0: x 0..1, y 0..4 (area 4), the same shape turned
    # overlap x 0..1, y 0..1 -> 1, union 4 + 4 - 1 = 7
    # b1: x 3..5, y 0..3 (area 6): overlap x 3..4, y 0..1 -> 1, union 4 + 6 - 1 = 9
    a = np.array([[0, 0, 4, 1]], float)
    b = np.array([[0, 0, 1, 4], [3, 0, 2, 3]], float)
    np.testing.assert_allclose(iou_matrix(a, b), [[1 / 7, 1 / 9]], atol=1e-12)
    np.testing.assert_allclose(iou_matrix(b, a), [[1 / 7], [1 / 9]], atol=1e-12)


def test_iou_matrix_of_empty_sets_has_the_right_shape():
    assert iou_matrix(np.zeros((0, 4)), np.array([[0, 0, 1, 1]] * 3, float)).shape == (0, 3)
    assert iou_matrix(np.array([[0, 0, 1, 1]] * 2, float), np.zeros((0, 4))).shape == (2, 0)


def test_degenerate_boxes_have_iou_zero():
    # zero-area boxes: the union is 0, so there is no ratio; 0 by definition
    assert iou((0, 0, 0, 5), (0, 0, 0, 5)) == 0.0
    assert iou((1, 1, 3, 0), (1, 1, 3, 0)) == 0.0
    np.testing.assert_array_equal(iou_matrix([[0, 0, 0, 5]], [[0, 0, 0, 5]]), [[0.0]])
    # an infinite box: intersection 1 (with the unit square), union infinite
    assert iou((0, 0, math.inf, 1), (0, 0, 1, 1)) == 0.0
    np.testing.assert_array_equal(iou_matrix([[0, 0, math.inf, 1]], [[0, 0, 1, 1]]), [[0.0]])


def test_clip_box_by_hand():
    # inside: unchanged
    assert clip_box((1, 2, 3, 4), 10, 8) == (1.0, 2.0, 3.0, 4.0)
    # sticks out left and top: x -2..3 -> 0..3, y -3..3 -> 0..3
    assert clip_box((-2, -3, 5, 6), 10, 10) == (0.0, 0.0, 3.0, 3.0)
    # half a pixel out at the left: x -0.5..1.5 -> 0..1.5
    assert clip_box((-0.5, 0.25, 2, 1), 10, 10) == (0.0, 0.25, 1.5, 1.0)
    # sticks out right and bottom of a 10 x 8 image: x 7..12 -> 7..10, y 6..9 -> 6..8
    assert clip_box((7, 6, 5, 3), 10, 8) == (7.0, 6.0, 3.0, 2.0)
    # covers the whole image and more
    assert clip_box((-5, -5, 30, 30), 10, 8) == (0.0, 0.0, 10.0, 8.0)


def test_clip_box_outside_or_touching_the_image_is_none():
    assert clip_box((20, 2, 3, 3), 10, 10) is None        # right of the image
    assert clip_box((-5, 2, 3, 3), 10, 10) is None        # left of it (x -5..-2)
    assert clip_box((2, -5, 3, 3), 10, 10) is None        # above it
    assert clip_box((10, 0, 5, 5), 10, 10) is None        # touches the right edge
    assert clip_box((0, 10, 5, 5), 10, 10) is None        # touches the bottom edge
    assert clip_box((-3, 0, 3, 5), 10, 10) is None        # touches the left edge
    assert clip_box((0, -3, 5, 3), 10, 10) is None        # touches the top edge


def test_centre_conversions_on_a_rectangle():
    # x 2..8 (w 6), y 1..5 (h 4): centre (5, 3)
    assert xywh_to_center((2, 1, 6, 4)) == (5.0, 3.0, 6.0, 4.0)
    assert center_to_xywh(5, 3, 6, 4) == (2.0, 1.0, 6.0, 4.0)
    np.testing.assert_array_equal(box_center((2, 1, 6, 4)), [5.0, 3.0])


def test_as_box_accepts_four_finite_numbers_with_positive_size():
    out = as_box([1, 2, 3, 4.5])
    assert out.dtype == np.float64
    np.testing.assert_array_equal(out, [1.0, 2.0, 3.0, 4.5])
    assert is_valid_box((0, 0, 0.5, 0.25))
    assert is_valid_box((-3, -4, 1, 1))          # a box may start left of / above the image


@pytest.mark.parametrize("bad", [
    (0, 0, 0, 1),            # zero width
    (0, 0, 1, 0),            # zero height
    (0, 0, -1, 2),           # negative width
    (0, 0, 2, -1),           # negative height
    (math.nan, 0, 1, 1),
    (0, 0, 1, math.inf),
    (0, 0, 1),               # three values
    (0, 0, 1, 1, 1),         # five values
    ("a", 0, 1, 1),          # not a number
    None,
])
def test_as_box_rejects_unusable_boxes(bad):
    with pytest.raises(InvalidBoxError):
        as_box(bad)
    assert not is_valid_box(bad)


@pytest.mark.parametrize("bad, reason", [
    ((0, 0, 0, 1), "non-positive width or height"),
    ((math.nan, 0, 1, 1), "NaN or infinite"),
    ((0, 0, 1), "must have 4 values"),
    (("a", 0, 1, 1), "not four numbers"),
])
def test_as_box_says_what_is_wrong(bad, reason):
    with pytest.raises(InvalidBoxError, match=reason):
        as_box(bad)


def test_iou_of_boxes_smaller_than_a_pixel():
    # x 0..0.5, y 0..0.5 (area 0.25) twice: IoU 1; against x 0.25..0.75 (same height):
    # overlap 0.25 x 0.5 = 0.125, union 0.25 + 0.25 - 0.125 = 0.375 -> 1/3
    a, b = (0, 0, 0.5, 0.5), (0.25, 0, 0.5, 0.5)
    assert iou(a, a) == pytest.approx(1.0)
    assert iou(a, b) == pytest.approx(1.0 / 3.0)
    np.testing.assert_allclose(iou_matrix([a], [a, b]), [[1.0, 1.0 / 3.0]], atol=1e-12)


def test_iou_matrix_computes_in_float64_whatever_the_input_type():
    # identical boxes at x = 2^24: x + w = 2^24 + 1 exists in float64 but not in float32
    # (it rounds to 2^24, leaving no width); the IoU of a box with itself is 1
    big = np.array([[2.0 ** 24, 0.0, 1.0, 1.0]], np.float32)
    np.testing.assert_allclose(iou_matrix(big, big.astype(np.float64)), [[1.0]])
    np.testing.assert_allclose(iou_matrix(big.astype(np.float64), big), [[1.0]])


def test_iou_matrix_raises_no_floating_point_error_on_degenerate_boxes():
    # zero-area and NaN boxes make 0/0 inside; the function must absorb it even when the
    # caller has numpy raise on invalid operations
    with np.errstate(all="raise"):
        out = iou_matrix([[0, 0, 0, 5], [np.nan, 0, 1, 1]], [[0, 0, 0, 5], [0, 0, 1, 1]])
    np.testing.assert_array_equal(out, np.zeros((2, 2)))


def test_transform_box_by_hand():
    # x' = 2x + 1, y' = 3y - 1: corners x 1..3 -> 3..7, y 1..2 -> 2..5
    h = np.array([[2.0, 0.0, 1.0], [0.0, 3.0, -1.0], [0.0, 0.0, 1.0]])
    assert transform_box((1, 1, 2, 1), h) == pytest.approx((3.0, 2.0, 4.0, 3.0))
    # mirror in x: x 1..3 -> -3..-1, the hull starts at the smaller corner
    mirror = np.diag([-1.0, 1.0, 1.0])
    assert transform_box((1, 0, 2, 1), mirror) == pytest.approx((-3.0, 0.0, 2.0, 1.0))
    # homogeneous scale 2 halves everything: x 2..4 -> 1..2, y 4..6 -> 2..3
    half = np.diag([1.0, 1.0, 2.0])
    assert transform_box((2, 4, 2, 2), half) == pytest.approx((1.0, 2.0, 1.0, 1.0))
    # perspective: w = x, so (x, y) -> (1, y / x); corners x 1..2, y 0..2
    # y / x over the corners: 0, 0, 2, 1 -> y' 0..2; x' = 1 for all -> zero width: invalid
    persp = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    with pytest.raises(InvalidBoxError):
        transform_box((1, 0, 1, 2), persp)
    # x' = x + y, y' = y, w = x: corners (1,0)->(1,0), (2,0)->(1,0), (1,2)->(3,2), (2,2)->(2,1)
    shear = np.array([[1.0, 1.0, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    assert transform_box((1, 0, 1, 2), shear) == pytest.approx((1.0, 0.0, 2.0, 2.0))


def test_transform_box_near_the_vanishing_line():
    # w = 1e-12 everywhere: a huge but finite box, x 1..2 -> 1e12..2e12
    scale = np.diag([1.0, 1.0, 1e-12])
    assert transform_box((1, 1, 1, 1), scale) == pytest.approx((1e12, 1e12, 1e12, 1e12))
    # w = 1e-13: treated as on the vanishing line
    with pytest.raises(InvalidBoxError, match="infinity"):
        transform_box((1, 1, 1, 1), np.diag([1.0, 1.0, 1e-13]))


def test_transform_box_on_the_vanishing_line_raises():
    # w = x: the corner at x = 0 maps to infinity
    persp = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    with pytest.raises(InvalidBoxError):
        transform_box((0, 0, 1, 1), persp)
    with pytest.raises(InvalidBoxError):
        transform_box((0, 0, 1, 1), np.full((3, 3), np.nan))
    with pytest.raises(InvalidBoxError):
        transform_box((0, 0, 0, 1), np.eye(3))                  # the input box is unusable
