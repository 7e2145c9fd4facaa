"""Tests of the constant-velocity Kalman filter against hand-computed steps."""

import math

import numpy as np
import pytest

from mk_tracker.kalman import (ConstantVelocityKalman, KalmanConfig, KalmanError,
                               process_noise, transition_matrix)
from mk_tracker.parameters import ParameterError, parameter_specs


def test_transition_matrix_is_2_2():
    a = transition_matrix(0.5)
    expected = np.array([[1, 0, 0.5, 0], [0, 1, 0, 0.5], [0, 0, 1, 0], [0, 0, 0, 1]], float)
    np.testing.assert_array_equal(a, expected)


def test_process_noise_is_2_3():
    q = process_noise(2.0, 3.0)
    # sigma_u^2 = 9; dt^3/3 = 8/3, dt^2/2 = 2, dt = 2
    expected = 9.0 * np.array([[8 / 3, 0, 2, 0], [0, 8 / 3, 0, 2],
                               [2, 0, 2, 0], [0, 2, 0, 2]])
    np.testing.assert_allclose(q, expected, rtol=1e-12)


@pytest.mark.parametrize("dt", [0.0, -0.1, float("nan"), float("inf"), "x", None])
def test_bad_time_step_is_a_kalman_error(dt):
    with pytest.raises(KalmanError):
        transition_matrix(dt)
    kf = ConstantVelocityKalman((0, 0))
    with pytest.raises(KalmanError):
        kf.predict(dt)
    with pytest.raises(ValueError):  # KalmanError is a ValueError
        kf.predicted(dt)


def _filter():
    return ConstantVelocityKalman((10.0, 20.0), sigma_u=1.0, sigma_w=2.0,
                                  initial_position_var=4.0, initial_velocity_var=100.0)


def test_predict_step_by_hand():
    kf = _filter()
    s = kf.predict(1.0)
    np.testing.assert_allclose(s, [10, 20, 0, 0])
    p = kf.covariance
    # A P A^T = [[4+100, 100], [100, 100]] per axis, plus Q = [[1/3, 1/2], [1/2, 1]]
    assert p[0, 0] == pytest.approx(104 + 1 / 3)
    assert p[0, 2] == pytest.approx(100.5)
    assert p[2, 2] == pytest.approx(101.0)
    assert p[0, 1] == pytest.approx(0.0)
    assert p[1, 1] == pytest.approx(104 + 1 / 3)


def test_update_step_by_hand():
    kf = _filter()
    kf.predict(1.0)
    s = kf.update((12.0, 20.0))
    # S = 313/3 + 4 = 325/3; gains 313/325 (position) and 301.5/325 (velocity)
    assert s[0] == pytest.approx(10 + 2 * 313 / 325)
    assert s[2] == pytest.approx(2 * 301.5 / 325)
    assert s[1] == pytest.approx(20.0)
    assert s[3] == pytest.approx(0.0)
    p = kf.covariance
    assert p[0, 0] == pytest.approx(4 * 313 / 325)
    assert p[0, 2] == pytest.approx(100.5 * 12 / 325)
    assert p[2, 2] == pytest.approx(101 - 3 * 100.5 ** 2 / 325)


def test_per_call_sigma_w_changes_the_gain_only_for_that_call():
    a, b = _filter(), _filter()
    a.predict(1.0)
    b.predict(1.0)
    a.update((12.0, 20.0), sigma_w=10.0)
    b.update((12.0, 20.0))
    # with sigma_w = 10: S = 313/3 + 100, gain = (313/3) / (613/3)
    assert a.state[0] == pytest.approx(10 + 2 * 313 / 613)
    assert a.sigma_w == 2.0
    assert b.state[0] > a.state[0]


def test_predicted_does_not_change_the_filter_and_velocity_moves_the_state():
    kf = ConstantVelocityKalman((0.0, 0.0), initial_velocity=(10.0, -4.0))
    before = kf.covariance
    s, p = kf.predicted(0.1)
    np.testing.assert_allclose(s, [1.0, -0.4, 10.0, -4.0])
    np.testing.assert_array_equal(kf.state, [0.0, 0.0, 10.0, -4.0])
    np.testing.assert_array_equal(kf.covariance, before)
    assert p[0, 0] > before[0, 0]


