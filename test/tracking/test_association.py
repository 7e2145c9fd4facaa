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
