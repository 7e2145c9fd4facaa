"""Camera encodings (YUV 4:2:2 and 8-bit Bayer) decoded from raw bytes built by hand.

Oracles: the BT.601 video-range colour bars (ITU-R BT.601: red = Y 81 U 90 V 240, green =
Y 145 U 54 V 34, blue = Y 41 U 240 V 110, white = Y 235, black = Y 16, U = V = 128), and
Bayer mosaics laid out here from the pattern name (the top-left 2x2 cell reads the name)
over a frame of flat colour patches, whose interiors demosaic to the patch colour exactly.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from mk_tracker.frame_processing import thermal_input, tracker_input
from mk_tracker.messages.image_conversion import (ImageConversionError, image_to_numpy,
                                                  numpy_to_image, to_bgr, to_gray)
from mk_tracker.messages.message_types import bag_message_types
from mk_tracker.bags.bag_typestore import make_typestore

# name -> (Y, U, V) and its BGR colour
BARS = {"red": ((81, 90, 240), (0, 0, 255)), "green": ((145, 54, 34), (0, 255, 0)),
        "blue": ((41, 240, 110), (255, 0, 0)), "white": ((235, 128, 128), (255, 255, 255)),
        "black": ((16, 128, 128), (0, 0, 0))}


def yuv_bytes(columns: list[str], rows: int, order: str) -> bytes:
    """One pixel pair per entry of ``columns`` (both pixels the same colour), written in
    ``order``: ``"UYVY"`` (ROS yuv422) or ``"YUYV"`` (ROS yuv422_yuy2)."""
    row = bytearray()
    for name in columns:
        y, u, v = BARS[name][0]
        values = {"Y": y, "U": u, "V": v}
        row += bytes(values[c] for c in order)  # Y appears twice: both pixels
    return bytes(row) * rows


def fake(data: bytes, encoding: str, height: int, width: int, step: int) -> SimpleNamespace:
    return SimpleNamespace(height=height, width=width, encoding=encoding, is_bigendian=0,
                           step=step, data=data)


@pytest.mark.parametrize("encoding,order", [("yuv422", "UYVY"), ("yuv422_yuy2", "YUYV")])
def test_yuv422_colour_bars_become_their_bgr_colours(encoding, order):
    columns = ["red", "green", "blue", "white", "black"]
    msg = fake(yuv_bytes(columns, 3, order), encoding, 3, 2 * len(columns),
               4 * len(columns))
    raw = image_to_numpy(msg)
    assert raw.shape == (3, 10, 2)
    bgr = tracker_input(msg)
    assert bgr.shape == (3, 10, 3) and bgr.dtype == np.uint8
    for k, name in enumerate(columns):
        for x in (2 * k, 2 * k + 1):
            got = bgr[1, x].astype(int)
            assert np.abs(got - BARS[name][1]).max() <= 2, (name, got)
    # gray is the luma, for the thermal side too
    luma = [BARS[name][0][0] for name in columns for _ in range(2)]
    np.testing.assert_array_equal(to_gray(raw, encoding)[2], luma)
    np.testing.assert_array_equal(thermal_input(msg)[0], luma)


def test_yuv422_needs_an_even_width():
    with pytest.raises(ImageConversionError, match="even"):
        image_to_numpy(fake(bytes(12), "yuv422", 2, 3, 6))
    with pytest.raises(ImageConversionError, match="even"):
        numpy_to_image(np.zeros((2, 3, 2), np.uint8), "yuv422_yuy2",
                       types=bag_message_types(make_typestore()))


def bayer_mosaic(pattern: str, colours: np.ndarray) -> np.ndarray:
    """The one-channel mosaic a sensor with ``pattern`` (e.g. ``"rggb"``: row 0 R G, row 1
    G B) records of the BGR frame ``colours``."""
    channel = {"b": 0, "g": 1, "r": 2}
    h, w, _ = colours.shape
    out = np.empty((h, w), np.uint8)
    for y in range(h):
        for x in range(w):
            out[y, x] = colours[y, x, channel[pattern[2 * (y % 2) + (x % 2)]]]
    return out


@pytest.mark.parametrize("pattern", ["rggb", "bggr", "gbrg", "grbg"])
def test_bayer_patches_demosaic_to_their_colours(pattern):
    patches = [(0, 0, 255), (0, 255, 0), (255, 0, 0), (40, 160, 220)]  # BGR
    frame = np.zeros((12, 48, 3), np.uint8)
    for k, colour in enumerate(patches):
        frame[:, 12 * k:12 * (k + 1)] = colour
    encoding = f"bayer_{pattern}8"
    msg = numpy_to_image(bayer_mosaic(pattern, frame), encoding,
                         types=bag_message_types(make_typestore()))
    bgr = tracker_input(msg)
    assert bgr.shape == frame.shape
    # inside each patch (2 px from its edges and the frame's), the colour is exact
    for k, colour in enumerate(patches):
        inner = bgr[2:-2, 12 * k + 2:12 * (k + 1) - 2]
        np.testing.assert_array_equal(inner, np.broadcast_to(colour, inner.shape))
    gray = to_gray(image_to_numpy(msg), encoding)
    assert gray.shape == frame.shape[:2]
    # BT.601 gray of the pure-red patch: 0.299 * 255 = 76
    assert abs(int(gray[6, 6]) - 76) <= 1


def test_bayer_is_not_a_thermal_input():
    msg = fake(bytes(16), "bayer_rggb8", 4, 4, 4)
    with pytest.raises(ImageConversionError, match="thermal"):
        thermal_input(msg)
    assert to_bgr(image_to_numpy(msg), "bayer_rggb8").shape == (4, 4, 3)
