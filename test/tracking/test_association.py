"""Association: Mahalanobis gating, combined cost and the Hungarian assignment."""

import math

import numpy as np
import pytest

from mk_tracker.tracking.association import (AssociationConfig, AssociationError, assign,
                                    association_cost, mahalanobis_matrix)


def test_mahalanobis_matches_hand_computation():
    # S = diag(4, 1): point (2, 1) from (0, 0) -> 2^2/4 + 1^2/1 = 2
    d = mahalanobis_matrix([[0.0, 0.0]], [np.diag([4.0, 1.0])], [[2.0, 1.0], [0.0, 0.0]])
    assert d.shape == (1, 2)
    assert d[0, 0] == pytest.approx(2.0)
    assert d[0, 1] == pytest.approx(0.0)


def test_mahalanobis_with_correlation():
    s = np.array([[2.0, 1.0], [1.0, 2.0]])        # inverse = [[2, -1], [-1, 2]] / 3
    d = mahalanobis_matrix([[1.0, 1.0]], [s], [[2.0, 1.0]])
    assert d[0, 0] == pytest.approx(2.0 / 3.0)


def test_mahalanobis_per_track_points_and_bad_covariance():
    pts = np.array([[[1.0, 0.0]], [[0.0, 3.0]]])  # (T=2, D=1, 2)
    d = mahalanobis_matrix([[0, 0], [0, 0]], [np.eye(2), np.eye(2) * 9], pts)
    assert d[:, 0] == pytest.approx([1.0, 1.0])
    with pytest.raises(AssociationError):
        mahalanobis_matrix([[0, 0]], [np.zeros((2, 2))], [[1.0, 1.0]])


def test_cost_zero_for_perfect_match_and_inf_outside_gate():
    cfg = AssociationConfig(overlap_weight=0.5, gate=9.0)
    tracks = np.array([[0, 0, 10, 20], [100, 100, 10, 20]], float)
    dets = np.array([[0, 0, 10, 20]], float)
    maha = np.array([[0.0], [50.0]])
    cost = association_cost(tracks, dets, maha, cfg)
    assert cost[0, 0] == pytest.approx(0.0)
    assert math.isinf(cost[1, 0])


def test_cost_mixes_overlap_and_distance():
    cfg = AssociationConfig(overlap_weight=0.25, gate=10.0)
    t = np.array([[0, 0, 10, 10]], float)
    d = np.array([[5, 0, 10, 10]], float)       # IoU = 50 / 150 = 1/3
    cost = association_cost(t, d, np.array([[5.0]]), cfg)
    assert cost[0, 0] == pytest.approx(0.25 * (2.0 / 3.0) + 0.75 * 0.5)


def test_min_iou_forbids_pairs():
    cfg = AssociationConfig(min_iou=0.5)
    t = np.array([[0, 0, 10, 10]], float)
    d = np.array([[5, 0, 10, 10]], float)
    assert math.isinf(association_cost(t, d, np.zeros((1, 1)), cfg)[0, 0])


def test_hungarian_beats_greedy():
    # greedy takes (0,0)=1 then (1,1)=10 (total 11); optimum is (0,1)+(1,0) = 3
    a = assign(np.array([[1.0, 2.0], [1.0, 10.0]]), max_cost=100.0)
    assert sorted(a.matches) == [(0, 1), (1, 0)]
    assert a.unmatched_rows == [] and a.unmatched_cols == []


def test_assign_drops_expensive_and_impossible_pairs():
    cost = np.array([[0.2, np.inf, np.inf], [np.inf, np.inf, np.inf], [np.inf, 0.95, np.inf]])
    a = assign(cost, max_cost=0.9)
    assert a.matches == [(0, 0)]
    assert a.unmatched_rows == [1, 2]
    assert a.unmatched_cols == [1, 2]


def test_assign_empty_and_nan():
    a = assign(np.zeros((0, 3)), max_cost=1.0)
    assert a.matches == [] and a.unmatched_cols == [0, 1, 2]
    with pytest.raises(AssociationError):
        assign(np.array([[np.nan]]), max_cost=1.0)


def test_mahalanobis_correlation_term_with_a_residual_in_both_axes():
    # S = [[4, 1], [1, 2]], det 7, inverse [[2, -1], [-1, 4]] / 7.  Residual (2, 1):
    # (2 * 2^2 - 2 * 1 * 2 * 1 + 4 * 1^2) / 7 = (8 - 4 + 4) / 7 = 8 / 7.
    # Residual (2, -1) flips the sign of the cross term: (8 + 4 + 4) / 7 = 16 / 7.
    s = np.array([[4.0, 1.0], [1.0, 2.0]])
    d = mahalanobis_matrix([[1.0, 1.0]], [s], [[3.0, 2.0], [3.0, 0.0]])
    assert d[0, 0] == pytest.approx(8.0 / 7.0)
    assert d[0, 1] == pytest.approx(16.0 / 7.0)


