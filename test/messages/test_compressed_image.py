"""sensor_msgs/CompressedImage: JPEG and PNG (8-bit colour, grey, 16-bit grey) both ways."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from mk_tracker.bags.bag_typestore import make_typestore
from mk_tracker.frame_processing import thermal_input, tracker_input
from mk_tracker.messages.compressed_image import (as_image, decode_compressed,
                                                  encode_compressed, numpy_to_compressed)
from mk_tracker.messages.image_conversion import ImageConversionError, image_to_numpy
from mk_tracker.messages.message_types import bag_message_types, make_header

TYPESTORE = make_typestore()
BAG = bag_message_types(TYPESTORE)


def colour_frame() -> np.ndarray:
    """Flat BGR patches (JPEG keeps flat areas within a few levels)."""
    frame = np.zeros((32, 48, 3), np.uint8)
    frame[:, :16] = (0, 0, 255)
    frame[:, 16:32] = (0, 255, 0)
    frame[:, 32:] = (200, 100, 50)
    return frame


def test_png_of_every_kind_decodes_exactly():
    rng = np.random.default_rng(5)
    counts = rng.integers(0, 65536, size=(9, 11), dtype=np.uint16)
    blob, fmt = encode_compressed(counts, "mono16", "png")
    assert fmt == "mono16; png compressed mono16"
    assert blob[:8] == b"\x89PNG\r\n\x1a\n"
    msg = SimpleNamespace(header=make_header(BAG, "thermal_camera", 7), format=fmt, data=blob)
    image = as_image(msg)
    assert (image.encoding, image.height, image.width) == ("mono16", 9, 11)
    np.testing.assert_array_equal(image_to_numpy(image), counts)
    np.testing.assert_array_equal(thermal_input(image), counts)
    assert image.header.frame_id == "thermal_camera"
    rgb = rng.integers(0, 256, size=(6, 5, 3), dtype=np.uint8)
    pixels, encoding = decode_compressed(SimpleNamespace(format="png",
                                                         data=encode_compressed(rgb, "rgb8",
                                                                                "png")[0]))
    assert encoding == "bgr8"
    np.testing.assert_array_equal(pixels, rgb[:, :, ::-1])   # rgb8 is stored as BGR


def test_jpeg_in_a_bag_message_survives_cdr_and_keeps_its_colours():
    frame = colour_frame()
    msg = numpy_to_compressed(frame, "bgr8", "jpeg", make_header(BAG, "camera", 42),
                              types=BAG, jpeg_quality=90)
    assert msg.format == "bgr8; jpeg compressed bgr8"
    raw = TYPESTORE.serialize_cdr(msg, "sensor_msgs/msg/CompressedImage")
    back = TYPESTORE.deserialize_cdr(raw, "sensor_msgs/msg/CompressedImage")
    bgr = tracker_input(as_image(back))
    assert bgr.shape == frame.shape
    # away from the patch borders (8x8 JPEG blocks), the colours are within a few levels
    for x0 in (0, 16, 32):
        inner = bgr[4:-4, x0 + 4:x0 + 12].astype(int)
        assert np.abs(inner - frame[4:-4, x0 + 4:x0 + 12]).max() <= 6


def test_ros_world_message_decodes():
    pytest.importorskip("sensor_msgs.msg")
    from mk_tracker.messages.message_types import ros_message_types
    types = ros_message_types()
    gray = np.tile(np.arange(0, 250, 10, dtype=np.uint8), (4, 1))
    msg = numpy_to_compressed(gray, "mono8", "png", types=types)
    np.testing.assert_array_equal(image_to_numpy(as_image(msg)), gray)


@pytest.mark.parametrize("data, words", [
    (b"", "no data"),
    (b"\xff\xd8\xff garbage", "could not be decoded"),
    (np.arange(40, dtype=np.uint8), "could not be decoded"),
])
def test_broken_compressed_data_raises_our_error(data, words):
    with pytest.raises(ImageConversionError, match=words):
        as_image(SimpleNamespace(header=None, format="jpeg", data=data))


def test_encoding_a_codec_cannot_hold_is_refused():
    with pytest.raises(ImageConversionError, match="jpeg cannot hold a mono16"):
        encode_compressed(np.zeros((4, 4), np.uint16), "mono16", "jpeg")
    with pytest.raises(ImageConversionError, match="not one of"):
        encode_compressed(np.zeros((4, 4), np.uint8), "mono8", "webp")


def test_an_image_message_passes_through_unchanged():
    img = SimpleNamespace(encoding="mono8", format="x")
    assert as_image(img) is img
