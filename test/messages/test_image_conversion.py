"""sensor_msgs/Image <-> numpy in the rclpy world and the rosbags world."""

from __future__ import annotations

import array
import sys
import warnings
from types import SimpleNamespace

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore

from mk_tracker.messages.image_conversion import (SUPPORTED_ENCODINGS, ImageConversionError,
                                         image_to_numpy, numpy_to_image, to_bgr, to_gray)
from mk_tracker.messages.message_types import (bag_message_types, make_header, ros_message_types,
                                      seconds_to_stamp, stamp_to_nanoseconds,
                                      stamp_to_seconds)

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
WORLDS = {"bag": bag_message_types(TYPESTORE)}
try:
    import sensor_msgs.msg  # noqa: F401
    WORLDS["ros"] = ros_message_types()
except ImportError:  # pragma: no cover - ROS wheels absent
    pass


def sample(encoding: str, h: int = 5, w: int = 7) -> np.ndarray:
    dtype, channels = SUPPORTED_ENCODINGS[encoding]
    rng = np.random.default_rng(3)
    shape = (h, w) if channels == 1 else (h, w, channels)
    if dtype.kind == "f":
        return rng.normal(size=shape).astype(dtype)
    return rng.integers(0, np.iinfo(dtype).max, size=shape, endpoint=True).astype(dtype)


@pytest.mark.parametrize("world", sorted(WORLDS))
@pytest.mark.parametrize("encoding", sorted(SUPPORTED_ENCODINGS))
def test_round_trip_every_encoding(world, encoding):
    types = WORLDS[world]
    width = 8 if encoding.startswith("yuv422") else 7   # YUV 4:2:2 packs pixel pairs
    arr = sample(encoding, w=width)
    header = make_header(types, "camera", 1_500_000_001)
    msg = numpy_to_image(arr, encoding, header, types=types)
    dtype, channels = SUPPORTED_ENCODINGS[encoding]
    assert (msg.height, msg.width, msg.encoding) == (5, width, encoding)
    assert msg.step == width * dtype.itemsize * channels
    assert msg.is_bigendian == int(sys.byteorder == "big")
    assert msg.header.frame_id == "camera"
    assert stamp_to_nanoseconds(msg.header.stamp) == 1_500_000_001
    back = image_to_numpy(msg)
    assert back.dtype == dtype and back.shape == arr.shape
    np.testing.assert_array_equal(back, arr)


def test_one_channel_array_with_a_unit_axis_reads_back_as_height_by_width():
    # found by the property test's dev profile: (h, w, 1) is accepted for mono16 and is
    # read back as (h, w), the documented shape of every one-channel encoding
    types = WORLDS["bag"]
    arr = np.array([[[1], [258]]], dtype=np.uint16)          # shape (1, 2, 1)
    msg = numpy_to_image(arr, "mono16", types=types)
    assert (msg.height, msg.width, msg.step) == (1, 2, 4)
    back = image_to_numpy(msg)
    assert back.shape == (1, 2)
    assert back.tolist() == [[1, 258]]


@pytest.mark.parametrize("big, raw", [(0, b"\x00\x00\x81\x7f"), (1, b"\x7f\x80\x00\x01")])
def test_signalling_nan_pixels_keep_their_bits(big, raw):
    # a 32FC1 pixel holding a signalling NaN (0x7f810000 little-endian, 0x7f800001
    # big-endian) is handed through bit for bit, also through the byteswapping copy; the
    # property test's own decoder once quieted it (0x7fc1...) by widening to a Python float
    msg = SimpleNamespace(height=1, width=1, step=4, encoding="32FC1", is_bigendian=big,
                          data=raw)
    back = image_to_numpy(msg)
    want = 0x7F810000 if not big else 0x7F800001
    assert back.dtype == np.float32 and back.shape == (1, 1)
    assert int(back.view(np.uint32)[0, 0]) == want


def test_signalling_nan_pixels_are_displayed_as_zero_without_a_warning():
    # 5x dev-profile examples: to_bgr of a 32FC1 image holding a signalling NaN warned
    # "invalid value encountered in cast" (the float64 widening raises the FPU flag)
    arr = np.array([[1.0, 1.0, 3.0]], dtype=np.float32)
    arr.view(np.uint32)[0, 0] = 0x7F810000                  # a signalling NaN
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        bgr = to_bgr(arr, "32FC1")
    # finite min 1 -> 0, max 3 -> 255, the NaN -> 0
    np.testing.assert_array_equal(bgr[0, :, 0], [0, 0, 255])


