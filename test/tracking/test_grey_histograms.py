"""The grey colour space of the kernels (issue #19 item 2: thermal-only tracking).

A thermal frame reaches the tracker grey-replicated into BGR; ``colour_space: grey`` bins its
luminance into ``grey_bins`` bins, and :func:`tracker_config_for_encoding` is the one rule
that picks ``multi_kernel.thermal_colour_space`` for single-channel images.
"""

import numpy as np
import pytest

from mk_tracker.frame_processing import SINGLE_CHANNEL_ENCODINGS, tracker_config_for_encoding
from mk_tracker.tracking.kernel_histograms import (bin_lookup_tables, grey_levels,
                                                   number_of_bins, quantize)
from mk_tracker.tracking.multi_kernel import MultiKernelTracker
from mk_tracker.tracking.multi_kernel_config import MultiKernelConfig
from mk_tracker.tracking.search_region import _MODES, _quantize_loops, compiled_kernels, \
    quantize_region, _HUE_RECIPROCAL, _SAT_RECIPROCAL
from mk_tracker.tracking.tracker_config import MultiObjectTrackerConfig


def _ramp_image() -> np.ndarray:
    """Every grey level 0..255 once, grey-replicated (as a mono8 frame reaches the tracker)."""
    level = np.arange(256, dtype=np.uint8).reshape(16, 16)
    return np.repeat(level[..., None], 3, axis=2)


def _plain_loops(img, bins):
    out = np.empty(img.shape[:2], np.int32)
    return _quantize_loops(img, 0, 0, 1, _MODES["grey"], bin_lookup_tables("grey", bins),
                           _SAT_RECIPROCAL, _HUE_RECIPROCAL, out)