def test_mahalanobis_per_track_covariances_are_not_mixed_up():
    # track 0: S = diag(1, 4), residual (2, 2) -> 4 + 1 = 5
    # track 1: S = diag(4, 1), residual (2, 2) -> 1 + 4 = 5; residual (0, 1) -> 1 and 1/4
    d = mahalanobis_matrix([[0.0, 0.0], [10.0, 10.0]], [np.diag([1.0, 4.0]), np.diag([4.0, 1.0])],
                           np.array([[[2.0, 2.0], [0.0, 1.0]], [[12.0, 12.0], [10.0, 11.0]]]))
    np.testing.assert_allclose(d, [[5.0, 0.25], [5.0, 1.0]])


@pytest.mark.parametrize("cov", [
    np.array([[1.0, 2.0], [2.0, 1.0]]),          # det = 1 - 4 < 0: indefinite
    np.array([[1.0, 1.0], [1.0, 1.0]]),          # det = 0: singular
    np.array([[np.nan, 0.0], [0.0, 1.0]]),       # det NaN
    np.array([[np.inf, 0.0], [0.0, 1.0]]),       # det infinite
])
def test_mahalanobis_rejects_covariances_that_are_not_positive_definite(cov):
    with pytest.raises(AssociationError):
        mahalanobis_matrix([[0.0, 0.0]], [cov], [[1.0, 1.0]])


def test_mahalanobis_shapes():
    assert mahalanobis_matrix(np.zeros((0, 2)), np.zeros((0, 2, 2)), [[1.0, 1.0]]).shape == (0, 1)
    assert mahalanobis_matrix([[0.0, 0.0]], [np.eye(2)], np.zeros((0, 2))).shape == (1, 0)
    with pytest.raises(AssociationError):        # two centres, one covariance
        mahalanobis_matrix([[0, 0], [1, 1]], [np.eye(2)], [[1.0, 1.0]])
    with pytest.raises(AssociationError):        # per-track points for 3 tracks, 2 tracks
        mahalanobis_matrix([[0, 0], [1, 1]], [np.eye(2)] * 2, np.zeros((3, 1, 2)))
    with pytest.raises(AssociationError):        # points of 3 coordinates
        mahalanobis_matrix([[0, 0]], [np.eye(2)], np.zeros((1, 2, 3)))


def test_min_iou_boundary_is_inclusive():
    # track x 0..10, y 0..10 (100); detection x 0..10, y 0..5 (50): IoU = 50 / 100 = 0.5
    t = np.array([[0, 0, 10, 10]], float)
    d = np.array([[0, 0, 10, 5]], float)
    at = association_cost(t, d, np.zeros((1, 1)), AssociationConfig(overlap_weight=0.5,
                                                                     min_iou=0.5))
    assert at[0, 0] == pytest.approx(0.5 * 0.5)
    above = association_cost(t, d, np.zeros((1, 1)), AssociationConfig(min_iou=0.5000001))
    assert math.isinf(above[0, 0])


def test_gate_boundary_is_inclusive():
    # d2 == gate is inside (distance term 1); just above is forbidden.  IoU 1 (same box).
    cfg = AssociationConfig(overlap_weight=0.4, gate=9.0)
    t = np.array([[0, 0, 4, 8]], float)
    cost = association_cost(t, t, np.array([[9.0]]), cfg)
    assert cost[0, 0] == pytest.approx(0.6)
    assert math.isinf(association_cost(t, t, np.array([[9.000001]]), cfg)[0, 0])


def test_extra_cost_is_added_and_does_not_open_forbidden_pairs():
    # IoU (0,0,10,10) vs (5,0,10,10) = 1/3; d2 = 2 of gate 8.
    # base = 0.5 * (2/3) + 0.5 * (2/8) = 1/3 + 1/8 = 11/24
    cfg = AssociationConfig(overlap_weight=0.5, gate=8.0)
    t = np.array([[0, 0, 10, 10], [50, 50, 10, 10]], float)
    d = np.array([[5, 0, 10, 10]], float)
    maha = np.array([[2.0], [100.0]])
    extra = np.array([[0.25], [-5.0]])
    cost = association_cost(t, d, maha, cfg, extra_cost=extra)
    assert cost[0, 0] == pytest.approx(11.0 / 24.0 + 0.25)
    assert math.isinf(cost[1, 0])                      # outside the gate whatever the extra
    with pytest.raises(AssociationError):
        association_cost(t, d, maha, cfg, extra_cost=np.zeros((1, 2)))


