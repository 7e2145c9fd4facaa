"""Ignore regions (issue #19): masked pixels, dropped boxes, parameter checks, and a
flickering burned-in overlay that the kernel covariance detector stops reporting."""

from __future__ import annotations

import numpy as np
import pytest

from mk_tracker.detection.ignore_regions import (MaskedDetector, centre_inside, mask_regions,
                                                 parse_regions)
from mk_tracker.detection.thermal_detector import ThermalDetectorConfig
from mk_tracker.detection.threshold_detector import ThresholdDetectorConfig
from mk_tracker.frame_processing import build_detector
from mk_tracker.parameters import ParameterError


def test_parse_regions_drops_placeholders_and_checks_values():
    assert parse_regions((0.0, 0.0, 0.0, 0.0)) == ()
    assert parse_regions([1, 2, 3, 4, 0, 0, 0, 5]) == ((1.0, 2.0, 3.0, 4.0),)
    with pytest.raises(ValueError, match="groups of 4"):
        parse_regions([1, 2, 3])
    with pytest.raises(ValueError, match="negative"):
        parse_regions([1, 2, -3, 4])
    with pytest.raises(ValueError, match="not finite"):
        parse_regions([1, float("nan"), 3, 4])


def test_mask_covers_every_touched_pixel_and_leaves_the_rest():
    frame = np.full((10, 12), 9, np.uint16)
    out = mask_regions(frame, [(2.5, 1.0, 3.0, 2.0)])     # x 2.5..5.5 -> columns 2..5
    expected = frame.copy()
    expected[1:3, 2:6] = 0
    assert np.array_equal(out, expected)
    assert frame.max() == frame.min() == 9                # the input is not changed
    assert mask_regions(frame, []) is frame
    # a region reaching out of the image is clipped, colour images masked on all channels
    rgb = np.full((4, 4, 3), 7, np.uint8)
    out = mask_regions(rgb, [(-2.0, 2.0, 4.0, 9.0)])
    assert (out[2:, :2] == 0).all() and (out[:2] == 7).all() and (out[2:, 2:] == 7).all()


def test_centre_inside_uses_half_open_boxes():
    regions = [(10.0, 10.0, 10.0, 10.0)]
    assert centre_inside((14.0, 14.0, 2.0, 2.0), regions)          # centre (15, 15)
    assert centre_inside((9.0, 9.0, 2.0, 2.0), regions)            # centre (10, 10)
    assert not centre_inside((19.0, 14.0, 2.0, 2.0), regions)      # centre x = 20
    assert not centre_inside((0.0, 0.0, 30.0, 5.0), regions)       # centre (15, 2.5)


class _Recorder:
    """A stand-in detector: remembers the frame it saw, returns fixed boxes."""

    def __init__(self, boxes):
        self.boxes, self.seen, self.last_mode = boxes, None, "tracking"

    def process(self, frame, stamp, encoding=None):
        self.seen = frame
        return [type("D", (), {"box": b, "score": 1.0})() for b in self.boxes]


def test_masked_detector_masks_input_and_filters_output():
    inner = _Recorder([(0.0, 0.0, 4.0, 4.0), (20.0, 20.0, 4.0, 4.0)])
    det = MaskedDetector(inner, [(0.0, 0.0, 5.0, 5.0)])
    frame = np.full((30, 30), 200, np.uint8)
    found = det.process(frame, 1.0, encoding="mono8")
    assert [d.box for d in found] == [(20.0, 20.0, 4.0, 4.0)]
    assert inner.seen[:5, :5].max() == 0 and inner.seen[5:, 5:].min() == 200
    assert det.last_mode == "tracking"                   # attributes pass through


def test_build_detector_validates_regions():
    with pytest.raises(ParameterError, match="groups of 4"):
        build_detector("threshold", ThermalDetectorConfig(), ThresholdDetectorConfig(),
                       (1.0, 2.0))
    plain = build_detector("threshold", ThermalDetectorConfig(), ThresholdDetectorConfig(),
                           (0.0, 0.0, 0.0, 0.0))
    assert not isinstance(plain, MaskedDetector)


def _counter_frames(n: int, with_person: bool) -> list[np.ndarray]:
    """64x64 mono8 frames: a flickering bright counter at the top left (changes every
    frame, like a burned-in frame number) and, optionally, a warm person walking right."""
    rng = np.random.default_rng(0)
    frames = []
    for k in range(n):
        f = np.full((64, 64), 60, np.uint8)
        f[2:10, 2:18] = rng.integers(0, 256, size=(8, 16)).astype(np.uint8)
        if with_person:
            x = 20 + k
            f[30:50, x:x + 8] = 180
        frames.append(f)
    return frames


@pytest.mark.parametrize("method", ["kernel_covariance", "threshold"])
def test_an_overlay_region_is_never_detected(method):
    cfg = ThermalDetectorConfig()
    thr = ThresholdDetectorConfig()
    region = (0.0, 0.0, 20.0, 12.0)
    plain = build_detector(method, cfg, thr)
    masked = build_detector(method, cfg, thr, region)
    seen_plain, seen_masked = [], []
    for k, f in enumerate(_counter_frames(30, with_person=True)):
        seen_plain += plain.process(f, k / 25.0, encoding="mono8")
        seen_masked += masked.process(f, k / 25.0, encoding="mono8")
    in_region = [d for d in seen_masked if centre_inside(d.box, [region])]
    assert in_region == []
    # the person is still found by the masked detector
    assert any(d.box[1] + d.box[3] / 2 > 25 for d in seen_masked)
    # the unmasked detector does report the overlay (the premise of the test; the kernel
    # covariance detector found it in 25 of 30 frames when this was written)
    assert sum(centre_inside(d.box, [region]) for d in seen_plain) >= 5
