"""Property tests of mk_tracker.messages.image_conversion on hostile Image messages and arrays.

Every generated input either converts to exactly the image an independent decoder (written
here with ``int.from_bytes``/``struct``, pixel by pixel) reads from the bytes, or raises
:class:`ImageConversionError` -- never another exception and never a wrong image.
"""

from __future__ import annotations

import array
import struct
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import event, given, settings
from hypothesis import strategies as st

import property_profile  # noqa: F401  (registers and loads the derandomized profile)
from mk_tracker.bags.bag_typestore import make_typestore
from mk_tracker.messages.image_conversion import (ImageConversionError, image_to_numpy, numpy_to_image,
                                         to_bgr, to_gray)
from mk_tracker.messages.message_types import bag_message_types, ros_message_types

# The encodings table as the ROS REP/sensor_msgs define them, written out independently:
# encoding -> (bytes per channel, channels, struct kind) ; kind: B/H unsigned, f float32
ORACLE = {"mono8": (1, 1, "B"), "8UC1": (1, 1, "B"), "mono16": (2, 1, "H"),
          "16UC1": (2, 1, "H"), "32FC1": (4, 1, "f"), "rgb8": (1, 3, "B"),
          "bgr8": (1, 3, "B"), "rgba8": (1, 4, "B"), "bgra8": (1, 4, "B")}
NUMPY_OF = {"B": np.uint8, "H": np.uint16, "f": np.float32}
OTHER_ENCODINGS = ["rgb16", "bgra16", "yuv420", "uyvy", "nv21", "bayer_rggb16", "64FC1",
                   "8SC1", "16SC1", "32SC1", "8UC3", "16UC3", "32FC3", "MONO8", "Mono16",
                   "rgb8 ", " bgr8", "bgr", "mono", "", "8UC", "32FC", "jpeg", "mono8\x00"]

WORLDS = {"bag": bag_message_types(make_typestore())}
try:
    import sensor_msgs.msg  # noqa: F401
    WORLDS["ros"] = ros_message_types()
except ImportError:   # pragma: no cover - rclpy wheels are part of the venv
    pass


def decode_independently(raw: bytes, encoding: str, height: int, width: int, step: int,
                         big: bool) -> np.ndarray:
    """The image a reader must return, decoded one value at a time.

    float32 values are unpacked as their 32-bit pattern ("I"), never through a Python float:
    widening to double quiets a signalling NaN (0x7f810000 -> 0x7fc10000), and a reader
    must hand the camera's bits through unchanged."""
    size, channels, kind = ORACLE[encoding]
    order = ">" if big else "<"
    bits_kind = {"B": "B", "H": "H", "f": "I"}[kind]
    bits = np.empty((height, width, channels), dtype=np.dtype(f"u{size}"))
    for r in range(height):
        for c in range(width):
            for k in range(channels):
                at = r * step + (c * channels + k) * size
                chunk = raw[at:at + size]
                bits[r, c, k] = struct.unpack(order + bits_kind, chunk)[0]
    out = bits.view(NUMPY_OF[kind])
    return out[:, :, 0] if channels == 1 else out


def expected_error(encoding: str, height: int, width: int, step: int, n_bytes: int) -> bool:
    if encoding not in ORACLE:
        return True
    size, channels, _ = ORACLE[encoding]
    return (height <= 0 or width <= 0 or step < width * size * channels
            or n_bytes < step * height)


def wrap(raw: bytes, container: str):
    return {"bytes": raw, "bytearray": bytearray(raw), "array": array.array("B", raw),
            "numpy": np.frombuffer(raw, np.uint8).copy()}[container]


encodings = st.one_of(st.sampled_from(sorted(ORACLE)), st.sampled_from(OTHER_ENCODINGS),
                      st.text(max_size=10))
dims = st.one_of(st.integers(-3, 7), st.sampled_from([0, 2**31 - 1, 2**32 + 1, 2**62]))


@settings(max_examples=400)
@given(hostile=st.booleans(), big=st.integers(0, 3),
       container=st.sampled_from(["bytes", "bytearray", "array", "numpy"]), data=st.data())
