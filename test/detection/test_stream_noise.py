"""The kernel bandwidth widened to a noisy thermal stream (``detector.noise_bandwidth``,
mk_tracker.detection.stream_noise)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mk_tracker.boxes import iou_matrix
from mk_tracker.detection.stream_noise import NoiseBandwidth, temporal_noise_std
from mk_tracker.detection.thermal_detector import ThermalDetector
from mk_tracker.detection.thermal_detector_config import ThermalDetectorConfig
from mk_tracker.synthetic.presets import crowd_scene
from mk_tracker.synthetic.scene import make_scene


def _noisy_frames(std: float, n: int = 6, shape=(240, 320), seed: int = 0) -> list:
    rng = np.random.default_rng(seed)
    return [100.0 + rng.normal(0.0, std, shape).astype(np.float32) for _ in range(n)]


@pytest.mark.parametrize("std", [1.0, 4.0, 12.0])
def test_noise_std_of_gaussian_frames(std):
    assert temporal_noise_std(_noisy_frames(std)) == pytest.approx(std, rel=0.05)


def test_moving_object_does_not_count_as_noise():
    frames = _noisy_frames(3.0)
    for k, f in enumerate(frames):        # a bright block covering a fifth of the frame moves
        f[40:150, 20 + 25 * k:100 + 25 * k] += 120.0
    # the block's leading and trailing strips change 7 % of the pixels of each difference:
    # their std is far off, the median moves by about a tenth
    assert np.std(np.diff(np.stack(frames), axis=0)) / np.sqrt(2.0) > 10.0
    assert temporal_noise_std(frames) == pytest.approx(3.0, rel=0.15)


def test_bit_identical_static_pixels_give_zero():
    still = np.full((120, 160), 90, dtype=np.uint8)
    frames = [still.copy() for _ in range(5)]
    frames[2][10:30, 10:30] = 200                  # motion only
    assert temporal_noise_std(frames) == 0.0
    assert temporal_noise_std(frames[:1]) == 0.0


def test_bandwidth_kept_on_quiet_streams_and_widened_on_noisy_ones():
    quiet = NoiseBandwidth(0.01, 3.0)
    assert quiet.observe(_noisy_frames(2.0), 1.0 / 255.0) == 0.01     # 3 x 2 < 25.5 levels
    noisy = NoiseBandwidth(0.01, 3.0)
    sigma2 = noisy.observe(_noisy_frames(12.0), 1.0 / 255.0)
    wanted = (3.0 * 12.0 / 255.0) ** 2
    assert wanted * 0.9 <= sigma2 <= wanted * 2.0 ** (1 / 8) * 1.1
    assert noisy.noise == pytest.approx(12.0 / 255.0, rel=0.05)
    off = NoiseBandwidth(0.01, 0.0)
    assert off.observe(_noisy_frames(12.0), 1.0 / 255.0) == 0.01


def test_bandwidth_follows_the_median_of_recent_passes():
    bw = NoiseBandwidth(0.01, 3.0, memory=3)
    for _ in range(3):
        bw.observe(_noisy_frames(12.0), 1.0 / 255.0)
    widened = bw.sigma2
    assert bw.observe(_noisy_frames(1.0), 1.0 / 255.0) == widened   # one quiet pass: median
    bw.observe(_noisy_frames(1.0, seed=1), 1.0 / 255.0)
    assert bw.sigma2 == 0.01                                          # then it follows


def _run(scene, config: ThermalDetectorConfig, events: list | None = None
         ) -> tuple[int, float]:
    """(boxes larger than a quarter of the frame, recall at IoU 0.5 of people at least half
    visible) from frame 15 on; the detector's events are appended to ``events``."""
    det = ThermalDetector(config)
    h, w = scene.frame(0).thermal.shape
    large = matched = people = 0
    for i in range(len(scene)):
        frame = scene.frame(i)
        found = det.process(frame.thermal, frame.stamp)
        if events is not None and det.last_event:
            events.append((det.last_event, det.kernel_sigma2, det.stream_noise))
        if i < 15:
            continue
        boxes = np.array([d.box for d in found], dtype=float).reshape(-1, 4)
        large += int(np.count_nonzero(boxes[:, 2] * boxes[:, 3] > 0.25 * w * h))
        truth = np.array([o.box_thermal for o in frame.objects if o.visible_fraction > 0.5],
                         dtype=float).reshape(-1, 4)
        people += len(truth)
        if len(truth) and len(boxes):
            matched += int((iou_matrix(truth, boxes).max(axis=1) >= 0.5).sum())
    return large, matched / max(people, 1)


@pytest.fixture(scope="module")
def crowd():
    return crowd_scene(4, seed=7, width=320, height=240, frames=50)


def test_noisy_stream_is_people_not_one_frame_sized_object(crowd):
    noisy = make_scene(dataclasses.replace(crowd.config, thermal_noise_std=1.2))
    large_off, recall_off = _run(noisy, ThermalDetectorConfig(noise_bandwidth=0.0))
    events: list = []
    large_on, recall_on = _run(noisy, ThermalDetectorConfig(), events)
    assert large_off > 20 and recall_off < 0.1          # the paper's bandwidth collapses
    assert large_on == 0 and recall_on > 0.7
    # the widening is said once (the first full pass), with the noise that caused it:
    # 1.2 K on the generator's 30 K mono8 scale is about 10 of 255 levels
    assert len(events) == 1 and "kernel bandwidth" in events[0][0]
    assert events[0][1] > 0.01
    assert 8.0 / 255 < events[0][2] < 13.0 / 255


def test_quiet_stream_is_unchanged(crowd):
    quiet_off = _run(crowd, ThermalDetectorConfig(noise_bandwidth=0.0))
    events: list = []
    assert quiet_off == _run(crowd, ThermalDetectorConfig(), events)
    assert events == []
    assert quiet_off[1] > 0.7