def test_innovation_distance_by_hand():
    kf = _filter()
    # P = 4 I on position, sigma_w = 2: S = 8 I; residual (4, 0) -> 16/8 = 2
    assert kf.innovation_distance((14.0, 20.0)) == pytest.approx(2.0)
    assert kf.innovation_distance((10.0, 20.0)) == pytest.approx(0.0)
    # per-call sigma_w: S = (4 + 16) I -> 16/20
    assert kf.innovation_distance((14.0, 20.0), sigma_w=4.0) == pytest.approx(0.8)


@pytest.mark.parametrize("z", [(float("nan"), 1.0), (1.0, float("inf")), (1.0,), "ab", None])
def test_bad_measurement_is_rejected_without_corrupting_the_state(z):
    kf = _filter()
    kf.predict(1.0)
    state, cov = kf.state, kf.covariance
    with pytest.raises(KalmanError):
        kf.update(z)
    np.testing.assert_array_equal(kf.state, state)
    np.testing.assert_array_equal(kf.covariance, cov)


def test_bad_noise_levels_are_rejected():
    with pytest.raises(KalmanError):
        ConstantVelocityKalman((0, 0), sigma_w=0.0)
    with pytest.raises(KalmanError):
        ConstantVelocityKalman((0, 0), sigma_u=-1.0)
    with pytest.raises(KalmanError):
        ConstantVelocityKalman((math.nan, 0))
    with pytest.raises(KalmanError):
        _filter().update((1, 1), sigma_w=float("nan"))


def test_constant_velocity_track_converges_to_the_true_velocity():
    kf = ConstantVelocityKalman((0.0, 0.0), sigma_u=1.0, sigma_w=1.0)
    rng = np.random.default_rng(0)
    dt = 1 / 30
    for k in range(1, 200):
        kf.predict(dt)
        kf.update(np.array([30.0, -15.0]) * k * dt + rng.normal(0, 1.0, 2))
    np.testing.assert_allclose(kf.velocity, [30.0, -15.0], atol=3.0)


def test_config_is_declared_and_used():
    names = {s.name for s in parameter_specs(KalmanConfig)}
    assert names == {"sigma_u", "sigma_w", "initial_position_var", "initial_velocity_var"}
    kf = ConstantVelocityKalman.from_config((1, 2), KalmanConfig(sigma_w=5.0,
                                                                 initial_position_var=9.0))
    assert kf.sigma_w == 5.0
    assert kf.covariance[0, 0] == 9.0
    with pytest.raises(ParameterError):
        ConstantVelocityKalman.from_config((1, 2), KalmanConfig(sigma_w=-1.0))


def test_repeated_step_uses_the_same_matrices_and_they_cannot_be_changed():
    """Objects predicted over the same dt share A and Sigma_u (cached per step): the second
    filter's prediction equals the formulas (4.2)-(4.3) written out, and the shared matrices
    are read-only."""
    from mk_tracker.kalman import _step_matrices, process_noise, transition_matrix
    first, second = _filter(), ConstantVelocityKalman((3.0, -2.0), sigma_u=1.5,
                                                      initial_velocity=(4.0, 1.0))
    first.predict(0.25)
    cov = second.covariance
    state, pred_cov = second.predicted(0.25)
    a, q = transition_matrix(0.25), process_noise(0.25, 1.5)
    np.testing.assert_allclose(state, [4.0, -1.75, 4.0, 1.0])
    np.testing.assert_allclose(pred_cov, a @ cov @ a.T + q)
    cached_a, _ = _step_matrices(0.25, 1.5)
    with pytest.raises(ValueError):
        cached_a[0, 2] = 1.0


