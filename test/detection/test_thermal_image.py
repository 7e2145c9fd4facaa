"""Thermal input handling: encodings, normalisation, missing pixels."""

import numpy as np
import pytest

from mk_tracker.detection.thermal_image import (ThermalInputError, as_thermal_array, fill_missing,
                                      normalization_map, normalize, robust_range,
                                      thermal_encoding, thermal_view)


def test_mono8_is_divided_by_255():
    raw, enc = as_thermal_array(np.array([[0, 255], [51, 102]], np.uint8))
    assert enc == "mono8"
    np.testing.assert_allclose(normalize(raw, *normalization_map(enc, None)),
                               [[0, 1], [0.2, 0.4]], atol=1e-7)


def test_encodings_and_dtypes_must_agree():
    assert thermal_encoding(np.zeros((2, 2), np.uint16), "16UC1") == "mono16"
    assert thermal_encoding(np.zeros((2, 2), np.float32)) == "32FC1"
    with pytest.raises(ThermalInputError):
        as_thermal_array(np.zeros((2, 2), np.uint8), "mono16")
    with pytest.raises(ThermalInputError):
        as_thermal_array(np.zeros((2, 2), np.int32))
    with pytest.raises(ThermalInputError):
        as_thermal_array(np.zeros((2, 2), np.uint8), "bgr8")
    with pytest.raises(ThermalInputError):
        as_thermal_array(np.zeros((2, 2, 3), np.uint8))
    with pytest.raises(ThermalInputError):
        as_thermal_array(np.zeros((0, 4), np.uint8))
    raw, _ = as_thermal_array(np.ones((3, 4, 1), np.uint8), "mono8")
    assert raw.shape == (3, 4)


def test_float_dead_pixels_become_nan():
    frame = np.array([[300.0, np.inf], [-np.inf, np.nan]], np.float32)
    raw, enc = as_thermal_array(frame, "32FC1")
    assert enc == "32FC1"
    assert raw[0, 0] == 300.0
    assert np.isnan(raw[0, 1]) and np.isnan(raw[1, 0]) and np.isnan(raw[1, 1])


def test_mono16_needs_a_range_and_maps_it_to_unit():
    with pytest.raises(ThermalInputError):
        normalization_map("mono16", None)
    off, scale = normalization_map("mono16", (29000.0, 31000.0))
    raw = np.array([[29000, 30000, 31000]], np.float32)
    np.testing.assert_allclose(normalize(raw, off, scale), [[0.0, 0.5, 1.0]])
    # a constant scene does not divide by zero
    off, scale = normalization_map("mono16", (5.0, 5.0))
    assert np.isfinite(scale)


def test_robust_range_ignores_nan_and_outliers():
    frames = np.full((2, 100, 100), 20.0, np.float32)
    frames[0, :50] = 30.0
    frames[1, 0, 0] = 1e6          # a hot dead pixel
    frames[1, 1, :10] = np.nan
    lo, hi = robust_range(frames)
    assert lo == pytest.approx(20.0) and hi == pytest.approx(30.0)
    assert robust_range(np.full((3, 3), np.nan, np.float32)) is None


def test_fill_missing_holds_the_previous_value():
    prev = np.array([[1.0, 2.0], [3.0, 4.0]], np.float32)
    cur = np.array([[5.0, np.nan], [np.nan, 8.0]], np.float32)
    filled, n = fill_missing(cur, prev)
    assert n == 2
    np.testing.assert_array_equal(filled, [[5.0, 2.0], [3.0, 8.0]])
    first, n = fill_missing(cur, None)
    np.testing.assert_array_equal(first, [[5.0, 6.5], [6.5, 8.0]])


def test_thermal_view_checks_like_as_thermal_array_without_copying():
    """The detector converts integer frames straight into its ring buffer: the view keeps
    the raw dtype and memory ((H, W, 1) squeezed), and bad frames fail the same way."""
    frame = np.arange(12, dtype=np.uint16).reshape(3, 4, 1)
    view, enc = thermal_view(frame, "16UC1")
    assert enc == "mono16" and view.shape == (3, 4) and view.dtype == np.uint16
    assert np.shares_memory(view, frame)
    np.testing.assert_array_equal(as_thermal_array(frame, "16UC1")[0], view.astype(np.float32))
    with pytest.raises(ThermalInputError):
        thermal_view(np.zeros((2, 2), np.uint8), "mono16")
    with pytest.raises(ThermalInputError):
        thermal_view(np.zeros((2, 2, 3), np.uint8))
