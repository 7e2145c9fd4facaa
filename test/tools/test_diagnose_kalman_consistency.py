"""benchmarks/diagnose_kalman_consistency.py: the NIS of the tracker's Kalman filter."""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import diagnose_kalman_consistency as diag  # noqa: E402
from mk_tracker.kalman import KalmanConfig  # noqa: E402
from mk_tracker.tracking.track import LifecycleConfig  # noqa: E402


def _walkers(noise_h, n=150, frames=25, seed=0):
    """Straight constant-velocity walkers 100 px tall, centres measured with an i.i.d.
    error of ``noise_h`` box heights."""
    rng = np.random.default_rng(seed)
    series = {}
    for i in range(n):
        v = rng.normal(0.0, 2.0, 2)           # px per frame
        track = []
        for k in range(frames):
            cx, cy = 300 + v[0] * k + rng.normal(0, noise_h * 100), \
                200 + v[1] * k + rng.normal(0, noise_h * 100)
            track.append((k, (cx - 20.0, cy - 50.0, 40.0, 100.0)))
        series[i] = track
    return series


def test_a_filter_whose_noise_is_the_true_noise_has_mean_nis_two():
    life = LifecycleConfig(measurement_noise=0.02)
    kw = dict(sigma_u=0.0, process_noise=1e-4, lifecycle=life, kalman=KalmanConfig(),
              burn_in=3)
    right = [v for v, _ in diag.nis_samples(_walkers(0.02), 25.0, **kw)]
    assert np.mean(right) == pytest.approx(2.0, abs=0.2)
    # detections that err twice as much as the filter assumes: about 4x the NIS
    wrong = [v for v, _ in diag.nis_samples(_walkers(0.04), 25.0, **kw)]
    assert np.mean(wrong) > 6.0
    assert all(h == 100.0 for _, h in diag.nis_samples(_walkers(0.02, n=2), 25.0, **kw))


def test_missing_measurements_are_predicted_over_and_not_counted():
    kw = dict(sigma_u=30.0, process_noise=0.0, lifecycle=LifecycleConfig(),
              kalman=KalmanConfig(), burn_in=1)
    box = (0.0, 0.0, 40.0, 100.0)
    full = {1: [(k, box) for k in range(6)]}
    gappy = {1: [(k, box if k % 2 == 0 else None) for k in range(6)]}
    assert len(diag.nis_samples(full, 25.0, **kw)) == 5
    assert len(diag.nis_samples(gappy, 25.0, **kw)) == 2


def test_detections_are_matched_to_the_truth_by_iou():
    truth = [{1: (0, 0, 40, 100), 2: (200, 0, 40, 100)}]
    dets = [[(202, 2, 40, 100), (100, 300, 40, 100), (5, 60, 40, 100)]]
    (frame,) = diag.matched_series(truth, dets)
    assert frame == {2: (202.0, 2.0, 40.0, 100.0)}       # the shifted one is below IoU 0.5
    series = diag.identity_series([frame], truth)
    assert series == {1: [(0, None)], 2: [(0, (202.0, 2.0, 40.0, 100.0))]}


def test_the_adaptive_measurement_noise_restores_consistency_and_never_lowers_the_model():
    life = LifecycleConfig(measurement_noise=0.02)
    kw = dict(sigma_u=0.0, process_noise=1e-4, lifecycle=life, kalman=KalmanConfig(),
              burn_in=10)
    # detections that err twice as much as the model: the fixed filter is near 4x over,
    # the covariance-matched one near 2 (consistent)
    fixed = np.mean([v for v, _ in diag.nis_samples(_walkers(0.04), 25.0, **kw)])
    adapted = np.mean([v for v, _ in diag.nis_samples(_walkers(0.04), 25.0,
                                                      adaptive_weight=0.1, **kw)])
    assert fixed > 6.0
    assert 1.5 < adapted < 3.0
    # detections as exact as the model: the floor keeps the std, the NIS stays about 2
    exact = np.mean([v for v, _ in diag.nis_samples(_walkers(0.02), 25.0,
                                                    adaptive_weight=0.1, **kw)])
    assert exact == pytest.approx(2.0, abs=0.3)
