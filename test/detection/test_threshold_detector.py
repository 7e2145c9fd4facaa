"""The pixel-threshold baseline (Table 1)."""

import numpy as np
import pytest

from mk_tracker.detection.thermal_detector import ThermalInputError
from mk_tracker.detection.threshold_detector import ThresholdDetector, ThresholdDetectorConfig


def scene():
    f = np.full((40, 60), 30, np.uint8)
    f[5:15, 10:20] = 200          # 100 px blob, centre (15, 10)
    f[20:30, 40:44] = 180         # 40 px blob, centre (42, 25)
    f[35:37, 2:4] = 250           # 4 px speck, below min_area
    f[20:30, 25:30] = 100         # below the threshold
    return f


def test_blobs_above_threshold_and_area_are_found():
    dets = ThresholdDetector(ThresholdDetectorConfig(threshold=0.5, min_area=20)).process(
        scene(), 0.0)
    dets = sorted(dets, key=lambda d: d.centroid[0])
    assert len(dets) == 2
    assert dets[0].box == (10.0, 5.0, 10.0, 10.0) and dets[0].pixel_count == 100
    assert dets[0].centroid == pytest.approx((15.0, 10.0))
    assert dets[1].centroid == pytest.approx((42.0, 25.0))
    assert dets[0].score == pytest.approx(200 / 255, abs=1e-6)


def test_lower_threshold_finds_more():
    dets = ThresholdDetector(ThresholdDetectorConfig(threshold=0.3, min_area=20)).process(
        scene(), 0.0)
    assert len(dets) == 3


def test_mono16_fixed_range_and_nan_float():
    f16 = scene().astype(np.uint16) * 100
    cfg = ThresholdDetectorConfig(normalization="fixed", range_min=0.0, range_max=25500.0)
    assert len(ThresholdDetector(cfg).process(f16, 0.0, "mono16")) == 2
    ff = scene().astype(np.float32)
    ff[0, :] = np.nan
    assert len(ThresholdDetector().process(ff, 0.0, "32FC1")) >= 1
    assert ThresholdDetector().process(np.full((5, 5), np.nan, np.float32), 0.0) == []


def test_bad_input():
    det = ThresholdDetector()
    with pytest.raises(ThermalInputError):
        det.process(np.zeros((4, 4, 3), np.uint8), 0.0)
    with pytest.raises(ThermalInputError):
        det.process(scene(), float("inf"))
    with pytest.raises(ThermalInputError):
        ThresholdDetector(ThresholdDetectorConfig(normalization="fixed", range_min=5.0,
                                                  range_max=5.0))
