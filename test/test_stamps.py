"""mk_tracker.stamps: one stamp check for the detectors and the tracker."""

import numpy as np
import pytest

from mk_tracker.tracking.multi_object_tracker import MultiObjectTracker, MultiObjectTrackerConfig, \
    TrackerInputError
from mk_tracker.stamps import checked_stamp
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