def test_ros_world_stores_bytes_as_array_array():
    if "ros" not in WORLDS:
        pytest.skip("rclpy message packages not installed")
    msg = numpy_to_image(np.full((480, 640, 3), 7, np.uint8), "bgr8", types=WORLDS["ros"])
    assert isinstance(msg.data, array.array) and len(msg.data) == 480 * 640 * 3
    assert msg.data.typecode == "B" and set(msg.data) == {7}     # the pixels, as bytes


def test_bag_world_survives_cdr_serialization():
    types = WORLDS["bag"]
    arr = sample("mono16")
    msg = numpy_to_image(arr, "mono16", make_header(types, "thermal_camera", 42), types=types)
    raw = TYPESTORE.serialize_cdr(msg, "sensor_msgs/msg/Image")
    back = TYPESTORE.deserialize_cdr(raw, "sensor_msgs/msg/Image")
    assert isinstance(back.data, np.ndarray)
    np.testing.assert_array_equal(image_to_numpy(back), arr)
    assert back.header.frame_id == "thermal_camera"


def fake(data, *, height=2, width=3, encoding="mono8", step=None, big=0):
    return SimpleNamespace(height=height, width=width, encoding=encoding, is_bigendian=big,
                           step=width if step is None else step, data=data)


def test_row_padding_is_skipped_and_result_is_a_view():
    # 2 rows of 3 pixels, step 5: bytes 3 and 4 of each row are padding
    data = np.array([1, 2, 3, 99, 99, 4, 5, 6, 99, 99], np.uint8)
    out = image_to_numpy(fake(data, step=5))
    np.testing.assert_array_equal(out, [[1, 2, 3], [4, 5, 6]])
    assert np.shares_memory(out, data)


@pytest.mark.parametrize("container", [bytes, lambda b: array.array("B", b)])
def test_reads_bytes_and_array_array(container):
    out = image_to_numpy(fake(container(bytes([1, 2, 3, 4, 5, 6]))))
    np.testing.assert_array_equal(out, [[1, 2, 3], [4, 5, 6]])


def test_big_endian_data_is_byteswapped():
    raw = bytes([0x00, 0x01, 0x01, 0x02, 0xFF, 0xFE])  # 1, 258, 65534 big-endian
    out = image_to_numpy(fake(raw, height=1, width=3, encoding="mono16", step=6, big=1))
    assert out.dtype == np.uint16 and out.dtype.isnative
    np.testing.assert_array_equal(out, [[1, 258, 65534]])
    little = image_to_numpy(fake(raw, height=1, width=3, encoding="16UC1", step=6, big=0))
    np.testing.assert_array_equal(little, [[256, 513, 65279]])


def test_non_native_array_is_written_with_its_byte_order():
    types = WORLDS["bag"]
    arr = np.array([[1, 258]], dtype=">u2")
    msg = numpy_to_image(arr, "mono16", types=types)
    assert msg.is_bigendian == 1
    assert bytes(msg.data) == bytes([0, 1, 1, 2])
    np.testing.assert_array_equal(image_to_numpy(msg), [[1, 258]])


@pytest.mark.parametrize("world", sorted(WORLDS))
def test_non_contiguous_input_is_written_correctly(world):
    base = np.arange(4 * 10 * 3, dtype=np.uint8).reshape(4, 10, 3)
    view = base[:, ::2, ::-1]  # strided columns, reversed channels
    msg = numpy_to_image(view, "rgb8", types=WORLDS[world])
    assert msg.step == 5 * 3
    np.testing.assert_array_equal(image_to_numpy(msg), view)


@pytest.mark.parametrize("msg, words", [
    (fake(bytes(6), encoding="bayer_rggb16"), "not supported"),
    (fake(bytes(12), encoding="yuv422", step=6), "width must be even"),
    (fake(bytes(18), encoding="8UC3"), "not supported"),
    (fake(bytes(6), encoding="fancy"), "unknown image encoding"),
    (fake(bytes(5)), "fewer than step*height"),
    (fake(bytes(6), step=2), "smaller than width"),
    (fake(bytes(6), width=0), "zero size"),
    (fake(bytes(6), height=0), "zero size"),
    (fake(np.zeros(6, np.float32)), "must be uint8"),
    (fake(12345), "not a byte buffer"),
    (SimpleNamespace(width=3), "not an Image message"),
])
def test_bad_messages_raise_clear_errors(msg, words):
    with pytest.raises(ImageConversionError, match=words.replace("*", r"\*")):
        image_to_numpy(msg)