def test_cost_with_per_track_detection_boxes():
    # track 0 sees the detection at x 0..4, y 0..2 (its own box: IoU 1);
    # track 1 (x 0..2, y 0..2, area 4) sees it at x 1..5, y 0..2 (area 8):
    # overlap x 1..2 -> 2, union 4 + 8 - 2 = 10, IoU 0.2
    cfg = AssociationConfig(overlap_weight=1.0)
    t = np.array([[0, 0, 4, 2], [0, 0, 2, 2]], float)
    d = np.array([[[0, 0, 4, 2]], [[1, 0, 4, 2]]], float)
    cost = association_cost(t, d, np.zeros((2, 1)), cfg)
    np.testing.assert_allclose(cost, [[0.0], [0.8]], atol=1e-12)
    empty = association_cost(np.zeros((0, 4)), np.zeros((0, 3, 4)), np.zeros((0, 3)), cfg)
    assert empty.shape == (0, 3)
    with pytest.raises(AssociationError):              # boxes for 3 tracks, 2 tracks
        association_cost(t, np.zeros((3, 1, 4)), np.zeros((2, 1)), cfg)


def test_cost_rejects_mismatched_or_nan_distances():
    cfg = AssociationConfig()
    t = np.array([[0, 0, 4, 2]], float)
    d = np.array([[0, 0, 4, 2], [1, 1, 2, 2]], float)
    with pytest.raises(AssociationError):
        association_cost(t, d, np.zeros((1, 3)), cfg)
    with pytest.raises(AssociationError):
        association_cost(t, d, np.array([[0.0, np.nan]]), cfg)


def test_assign_keeps_a_pair_whose_cost_equals_max_cost():
    a = assign(np.array([[0.85, np.inf], [np.inf, 0.8500001]]), max_cost=0.85)
    assert a.matches == [(0, 0)]
    assert a.unmatched_rows == [1] and a.unmatched_cols == [1]


def test_assign_never_matches_an_impossible_pair_even_without_a_cost_limit():
    a = assign(np.array([[np.inf, 1.0], [np.inf, np.inf]]), max_cost=math.inf)
    assert a.matches == [(0, 1)]
    assert a.unmatched_rows == [1] and a.unmatched_cols == [0]
    with pytest.raises(AssociationError):
        assign(np.zeros(3), max_cost=1.0)


def _message(call):
    with pytest.raises(AssociationError) as info:
        call()
    return str(info.value)


def test_error_messages_say_what_does_not_fit():
    eye = np.eye(2)
    assert _message(lambda: mahalanobis_matrix([[0, 0], [1, 1], [2, 2]], [eye],
                                               [[1.0, 1.0]])) == "3 centres but 1 covariances"
    assert _message(lambda: mahalanobis_matrix([[0, 0], [1, 1], [2, 2]], [eye] * 3,
                                               np.zeros((4, 1, 2)))) == \
        "points of shape (4, 1, 2) do not fit 3 tracks"
    assert _message(lambda: mahalanobis_matrix([[0, 0]], [np.zeros((2, 2))], [[1.0, 1.0]])) \
        == "an innovation covariance is not positive definite"
    cfg = AssociationConfig()
    t = np.array([[0, 0, 4, 2], [1, 1, 2, 2]], float)
    d = np.array([[0, 0, 4, 2]] * 3, float)
    assert _message(lambda: association_cost(t, d, np.zeros((2, 2)), cfg)) == \
        "Mahalanobis matrix (2, 2) does not match 2 tracks x 3 detections"
    assert _message(lambda: association_cost(t, np.zeros((3, 3, 4)), np.zeros((2, 3)),
                                             cfg)) == \
        "per-track detection boxes do not match the tracks"
    assert _message(lambda: association_cost(t, d, np.full((2, 3), np.nan), cfg)) == \
        "Mahalanobis matrix has NaN values"
    assert _message(lambda: association_cost(t, d, np.zeros((2, 3)), cfg,
                                             extra_cost=np.zeros((3, 2)))) == \
        "extra cost (3, 2) does not match (2, 3)"
    assert _message(lambda: assign(np.zeros(3), 1.0)) == "cost must be a matrix, got shape (3,)"
    assert _message(lambda: assign(np.array([[0.0, np.nan]]), 1.0)) == \
        "cost matrix has NaN values"


