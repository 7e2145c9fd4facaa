"""mk_tracker.stamps: one stamp check for the detectors and the tracker."""

import numpy as np
import pytest

from mk_tracker.tracking.multi_object_tracker import MultiObjectTracker, MultiObjectTrackerConfig, \
    TrackerInputError
from mk_tracker.stamps import FrameRate, checked_stamp
from mk_tracker.detection.thermal_detector import ThermalDetector
from mk_tracker.detection.thermal_image import ThermalInputError
from mk_tracker.detection.threshold_detector import ThresholdDetector


class OwnError(ValueError):
    pass


def test_checked_stamp_accepts_numbers_and_names_bad_ones():
    assert checked_stamp(3) == 3.0 and isinstance(checked_stamp(np.float32(1.5)), float)
    assert checked_stamp("2.25") == 2.25
    for bad, words in ((None, "is not a number"), ("soon", "is not a number"),
                       (float("nan"), "is not finite"), (float("-inf"), "is not finite")):
        with pytest.raises(OwnError, match=words):
            checked_stamp(bad, OwnError)
    with pytest.raises(ValueError):
        checked_stamp(float("inf"))


@pytest.mark.parametrize("make, error", [
    (ThermalDetector, ThermalInputError),
    (ThresholdDetector, ThermalInputError),
])
def test_detectors_reject_bad_stamps_with_their_error(make, error):
    det = make()
    for bad in (float("nan"), "x", None):
        with pytest.raises(error, match="stamp"):
            det.process(np.zeros((8, 8), np.uint8), bad)


def test_tracker_rejects_bad_stamps_with_its_error():
    trk = MultiObjectTracker(MultiObjectTrackerConfig(use_multi_kernel=False))
    for bad in (float("inf"), "x", None):
        with pytest.raises(TrackerInputError, match="stamp"):
            trk.step(np.zeros((8, 8, 3), np.uint8), bad)


def test_frame_rate_is_the_median_interval():
    rate = FrameRate(window=5)
    assert rate.rate is None
    for dt in (0.1, 0.1, 0.5, 0.1, 0.12):         # one late frame does not move it
        rate.add(dt)
    assert rate.rate == pytest.approx(10.0)
    rate.add(0.0)                                  # a repeated stamp is not an interval
    rate.add(-1.0)
    assert rate.rate == pytest.approx(10.0)
    rate.clear()
    assert rate.rate is None


def test_frame_rate_bounded_by_max_rate():
    rate = FrameRate(window=3, max_rate=100.0)
    rate.add(1e-6)
    assert rate.rate == pytest.approx(100.0)


@pytest.mark.parametrize("interval,count,minimum,slower_only,expected", [
    (1 / 25, 25, 1, False, 25),       # at the reference rate: the count
    (1 / 8.33, 25, 1, False, 8),      # a third of the rate: a third of the frames
    (1 / 8.33, 4, 2, False, 2),       # never below the minimum
    (1 / 6.25, 6, 1, False, 2),       # 1.5 rounds half up
    (1 / 50, 4, 1, False, 8),         # a faster stream: more frames for the same time
    (1 / 50, 4, 1, True, 4),          # ... unless only slower streams are converted
    (1 / 8.33, 25, 1, True, 8),
])
def test_frames_keep_the_duration(interval, count, minimum, slower_only, expected):
    rate = FrameRate()
    rate.add(interval)
    assert rate.frames(count, 25.0, minimum, slower_only) == expected


def test_frames_unconverted_without_rate_or_reference():
    rate = FrameRate()
    assert rate.frames(25, 25.0) == 25               # no stamps yet
    rate.add(1 / 8.33)
    assert rate.frames(25, 0.0) == 25                # reference 0: counted in frames
    assert rate.frames(0, 25.0) == 0