@pytest.mark.parametrize("n", [4, 8, 16, 32])
def test_a_grey_ramp_falls_into_n_equal_bins(n):
    # hand-computed: 256 levels in n bins of 256 / n consecutive levels each
    expected = np.repeat(np.arange(n), 256 // n).reshape(16, 16)
    img = _ramp_image()
    assert np.array_equal(quantize(img, "grey", (1, 1, n)), expected)
    assert np.array_equal(quantize_region(img, (0, 0, 16, 16), 1, "grey", (1, 1, n), "numpy"),
                          expected)
    assert np.array_equal(_plain_loops(img, (1, 1, n)), expected)
    if compiled_kernels() is not None:
        assert np.array_equal(
            quantize_region(img, (0, 0, 16, 16), 1, "grey", (1, 1, n), "compiled"), expected)


def test_luminance_of_known_colours_in_both_backends():
    # BT.601 weights: 0.114 B + 0.587 G + 0.299 R, rounded: blue 29.07 -> 29,
    # green 149.7 -> 150, red 76.2 -> 76, white 255, (10, 20, 30) 21.85 -> 22
    colours = np.array([[[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 255],
                         [10, 20, 30], [0, 0, 0]]], dtype=np.uint8)
    expected = np.array([[29, 150, 76, 255, 22, 0]])
    assert np.array_equal(grey_levels(colours), expected)
    assert np.array_equal(quantize(colours, "grey", (1, 1, 256)), expected)
    assert np.array_equal(_plain_loops(colours, (1, 1, 256)), expected)


def test_backends_agree_on_random_colour_and_grey_images():
    rng = np.random.default_rng(7)
    colour = rng.integers(0, 256, (37, 53, 3), dtype=np.uint8)
    grey = np.repeat(rng.integers(0, 256, (37, 53, 1), dtype=np.uint8), 3, axis=2)
    for img in (colour, grey):
        for n in (8, 16):
            want = quantize(img, "grey", (1, 1, n))
            assert np.array_equal(_plain_loops(img, (1, 1, n)), want)
            if compiled_kernels() is not None:
                for stride, region in ((1, (0, 0, 53, 37)), (3, (6, 3, 50, 31))):
                    x0, y0, x1, y1 = region
                    got = quantize_region(img, region, stride, "grey", (1, 1, n), "compiled")
                    assert np.array_equal(
                        got, quantize(img[y0:y1:stride, x0:x1:stride], "grey", (1, 1, n)))


def test_grey_with_four_bins_is_the_old_hsv_histogram_of_a_thermal_frame():
    # before the grey colour space, a grey-replicated frame had hue = saturation = 0 in HSV,
    # so only the 4 value bins varied: grey with 4 bins gives the same histograms
    img = _ramp_image()
    assert np.array_equal(quantize(img, "grey", (1, 1, 4)), quantize(img, "hsv", (16, 8, 4)))


def test_grey_needs_a_single_channel_of_bins():
    with pytest.raises(ValueError, match=r"grey histograms have bins \(1, 1, n\)"):
        bin_lookup_tables("grey", (16, 8, 4))
    cfg = MultiKernelConfig(colour_space="grey", grey_bins=16)
    assert cfg.bins == (1, 1, 16) and number_of_bins(cfg.bins) == 16
    assert MultiKernelConfig(grey_bins=16).bins == (16, 8, 4)     # hsv keeps its bins


def test_single_channel_frames_use_the_thermal_colour_space():
    base = MultiObjectTrackerConfig()
    grey = MultiObjectTrackerConfig(multi_kernel=MultiKernelConfig(
        thermal_colour_space="grey", grey_bins=16))
    for enc in ("rgb8", "bgr8", "yuv422"):
        assert tracker_config_for_encoding(grey, enc) is grey
    for enc in SINGLE_CHANNEL_ENCODINGS:
        assert tracker_config_for_encoding(base, enc) is base       # thermal default: hsv
        chosen = tracker_config_for_encoding(grey, enc)
        assert chosen.multi_kernel.colour_space == "grey"
        assert chosen.multi_kernel.bins == (1, 1, 16)
        assert chosen.kalman == grey.kalman                         # nothing else changes
    assert grey.multi_kernel.colour_space == "hsv"                  # the input is untouched


def _thermal_scene(warm_x: float, cool_x: float) -> np.ndarray:
    """A grey-replicated thermal frame: background ~70, a cool person at grey 150 and a warm
    one at grey 180 (head 200), 30 x 80 px each, both at rows 60-140."""
    yy, xx = np.mgrid[0:200, 0:320]
    img = (70 + 8 * np.sin(xx / 9.0) * np.cos(yy / 7.0)).astype(np.float64)
    for x, body, head in ((cool_x, 150.0, 165.0), (warm_x, 180.0, 200.0)):   # warm in front
        x0 = int(round(x))
        img[60:140, x0:x0 + 30] = body
        img[60:80, x0 + 5:x0 + 25] = head
    grey = np.clip(img, 0, 255).astype(np.uint8)
    return np.repeat(grey[..., None], 3, axis=2)


def _follow_the_warm_person(colour_space: str) -> float:
    """Largest x error of a track on the warm person as they walk 4 px/frame past the cool
    one (which walks 1 px/frame the other way); each search starts at the last position."""
    tracker = MultiKernelTracker(MultiKernelConfig(colour_space=colour_space, grey_bins=16,
                                                   scale_update=False))
    warm, cool = 60.0, 230.0
    state = tracker.start(_thermal_scene(warm, cool), (warm, 60, 30, 80))
    worst = 0.0
    for _ in range(50):
        warm += 4.0
        cool -= 1.0
        res = tracker.refine(_thermal_scene(warm, cool), state)
        assert not res.lost, (colour_space, warm, cool)
        worst = max(worst, abs(res.center[0] - (warm + 15.0)))
    assert warm + 15.0 > cool + 30.0 + 10.0           # really went past the cool person
    return worst


def test_a_thermal_only_track_follows_a_warm_person_past_a_cooler_one():
    # 16 grey bins: cool body 150 -> bin 9, head 165 -> 10; warm body 180 -> 11, head 200 -> 12
    assert _follow_the_warm_person("grey") < 4.0
    # the old histogram (HSV: only 4 value bins vary) puts both bodies in bin 2 (128-191):
    # it is pulled towards the cool person while they overlap
    assert _follow_the_warm_person("hsv") > 6.0