def test_arbitrary_messages_read_correctly_or_raise_our_error(hostile, big, container, data):
    """Half the examples are well-formed messages (any supported encoding, padding, byte
    order, extra trailing bytes), half hostile (any encoding string, size, step, length)."""
    if hostile:
        encoding = data.draw(encodings, label="encoding")
        height, width = data.draw(dims, label="height"), data.draw(dims, label="width")
    else:
        encoding = data.draw(st.sampled_from(sorted(ORACLE)), label="encoding")
        height, width = data.draw(st.integers(1, 6)), data.draw(st.integers(1, 6))
    size, channels, _ = ORACLE.get(encoding, (1, 1, "B"))
    row = max(width, 0) * size * channels
    if hostile:
        step = data.draw(st.one_of(st.integers(row - 3, row + 9), st.integers(-5, 50),
                                   st.sampled_from([2**31, 2**63 - 1])), label="step")
    else:
        step = data.draw(st.integers(row, row + 9), label="step")
    exact = max(step, 0) * max(height, 0)
    if not hostile:
        n_bytes = data.draw(st.integers(exact, exact + 7), label="n_bytes")
    elif exact <= 4096:
        n_bytes = data.draw(st.integers(max(0, exact - 5), exact + 7), label="n_bytes")
    else:
        n_bytes = data.draw(st.integers(0, 64), label="n_bytes")
    raw = data.draw(st.binary(min_size=n_bytes, max_size=n_bytes), label="raw")
    msg = SimpleNamespace(height=height, width=width, step=step, encoding=encoding,
                          is_bigendian=big, data=wrap(raw, container))
    if expected_error(encoding, height, width, step, n_bytes):
        event("rejected")
        with pytest.raises(ImageConversionError) as info:
            image_to_numpy(msg)
        assert str(info.value)          # a reason, not an empty message
        return
    event("decoded")
    out = image_to_numpy(msg)
    want = decode_independently(raw, encoding, height, width, step, bool(big))
    assert out.dtype == want.dtype and out.dtype.isnative
    assert out.shape == want.shape
    np.testing.assert_array_equal(out, want)
    if want.dtype == np.float32:        # NaN payloads and -0.0 too: compare bits
        assert np.ascontiguousarray(out).tobytes() == np.ascontiguousarray(want).tobytes()


ARRAY_DTYPES = ["u1", "i1", "<u2", ">u2", "<i2", "<f4", ">f4", "<f8", "<i4", "?"]


@settings(max_examples=300)
@given(encoding=encodings, dtype=st.sampled_from(ARRAY_DTYPES),
       shape=st.lists(st.integers(0, 5), min_size=1, max_size=4),
       step2=st.booleans(), world=st.sampled_from(sorted(WORLDS)), seed=st.integers(0, 2**16))
def test_arbitrary_arrays_round_trip_or_raise_our_error(encoding, dtype, shape, step2, world,
                                                        seed):
    types = WORLDS[world]
    rng = np.random.default_rng(seed)
    dt = np.dtype(dtype)
    raw = rng.integers(0, 256, size=int(np.prod(shape)) * dt.itemsize * (2 if step2 else 1),
                       dtype=np.uint8)
    arr = raw.view(dt).reshape([*shape[:-1], shape[-1] * (2 if step2 else 1)])
    if step2:
        arr = arr[..., ::2]                     # a non-contiguous view
    fits = False
    if encoding in ORACLE:
        size, channels, kind = ORACLE[encoding]
        want_kind = {"B": "u", "H": "u", "f": "f"}[kind]
        shape_ok = (arr.ndim == 3 and arr.shape[2] == channels) or (
            arr.ndim == 2 and channels == 1)
        fits = (dt.kind == want_kind and dt.itemsize == size and shape_ok
                and arr.shape[0] > 0 and arr.shape[1] > 0)
    event("round trip" if fits else "rejected")
    if not fits:
        with pytest.raises(ImageConversionError) as info:
            numpy_to_image(arr, encoding, types=types)
        assert str(info.value)
        return
    check_round_trip(arr, encoding, types)


