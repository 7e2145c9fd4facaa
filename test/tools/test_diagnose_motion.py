"""benchmarks/diagnose_motion.py's statistics on tracks whose answer is known in closed form."""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import diagnose_motion as dm  # noqa: E402


def _track(centres, h=100.0):
    c = np.asarray(centres, float)
    boxes = np.column_stack([c[:, 0] - 20.0, c[:, 1] - h / 2, np.full(len(c), 40.0),
                             np.full(len(c), h)])
    return np.arange(len(c)), boxes


def test_constant_velocity_has_no_drift_and_no_acceleration():
    t = np.arange(100.0)
    stats = dm.motion_statistics({1: _track(np.column_stack([3.0 * t, 1.0 * t + 50]))}, 25.0)
    assert stats["speed"] == pytest.approx(np.full(99, np.hypot(3.0, 1.0) * 25 / 100))
    assert np.abs(stats["accel"]).max() < 1e-9
    for t_ahead in dm.HORIZONS:
        assert len(stats["drift"][t_ahead]) > 0
        assert np.abs(stats["drift"][t_ahead]).max() < 1e-9


def test_constant_acceleration_drifts_by_the_closed_form():
    # x = a t^2 / 2 (px, frames): the velocity over the last l frames is a (k - l/2), so
    # m frames ahead the extrapolation misses by a m (m + l) / 2 px
    a, fps, h = 0.02, 25.0, 100.0
    t = np.arange(200.0)
    stats = dm.motion_statistics({7: _track(np.column_stack([a * t ** 2 / 2, 0 * t]), h)},
                                 fps, window=0.2)
    lag = 5
    for t_ahead in dm.HORIZONS:
        m = round(t_ahead * fps)
        assert stats["drift"][t_ahead] == pytest.approx(a * m * (m + lag) / 2 / h)
    # the acceleration, H/s^2: a px/frame^2 * fps^2 / h
    assert stats["accel"] == pytest.approx(a * fps ** 2 / h)


def test_gaps_split_a_track():
    frames = np.r_[np.arange(10), np.arange(30, 40)]
    boxes = np.column_stack([frames * 2.0, np.zeros(20), np.full(20, 10.0), np.full(20, 50.0)])
    stats = dm.motion_statistics({1: (frames, boxes)}, 25.0)
    assert len(stats["speed"]) == 18    # no step across the gap


def test_detection_errors_measure_offsets_sizes_and_their_correlation():
    truth = [{1: (100.0, 100.0, 40.0, 100.0)} for _ in range(50)]
    sign = [(-1) ** k for k in range(50)]          # flips every frame: lag-1 corr -1
    dets = [[(100.0 + 5.0 * s, 100.0 - 5.0 * s, 40.0 * 1.1, 100.0)] for s in sign]
    e = dm.detection_errors(truth, dets)
    # centre x: 5 px each way plus half the 4 px of extra width, over the 100 px height
    assert e["dx"] == pytest.approx((5.0 * np.asarray(sign) + 2.0) / 100.0)
    assert e["dy"] == pytest.approx(-5.0 * np.asarray(sign) / 100.0)
    assert e["dw"] == pytest.approx(np.full(50, 0.1))
    assert e["dh"] == pytest.approx(np.zeros(50))
    assert e["autocorr"][1] == pytest.approx(-1.0)
    assert e["autocorr"][5] == pytest.approx(-1.0)
    far = [[(400.0, 400.0, 40.0, 100.0)] for _ in range(50)]   # IoU 0: nothing matched
    assert len(dm.detection_errors(truth, far)["dx"]) == 0


def test_real_detection_noise_errs_like_the_public_detections_and_keeps_misses():
    """bench_multi_object --real-detection-noise against the TUD clips' public detections
    as measured by diagnose_motion.py: centre sd 0.032-0.049 H, width ratio sd
    0.15-0.20, height 0.078-0.098, lag-1 correlation 0.51-0.68 (the 2 px i.i.d. default:
    0.016-0.022, 0.03, 0.0)."""
    import bench_multi_object as bench
    from mk_tracker.synthetic.presets import crowd_scene

    scene = crowd_scene(8, seed=2, frames=150)
    plain = dm.generated_detection_errors(scene, 2.0, 2)
    real = dm.generated_detection_errors(scene, 2.0, 2, bench.REAL_DETECTION_NOISE)
    assert np.std(plain["dx"]) < 0.025 and abs(plain["autocorr"][1]) < 0.1
    for key, (lo, hi) in {"dx": (0.03, 0.05), "dy": (0.03, 0.05), "dw": (0.14, 0.21),
                          "dh": (0.07, 0.11)}.items():
        assert lo <= np.std(real[key]) <= hi, key
    assert 0.45 <= real["autocorr"][1] <= 0.7
    assert real["autocorr"][5] < real["autocorr"][1]
    # the same people detected and missed, the same false positives: only the boxes move
    a, _ = bench.scene_frames(scene, 2, 0.5, 0.1, 0.3, 2.0)
    b, _ = bench.scene_frames(scene, 2, 0.5, 0.1, 0.3, 2.0, box_error=bench.REAL_DETECTION_NOISE)
    assert [len(f[2]) for f in a] == [len(f[2]) for f in b]
    assert [d[4] for f in a for d in f[2]] == [d[4] for f in b for d in f[2]]
    assert any(abs(da[0] - db[0]) > 1.0 for fa, fb in zip(a, b) for da, db in zip(fa[2], fb[2]))
