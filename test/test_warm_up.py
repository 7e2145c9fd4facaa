"""mk_tracker.warm_up: the nodes' start-up pass goes through the compiled code paths."""

from __future__ import annotations

import time

import pytest

from mk_tracker.tracking.multi_kernel import MultiKernelConfig
from mk_tracker.detection.thermal_detector import ThermalDetectorConfig
from mk_tracker.warm_up import warm_up_detector, warm_up_tracker


@pytest.mark.parametrize("kernels", [1, 2, 4, 6])
def test_tracker_warm_up_starts_refines_and_compares(kernels):
    before = time.perf_counter()
    done = warm_up_tracker(MultiKernelConfig(num_kernels=kernels))
    elapsed = time.perf_counter() - before
    assert done.paths == {"start", "refine", "appearance_similarity"}
    # the wall time of the warm-up itself: a part of the call measured around it (not a
    # clock reading, not another unit), and more than nothing since it did work
    assert 0.0 < done.seconds <= elapsed


@pytest.mark.parametrize("startup, window", [(6, 4), (3, 2), (10, 8)])
def test_detector_warm_up_reaches_tracking_mode_with_the_given_config(startup, window):
    before = time.perf_counter()
    done = warm_up_detector(ThermalDetectorConfig(startup_frames=startup,
                                                  window_frames=window))
    elapsed = time.perf_counter() - before
    assert {"startup", "tracking"} <= done.paths, done.paths
    assert 0.0 < done.seconds <= elapsed


def test_detector_warm_up_loads_the_valley_split_only_when_it_is_on():
    assert "valley_split" not in warm_up_detector(ThermalDetectorConfig()).paths
    done = warm_up_detector(ThermalDetectorConfig(split_by_valleys=True))
    assert "valley_split" in done.paths


def test_load_valley_split_splits_its_constructed_pair():
    from mk_tracker.detection.pixel_clustering import load_valley_split
    assert load_valley_split() == 2