def check_round_trip(arr: np.ndarray, encoding: str, types) -> None:
    """``arr`` fits ``encoding``: the message has its size and step, reads back as the same
    values, and the display/gray helpers accept it."""
    size, channels, _ = ORACLE[encoding]
    msg = numpy_to_image(arr, encoding, types=types)
    assert (msg.height, msg.width) == arr.shape[:2]
    assert msg.step == arr.shape[1] * size * channels
    back = image_to_numpy(msg)
    # image_to_numpy promises (h, w) for every one-channel encoding (its docstring, like
    # cv_bridge), so an accepted (h, w, 1) array comes back without its unit axis.
    want_shape = arr.shape[:2] if channels == 1 else arr.shape
    assert back.dtype.isnative and back.shape == want_shape
    assert np.ascontiguousarray(back).tobytes() == np.ascontiguousarray(
        arr.astype(arr.dtype.newbyteorder("="))).tobytes()
    # the display/gray helpers accept whatever was accepted, NaN/inf included
    bgr = to_bgr(back, encoding)
    assert bgr.dtype == np.uint8 and bgr.shape == (*arr.shape[:2], 3)
    gray = to_gray(back, encoding)
    assert gray.shape == arr.shape[:2]
    if encoding in ("rgb8", "rgba8"):
        np.testing.assert_array_equal(bgr, back[:, :, 2::-1])
    elif encoding in ("bgr8", "bgra8"):
        np.testing.assert_array_equal(bgr, back[:, :, :3])
    elif encoding in ("mono8", "8UC1"):
        np.testing.assert_array_equal(bgr, np.repeat(back[:, :, None], 3, axis=2))


@st.composite
def fitting_arrays(draw):
    """An array that fits a supported encoding: its kind and size in either byte order,
    (h, w) or (h, w, channels) (also (h, w, 1) for one channel), maybe a strided view."""
    encoding = draw(st.sampled_from(sorted(ORACLE)), label="encoding")
    size, channels, kind = ORACLE[encoding]
    order = draw(st.sampled_from("<>")) if size > 1 else "|"
    dt = np.dtype(f"{order}{'f' if kind == 'f' else 'u'}{size}")
    h, w = draw(st.integers(1, 5), label="h"), draw(st.integers(1, 5), label="w")
    if channels == 1:
        shape = draw(st.sampled_from([(h, w), (h, w, 1)]), label="shape")
    else:
        shape = (h, w, channels)
    step2 = draw(st.booleans(), label="strided")
    wide = (*shape[:1], shape[1] * (2 if step2 else 1), *shape[2:])
    raw = draw(st.binary(min_size=int(np.prod(wide)) * size,
                         max_size=int(np.prod(wide)) * size), label="raw")
    arr = np.frombuffer(raw, dtype=dt).reshape(wide)
    return encoding, arr[:, ::2] if step2 else arr


@settings(max_examples=200)
@given(case=fitting_arrays(), world=st.sampled_from(sorted(WORLDS)))
def test_arrays_that_fit_an_encoding_round_trip(case, world):
    # the test above meets a fitting array in ~2 % of its examples (most random arrays are
    # rejected), so the round trip gets examples of its own here
    encoding, arr = case
    check_round_trip(arr, encoding, WORLDS[world])


@settings(max_examples=60)
@given(field=st.sampled_from(["height", "width", "step", "encoding", "data", "is_bigendian"]))
def test_messages_missing_a_field_raise_our_error(field):
    values = dict(height=2, width=2, step=2, encoding="mono8", is_bigendian=0, data=b"abcd")
    del values[field]
    with pytest.raises(ImageConversionError):
        image_to_numpy(SimpleNamespace(**values))


@settings(max_examples=60)
@given(data=st.one_of(st.none(), st.integers(), st.floats(), st.text(max_size=8),
                      st.lists(st.integers(0, 255), max_size=8)))
def test_data_that_is_not_a_byte_buffer_raises_our_error(data):
    msg = SimpleNamespace(height=1, width=1, step=1, encoding="mono8", is_bigendian=0,
                          data=data)
    with pytest.raises(ImageConversionError):
        image_to_numpy(msg)