def test_a_single_detection_box_may_be_given_flat():
    # one detection as (4,) instead of (1, 4): track x 0..4, y 0..2; detection x 2..6:
    # overlap 2 x 2 = 4, union 8 + 8 - 4 = 12, IoU 1/3; overlap weight 1 -> cost 2/3
    cfg = AssociationConfig(overlap_weight=1.0)
    cost = association_cost(np.array([[0, 0, 4, 2]], float), np.array([2, 0, 4, 2], float),
                            np.zeros((1, 1)), cfg)
    np.testing.assert_allclose(cost, [[2.0 / 3.0]], atol=1e-12)


def test_near_singular_covariance_is_inverted_in_float64():
    # S = [[a, 1], [1, a]], a = 1 + 2^-12, residual (1, -1):
    # d2 = (a + 2 + a) / (a^2 - 1) = 2 / (a - 1) = 2^13 exactly.  In float32 the
    # determinant loses its 2^-24 term and d2 would come out as 8193.
    a = 1.0 + 2.0 ** -12
    s = np.array([[[a, 1.0], [1.0, a]]], np.float32)
    d = mahalanobis_matrix([[0.0, 0.0]], s, [[1.0, -1.0]])
    assert d[0, 0] == pytest.approx(8192.0, rel=1e-9)


def test_float32_distances_are_used_in_float64():
    # d2 = 1 (exact in float32) over gate 3: distance term 1/3 in float64 arithmetic;
    # same box so the overlap term is 0; weight 0 -> cost exactly 1/3 in float64
    cfg = AssociationConfig(overlap_weight=0.0, gate=3.0)
    t = np.array([[0, 0, 4, 2]], float)
    cost = association_cost(t, t, np.array([[1.0]], np.float32), cfg)
    assert cost[0, 0] == 1.0 / 3.0


# -- size validation gate (association.max_height_ratio) -------------------------------------

def test_height_ratio_gate_is_symmetric_in_log_and_off_at_zero():
    from mk_tracker.tracking.association import height_ratio_exceeded
    # track 100 px, ratio 1.4: 71.4 .. 140 px pass, 70 and 141 do not
    out = height_ratio_exceeded([100.0], [100.0, 139.0, 141.0, 72.0, 70.0], 1.4)
    assert out.tolist() == [[False, False, True, False, True]]
    assert not height_ratio_exceeded([100.0], [10.0, 1000.0], 0.0).any()     # off
    per_track = height_ratio_exceeded([50.0, 100.0], [[50.0, 100.0], [50.0, 100.0]], 1.4)
    assert per_track.tolist() == [[False, True], [True, False]]
    # a box that cannot be a person is outside the gate, without stopping the frame
    bad = height_ratio_exceeded([100.0, 0.0], [0.0, 100.0, np.nan, -5.0], 1.4)
    assert bad.tolist() == [[True, False, True, True], [True, True, True, True]]


def test_height_ratio_below_one_is_refused_not_read_as_off():
    from mk_tracker.parameters import ParameterError, updated
    for bad in (0.5, 0.999):
        with pytest.raises(ParameterError, match="max_height_ratio"):
            AssociationConfig(max_height_ratio=bad)
        with pytest.raises(ParameterError, match="max_height_ratio"):
            updated(AssociationConfig(), {"max_height_ratio": bad})
    assert AssociationConfig(max_height_ratio=0.0).max_height_ratio == 0.0
    assert AssociationConfig(max_height_ratio=1.0).max_height_ratio == 1.0


def test_height_ratio_gate_forbids_the_pair_and_leaves_others_alone():
    t = np.array([[0, 0, 30, 60], [100, 0, 30, 60]], float)
    # an upper-body box on track 0 (same top, 28 px high) and a whole-body one on track 1
    d = np.array([[0, 0, 30, 28], [100, 0, 30, 62]], float)
    maha = np.zeros((2, 2))
    off = association_cost(t, d, maha, AssociationConfig())
    on = association_cost(t, d, maha, AssociationConfig(max_height_ratio=1.4))
    assert math.isfinite(off[0, 0]) and math.isinf(on[0, 0])
    assert on[1, 1] == pytest.approx(off[1, 1])
    assert assign(on, 0.85).matches == [(1, 1)]
    # per-track (time-compensated) boxes are gated by their own heights
    on3 = association_cost(t, np.stack([d, d]), maha, AssociationConfig(max_height_ratio=1.4))
    assert np.array_equal(np.isinf(on3), np.isinf(on))