@pytest.mark.parametrize("z", [
    (float("nan"), 1.0), (1.0, float("nan")),          # the tuple-of-floats fast path
    (float("inf"), 1.0), (1.0, float("-inf")),
    [float("nan"), 1.0], np.array([1.0, np.nan]),      # the general path
    (1.0, 2.0, 3.0), (1.0,),
])
def test_innovation_distance_rejects_a_bad_measurement(z):
    # a NaN in one coordinate must not come out as a NaN distance (it would fail every
    # gate comparison silently)
    kf = _filter()
    with pytest.raises(KalmanError):
        kf.innovation_distance(z)


def test_innovation_distance_with_correlated_covariance_by_hand():
    # predict/update from a diagonal start never correlate x and y (the model is separable),
    # so the correlated covariance is set directly
    kf = _filter()
    kf._cov = np.array([[4.0, 1.0, 0, 0], [1.0, 2.0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
    # S = [[4, 1], [1, 2]] + 4 I = [[8, 1], [1, 6]], det 47, S^-1 = [[6, -1], [-1, 8]] / 47
    # residual (2, 1): (6 * 4 - 2 * 1 * 2 * 1 + 8 * 1) / 47 = 28 / 47
    assert kf.innovation_distance((12.0, 21.0)) == pytest.approx(28.0 / 47.0)
    # residual (2, -1): (24 + 4 + 8) / 47 = 36 / 47
    assert kf.innovation_distance((12.0, 19.0)) == pytest.approx(36.0 / 47.0)
    np.testing.assert_allclose(kf.innovation_covariance(), [[8.0, 1.0], [1.0, 6.0]])
    # per-call sigma_w = 1: S = [[5, 1], [1, 3]]
    np.testing.assert_allclose(kf.innovation_covariance(1.0), [[5.0, 1.0], [1.0, 3.0]])


def test_update_with_correlated_covariance_by_hand():
    # P = [[4, 1, 0, 0], [1, 2, 0, 0], 0, diag(1, 1)] and sigma_w = 2: S = [[8, 1], [1, 6]],
    # S^-1 = [[6, -1], [-1, 8]] / 47; gain (position rows) = P_pos S^-1
    # = [[4, 1], [1, 2]] [[6, -1], [-1, 8]] / 47 = [[23, 4], [4, 15]] / 47; velocity rows 0
    kf = _filter()
    kf._cov = np.array([[4.0, 1.0, 0, 0], [1.0, 2.0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
    s = kf.update((12.0, 21.0))                  # residual (2, 1)
    # x: 10 + (23 * 2 + 4 * 1) / 47 = 10 + 50/47; y: 20 + (4 * 2 + 15 * 1) / 47 = 20 + 23/47
    np.testing.assert_allclose(s, [10 + 50 / 47, 20 + 23 / 47, 0.0, 0.0])
    # P_pos - G P_pos = [[4, 1], [1, 2]] - [[23, 4], [4, 15]] [[4, 1], [1, 2]] / 47
    # G P = [[96, 31], [31, 34]] / 47 -> [[92/47, 16/47], [16/47, 60/47]]
    np.testing.assert_allclose(kf.covariance[:2, :2],
                               np.array([[92.0, 16.0], [16.0, 60.0]]) / 47.0)
    np.testing.assert_allclose(kf.covariance[2:, 2:], np.eye(2))


def test_update_with_a_covariance_that_is_not_positive_definite_is_refused():
    kf = _filter()
    kf._cov = np.diag([-4.0, 1.0, 1.0, 1.0])      # S = diag(0, 5): singular
    state = kf.state
    with pytest.raises(KalmanError):
        kf.update((12.0, 21.0))
    np.testing.assert_array_equal(kf.state, state)
    kf._cov = np.diag([1.0, 1.0, np.inf, 1.0])    # finite S, but the new covariance is not
    with pytest.raises(KalmanError):
        kf.update((12.0, 21.0))
    np.testing.assert_array_equal(kf.state, state)


def test_step_matrix_cache_is_bounded_and_keyed_by_sigma_u():
    from mk_tracker.kalman import _STEP_MATRICES, _step_matrices
    a1, q1 = _step_matrices(0.5, 1.0)
    a2, q2 = _step_matrices(0.5, 2.0)
    np.testing.assert_allclose(q2, 4.0 * q1)          # sigma_u doubled: Q times 4
    for k in range(40):
        _step_matrices(1.0 + k, 1.0)
    assert len(_STEP_MATRICES) <= 16


def _error(call):
    with pytest.raises(KalmanError) as info:
        call()
    return str(info.value)


def test_error_messages_name_the_value_and_what_is_wrong():
    """A caller (or a node's log) learns which input was refused and why."""
    K = ConstantVelocityKalman
    assert _error(lambda: transition_matrix("x")) == "time step 'x' is not a number"
    assert _error(lambda: transition_matrix(-1)) == \
        "time step must be a positive finite number of seconds, got -1"
    assert _error(lambda: process_noise(1.0, -1)) == \
        "sigma_u must be a finite non-negative number, got -1"
    assert _error(lambda: K((0, 0), sigma_u="a")) == "sigma_u 'a' is not a number"
    assert _error(lambda: K((0, 0), sigma_u=-2)) == \
        "sigma_u must be a finite non-negative number, got -2"
    assert _error(lambda: K((0, 0), sigma_w=0)) == \
        "sigma_w must be a finite positive number, got 0"
    assert _error(lambda: K((0, 0), initial_position_var=0)) == \
        "initial_position_var must be a finite positive number, got 0"
    assert _error(lambda: K((0, 0), initial_velocity_var=0)) == \
        "initial_velocity_var must be a finite positive number, got 0"
    assert _error(lambda: K((math.nan, 0.0))) == "center [nan, 0.0] has a NaN or infinite value"
    assert _error(lambda: K([0.0, math.inf])) == "center [0.0, inf] has a NaN or infinite value"
    assert _error(lambda: K(("x", 1.0))) == "center ('x', 1.0) is not two numbers"
    assert _error(lambda: K((0, 0), initial_velocity=(1.0,))) == \
        "initial_velocity must have two values (x, y), got 1"
    kf = _filter()
    assert _error(lambda: kf.innovation_distance((math.nan, 1.0))) == \
        "measurement [nan, 1.0] has a NaN or infinite value"
    assert _error(lambda: kf.update([1.0, 2.0, 3.0])) == \
        "measurement must have two values (x, y), got 3"
    assert _error(lambda: kf.update((1.0, 1.0), sigma_w=0)) == \
        "sigma_w must be a finite positive number, got 0"


@pytest.mark.parametrize("z, reason", [(("x", 1.0), "is not two numbers"),
                                       ((1.0, "x"), "is not two numbers"),
                                       ((1.0, None), "NaN"),      # numpy reads None as NaN
                                       ((None, 1.0), "NaN")])
def test_a_tuple_with_a_non_number_is_a_kalman_error(z, reason):
    kf = _filter()
    with pytest.raises(KalmanError, match=reason):
        kf.update(z)
    with pytest.raises(KalmanError, match=reason):
        kf.innovation_distance(z)


def test_points_may_be_given_in_any_two_number_shape():
    # a tuple of ints, a list, a (2, 1) column and a (1, 2) row are all the point (12, 21)
    for z in [(12, 21), [12.0, 21.0], np.array([[12.0], [21.0]]), np.array([[12.0, 21.0]]),
              (12.0, 21)]:
        kf = _filter()
        # P = 4 I, sigma_w = 2: S = 8 I; residual (2, 1): (4 + 1) / 8
        assert kf.innovation_distance(z) == pytest.approx(5.0 / 8.0)


def test_zero_process_noise_is_allowed_but_zero_variances_are_not():
    kf = ConstantVelocityKalman((0.0, 0.0), sigma_u=0.0, initial_position_var=1.0,
                                initial_velocity_var=1.0)
    # no process noise: P(t|t-1) = A P A^T only: position var 1 + dt^2 * 1 = 5 at dt = 2
    kf.predict(2.0)
    assert kf.covariance[0, 0] == pytest.approx(5.0)
    np.testing.assert_array_equal(process_noise(1.0, 0.0), np.zeros((4, 4)))
    with pytest.raises(KalmanError):
        ConstantVelocityKalman((0, 0), initial_position_var=0.0)
    with pytest.raises(KalmanError):
        ConstantVelocityKalman((0, 0), initial_velocity_var=0.0)


def test_small_noise_levels_below_one_are_valid():
    # P = 0.1 I, sigma_w = 0.1: S = 0.11 I (det 0.0121 < 1), gain 0.1 / 0.11 = 10/11
    kf = ConstantVelocityKalman((10.0, 20.0), sigma_u=0.5, sigma_w=0.1,
                                initial_position_var=0.1, initial_velocity_var=0.5)
    assert kf.sigma_u == 0.5 and kf.sigma_w == 0.1
    s = kf.update((12.0, 20.0))
    assert s[0] == pytest.approx(10.0 + 2.0 * 10.0 / 11.0)
    s = _filter().update((12.0, 20.0), sigma_w=0.5)      # S = 4 + 0.25: gain 4 / 4.25
    assert s[0] == pytest.approx(10.0 + 2.0 * 4.0 / 4.25)


def test_an_infinite_innovation_covariance_is_refused_before_the_gain():
    kf = _filter()
    kf._cov = np.diag([np.inf, 1.0, 1.0, 1.0])
    assert _error(lambda: kf.update((12.0, 21.0))) == \
        "innovation covariance is not positive definite; filter left unchanged"
    kf._cov = np.diag([-4.0, 1.0, 1.0, 1.0])          # S = diag(0, 5): det exactly 0
    with pytest.raises(KalmanError, match="not positive definite"):
        kf.update((12.0, 21.0))
    kf._cov = np.diag([1.0, 1.0, np.inf, 1.0])
    assert _error(lambda: kf.update((12.0, 21.0))) == \
        "update produced a non-finite state; filter left unchanged"


def test_from_config_passes_every_setting():
    cfg = KalmanConfig(sigma_u=7.0, sigma_w=3.0, initial_position_var=9.0,
                       initial_velocity_var=16.0)
    kf = ConstantVelocityKalman.from_config((1.0, 2.0), cfg, initial_velocity=(3.0, -1.0))
    assert (kf.sigma_u, kf.sigma_w) == (7.0, 3.0)
    np.testing.assert_array_equal(np.diag(kf.covariance), [9.0, 9.0, 16.0, 16.0])
    np.testing.assert_array_equal(kf.state, [1.0, 2.0, 3.0, -1.0])


def test_step_matrices_are_shared_read_only_and_at_most_16():
    from mk_tracker.kalman import _STEP_MATRICES, _step_matrices
    a, q = _step_matrices(0.125, 3.0)
    again = _step_matrices(0.125, 3.0)
    assert again[0] is a and again[1] is q                 # served from the cache
    with pytest.raises(ValueError):
        q[0, 0] = 1.0
    sizes = []
    for k in range(40):
        _step_matrices(2.0 + k, 1.0)
        sizes.append(len(_STEP_MATRICES))
    assert max(sizes) == 16


def test_update_keeps_variances_non_negative_across_24_decades():
    # found by the property test's dev profile (after the Joseph form): position variance
    # 1e-9, velocity variance 1e12, sigma_u 0, sigma_w 1e-6, one 4.75 s step.  By hand:
    # P(t|t-1)_pp = 1e-9 + 4.75^2 1e12 = 2.25625e13, P_pv = 4.75e12, P_vv = 1e12, r = 1e-12;
    # posterior P_pp = r P_pp / (P_pp + r) = 1e-12 (to 1e-25), P_vv = P_vv (1e-9 + r) /
    # (P_pp + r) = 4.4e-17, which double precision cannot resolve next to entries of 2e13
    # (eps * 2.26e13 = 5e-3): the Joseph form alone left it at -1.2e-4
    kf = ConstantVelocityKalman((0.0, 0.0), sigma_u=0.0, sigma_w=1e-6,
                                initial_position_var=1e-9, initial_velocity_var=1e12)
    kf.predict(4.75)
    kf.update((0.0, 0.0))
    cov = kf.covariance
    assert np.all(np.diag(cov) >= 0.0)
    np.testing.assert_allclose(np.diag(cov)[:2], [1e-12, 1e-12], rtol=1e-6)
    assert np.all(np.diag(cov)[2:] <= 5e-3)
    np.testing.assert_array_equal(cov, cov.T)


def test_negative_variances_from_rounding_are_clipped_to_the_nearest_psd_matrix():
    from mk_tracker.kalman import _positive_semidefinite
    ok = np.diag([4.0, 4.0, 1.0, 1.0])
    assert _positive_semidefinite(ok) is ok        # the usual case is not touched
    # eigenvalues of [[1, 2], [2, 1]] are 3 and -1 (vectors (1, 1)/sqrt2, (1, -1)/sqrt2):
    # clipping -1 leaves 3 (1, 1)(1, 1)^T / 2 = [[1.5, 1.5], [1.5, 1.5]]
    bad = np.zeros((4, 4))
    bad[:2, :2] = [[1.0, 2.0], [2.0, 1.0]]
    bad[2, 2], bad[3, 3] = -1e-6, 5.0
    out = _positive_semidefinite(bad)
    np.testing.assert_allclose(out[:2, :2], [[1.5, 1.5], [1.5, 1.5]], atol=1e-12)
    np.testing.assert_allclose(np.diag(out)[2:], [0.0, 5.0], atol=1e-12)


# -- warp (camera-motion compensation, tracking/camera_motion.py) ---------------------
def test_kalman_warp_moves_mean_and_covariance_by_hand():
    kf = ConstantVelocityKalman((10.0, 20.0), initial_velocity=(3.0, -1.0),
                                initial_position_var=4.0, initial_velocity_var=1.0)
    kf._cov[0, 2] = kf._cov[2, 0] = 0.5          # x position - x velocity covariance
    kf._cov[1, 1], kf._cov[3, 3] = 9.0, 2.0
    # a quarter turn (x, y) -> (-y, x) and a shift (5, -7)
    kf.warp([[0.0, -1.0], [1.0, 0.0]], (5.0, -7.0))
    # mean: (-20 + 5, 10 - 7) and velocity (1, 3)
    np.testing.assert_allclose(kf.state, [-15.0, 3.0, 1.0, 3.0])
    # P = diag(4, 9, 1, 2) + 0.5 at (x, vx): the axes swap, the x terms become y terms
    expected = np.array([[9.0, 0.0, 0.0, 0.0], [0.0, 4.0, 0.0, 0.5],
                         [0.0, 0.0, 2.0, 0.0], [0.0, 0.5, 0.0, 1.0]])
    np.testing.assert_allclose(kf.covariance, expected, atol=1e-12)


def test_kalman_warp_with_scale_scales_velocity_and_covariance():
    kf = ConstantVelocityKalman((10.0, 20.0), initial_velocity=(3.0, -1.0),
                                initial_position_var=4.0, initial_velocity_var=1.0)
    kf.warp([[2.0, 0.0], [0.0, 2.0]], (1.0, 1.0))
    np.testing.assert_allclose(kf.state, [21.0, 41.0, 6.0, -2.0])
    np.testing.assert_allclose(np.diag(kf.covariance), [16.0, 16.0, 4.0, 4.0])


@pytest.mark.parametrize("lin,shift", [([[1, 0], [0, float("nan")]], (0, 0)),
                                       ([[1, 0], [0, 1]], (float("inf"), 0)),
                                       ([1, 2, 3], (0, 0))])
def test_kalman_warp_refuses_bad_input_and_leaves_the_filter(lin, shift):
    kf = ConstantVelocityKalman((10.0, 20.0))
    before = kf.state, kf.covariance
    with pytest.raises(KalmanError):
        kf.warp(lin, shift)
    np.testing.assert_array_equal(kf.state, before[0])
    np.testing.assert_array_equal(kf.covariance, before[1])