@pytest.mark.parametrize("arr, encoding, words", [
    (np.zeros((4, 4), np.float64), "32FC1", "needs dtype float32"),
    (np.zeros((4, 4), np.uint8), "mono16", "needs dtype uint16"),
    (np.zeros((4, 4), np.uint8), "bgr8", "3 channel"),
    (np.zeros((4, 4, 4), np.uint8), "rgb8", "3 channel"),
    (np.zeros((0, 4, 3), np.uint8), "bgr8", "zero size"),
    (np.zeros((4, 4), bool), "mono8", "needs dtype"),
    ([[1, 2]], "mono8", "numpy array"),
    (np.zeros((4, 4), np.uint8), "bayer_rggb16", "not supported"),
])
def test_bad_arrays_raise_clear_errors(arr, encoding, words):
    with pytest.raises(ImageConversionError, match=words):
        numpy_to_image(arr, encoding, types=WORLDS["bag"])


def test_to_bgr_and_to_gray():
    rgb = np.zeros((1, 2, 3), np.uint8)
    rgb[0, 0] = (255, 0, 0)  # red
    bgr = to_bgr(rgb, "rgb8")
    np.testing.assert_array_equal(bgr[0, 0], [0, 0, 255])
    bgra = np.array([[[10, 20, 30, 255]]], np.uint8)
    np.testing.assert_array_equal(to_bgr(bgra, "bgra8"), [[[10, 20, 30]]])
    counts = np.array([[0, 1000, 2000]], np.uint16)
    np.testing.assert_array_equal(to_bgr(counts, "mono16")[0, :, 1], [0, 128, 255])
    temps = np.array([[np.nan, 20.0, 30.0]], np.float32)
    np.testing.assert_array_equal(to_bgr(temps, "32FC1")[0, :, 2], [0, 0, 255])
    assert to_gray(counts, "16UC1") is counts
    white = np.full((2, 2, 3), 255, np.uint8)
    np.testing.assert_array_equal(to_gray(white, "bgr8"), np.full((2, 2), 255))


def test_stamp_helpers():
    types = WORLDS["bag"]
    stamp = seconds_to_stamp(1.5, types)
    assert (stamp.sec, stamp.nanosec) == (1, 500_000_000)
    assert stamp_to_seconds(stamp) == 1.5
    assert stamp_to_nanoseconds(types.Time(sec=3, nanosec=7)) == 3_000_000_007
    with pytest.raises(ValueError):
        seconds_to_stamp(-1.0, types)
    with pytest.raises(ValueError):
        seconds_to_stamp(float("nan"), types)


from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402


@settings(max_examples=60, deadline=None)
@given(encoding=st.sampled_from(sorted(SUPPORTED_ENCODINGS)), h=st.integers(1, 6),
       w=st.integers(1, 6), pad=st.integers(0, 5), big=st.booleans(),
       container=st.sampled_from(["bytes", "array", "numpy"]), seed=st.integers(0, 1000))
def test_padded_buffers_of_either_byte_order_read_back(encoding, h, w, pad, big, container,
                                                        seed):
    """Rows are serialized here independently (row bytes + padding), then read back."""
    dtype, channels = SUPPORTED_ENCODINGS[encoding]
    if encoding.startswith("yuv422"):
        w += w % 2                          # pixel pairs: the width is even
    rng = np.random.default_rng(seed)
    shape = (h, w) if channels == 1 else (h, w, channels)
    arr = (rng.normal(size=shape) * 100).astype(dtype) if dtype.kind == "f" else \
        rng.integers(0, np.iinfo(dtype).max, size=shape, endpoint=True).astype(dtype)
    stored = arr.astype(dtype.newbyteorder(">" if big else "<"))
    raw = b"".join(stored[r].tobytes() + b"\xab" * pad for r in range(h))
    data = {"bytes": raw, "array": array.array("B", raw),
            "numpy": np.frombuffer(raw, np.uint8)}[container]
    msg = fake(data, height=h, width=w, encoding=encoding,
               step=w * dtype.itemsize * channels + pad, big=int(big))
    out = image_to_numpy(msg)
    assert out.dtype == dtype and out.shape == arr.shape
    np.testing.assert_array_equal(out, arr)


def test_image_cdr_is_identical_between_rclpy_and_rosbags():
    serialization = pytest.importorskip("rclpy.serialization")
    if "ros" not in WORLDS:
        pytest.skip("rclpy message packages not installed")
    arr = sample("16UC1")
    live = numpy_to_image(arr, "16UC1", make_header(WORLDS["ros"], "thermal_camera", 9),
                          types=WORLDS["ros"])
    stored = TYPESTORE.deserialize_cdr(serialization.serialize_message(live),
                                       "sensor_msgs/msg/Image")
    np.testing.assert_array_equal(image_to_numpy(stored), arr)
    offline = numpy_to_image(arr, "16UC1", types=WORLDS["bag"])
    played = serialization.deserialize_message(
        bytes(TYPESTORE.serialize_cdr(offline, "sensor_msgs/msg/Image")), type(live))
    np.testing.assert_array_equal(image_to_numpy(played), arr)
