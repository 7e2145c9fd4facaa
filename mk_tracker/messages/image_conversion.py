"""``sensor_msgs/Image`` <-> numpy without cv_bridge.

Reading (:func:`image_to_numpy`) works on any object with the fields ``height``, ``width``,
``encoding``, ``is_bigendian``, ``step`` and ``data``: rclpy messages (``data`` is an
``array.array('B')`` or ``bytes``) and rosbags dataclasses (``data`` is a numpy uint8 array).
Writing (:func:`numpy_to_image`) builds the message class of a
:class:`mk_tracker.messages.message_types.MessageTypes` (rclpy world or rosbags world).

Supported encodings (:data:`SUPPORTED_ENCODINGS`)::

    mono8 8UC1 (uint8, 1 channel)   mono16 16UC1 (uint16, 1)   32FC1 (float32, 1)
    rgb8 bgr8 (uint8, 3)            rgba8 bgra8 (uint8, 4)
    camera encodings (:data:`CAMERA_ENCODINGS`), read raw and converted by OpenCV:
    yuv422 = UYVY, yuv422_yuy2 = YUYV (uint8, 2: chroma, luma; even width; BT.601 video range)
    bayer_rggb8 bayer_bggr8 bayer_gbrg8 bayer_grbg8 (uint8, 1: the mosaic)

Everything else is rejected with :class:`ImageConversionError`; known-but-unsupported names
(:data:`UNSUPPORTED_ENCODINGS`: 16-bit Bayer, NV21, 16-bit colour, the
multi-channel and signed ``nUCk``/``nSCk``/``nFCk`` forms) get a message that says so.
``sensor_msgs/CompressedImage`` (JPEG/PNG) is decoded by
:mod:`mk_tracker.messages.compressed_image`.

Copies: reading returns a *view* of the message buffer (no copy; read-only when the buffer
is ``bytes``) except when ``is_bigendian`` differs from the machine for a multi-byte
encoding, where the data is byteswapped into a new array.  Writing copies once into the
message (a numpy view in the bag world is not a copy when the input is already
C-contiguous; the rclpy world always copies into an ``array.array``, one memcpy).
"""

from __future__ import annotations

import sys
from typing import Any

import cv2
import numpy as np

from mk_tracker.messages.message_types import MessageTypes, make_header


class ImageConversionError(ValueError):
    """An image message or array cannot be converted (encoding, size, dtype, buffer)."""


# encoding -> (numpy dtype, channels)
SUPPORTED_ENCODINGS: dict[str, tuple[np.dtype, int]] = {
    "mono8": (np.dtype(np.uint8), 1),
    "8UC1": (np.dtype(np.uint8), 1),
    "mono16": (np.dtype(np.uint16), 1),
    "16UC1": (np.dtype(np.uint16), 1),
    "32FC1": (np.dtype(np.float32), 1),
    "rgb8": (np.dtype(np.uint8), 3),
    "bgr8": (np.dtype(np.uint8), 3),
    "rgba8": (np.dtype(np.uint8), 4),
    "bgra8": (np.dtype(np.uint8), 4),
    "yuv422": (np.dtype(np.uint8), 2),
    "yuv422_yuy2": (np.dtype(np.uint8), 2),
    "bayer_rggb8": (np.dtype(np.uint8), 1),
    "bayer_bggr8": (np.dtype(np.uint8), 1),
    "bayer_gbrg8": (np.dtype(np.uint8), 1),
    "bayer_grbg8": (np.dtype(np.uint8), 1),
}

# Camera encodings -> (OpenCV code to BGR, OpenCV code to gray).  OpenCV names a Bayer
# pattern by the second row's first two pixels, so ROS ``rggb`` is OpenCV ``BG`` (the test
# checks this on a hand-built mosaic).
CAMERA_ENCODINGS: dict[str, tuple[int, int]] = {
    "yuv422": (cv2.COLOR_YUV2BGR_UYVY, cv2.COLOR_YUV2GRAY_UYVY),
    "yuv422_yuy2": (cv2.COLOR_YUV2BGR_YUY2, cv2.COLOR_YUV2GRAY_YUY2),
    "bayer_rggb8": (cv2.COLOR_BayerBG2BGR, cv2.COLOR_BayerBG2GRAY),
    "bayer_bggr8": (cv2.COLOR_BayerRG2BGR, cv2.COLOR_BayerRG2GRAY),
    "bayer_gbrg8": (cv2.COLOR_BayerGR2BGR, cv2.COLOR_BayerGR2GRAY),
    "bayer_grbg8": (cv2.COLOR_BayerGB2BGR, cv2.COLOR_BayerGB2GRAY),
}

UNSUPPORTED_ENCODINGS: frozenset[str] = frozenset(
    ["rgb16", "bgr16", "rgba16", "bgra16", "uyvy", "yuyv", "nv21",
     "nv24", "bayer_rggb16",
     "bayer_bggr16", "bayer_gbrg16", "bayer_grbg16", "64FC1", "8SC1", "16SC1", "32SC1"]
    + [f"{bits}{kind}C{n}" for bits in (8, 16, 32, 64) for kind in "USF"
       for n in (2, 3, 4) if not (kind == "F" and bits < 32)]
)

_MACHINE_BIG_ENDIAN = sys.byteorder == "big"


def encoding_info(encoding: str) -> tuple[np.dtype, int]:
    """``(dtype, channels)`` of a supported encoding, else :class:`ImageConversionError`."""
    try:
        return SUPPORTED_ENCODINGS[encoding]
    except (KeyError, TypeError):
        pass
    if encoding in UNSUPPORTED_ENCODINGS:
        raise ImageConversionError(
            f"image encoding {encoding!r} is not supported by mk_tracker "
            f"(supported: {', '.join(SUPPORTED_ENCODINGS)})")
    raise ImageConversionError(
        f"unknown image encoding {encoding!r} (supported: {', '.join(SUPPORTED_ENCODINGS)})")


def _byte_buffer(data: Any) -> np.ndarray:
    """Flat uint8 view of a message ``data`` field without copying."""
    if isinstance(data, np.ndarray):
        if data.dtype != np.uint8:
            raise ImageConversionError(f"image data array must be uint8, got {data.dtype}")
        if data.ndim != 1 or not data.flags.c_contiguous:
            # unusual (a rosbags message always holds a flat array); a copy is unavoidable
            data = np.ascontiguousarray(data).reshape(-1)
        return data
    try:
        return np.frombuffer(data, dtype=np.uint8)
    except (TypeError, ValueError) as exc:
        raise ImageConversionError(
            f"image data of type {type(data).__name__} is not a byte buffer") from exc


def image_to_numpy(msg: Any) -> np.ndarray:
    """Pixel array of an Image message: ``(height, width)`` for one channel, else
    ``(height, width, channels)``, in the encoding's dtype and channel order (no colour
    conversion).  A view of ``msg.data`` (row padding skipped via strides) unless a byteswap
    is needed; see the module docstring.
    """
    try:
        height, width, step = int(msg.height), int(msg.width), int(msg.step)
        encoding, big = msg.encoding, bool(msg.is_bigendian)
        data = msg.data
    except AttributeError as exc:
        raise ImageConversionError(f"not an Image message: {exc}") from exc
    dtype, channels = encoding_info(encoding)
    if height <= 0 or width <= 0:
        raise ImageConversionError(f"image has zero size ({width}x{height})")
    _check_even_width(encoding, width)
    pixel_bytes = dtype.itemsize * channels
    if step < width * pixel_bytes:
        raise ImageConversionError(
            f"step {step} is smaller than width*bytes_per_pixel = {width}*{pixel_bytes}")
    buffer = _byte_buffer(data)
    if buffer.size < step * height:
        raise ImageConversionError(
            f"image data has {buffer.size} bytes, fewer than step*height = {step}*{height}")
    stored = dtype.newbyteorder(">" if big else "<") if dtype.itemsize > 1 else dtype
    shape: tuple[int, ...] = (height, width, channels)
    strides: tuple[int, ...] = (step, pixel_bytes, dtype.itemsize)
    if channels == 1:
        shape, strides = shape[:2], strides[:2]
    view = np.ndarray(shape=shape, dtype=stored, buffer=buffer, strides=strides)
    if dtype.itemsize > 1 and big != _MACHINE_BIG_ENDIAN:
        return view.astype(dtype)  # byteswapped copy in native order
    return view


def _check_even_width(encoding: str, width: int) -> None:
    if encoding.startswith("yuv422") and width % 2:
        raise ImageConversionError(
            f"encoding {encoding} packs two pixels per 4 bytes: the width must be even, "
            f"got {width}")


def _check_array(array: Any, encoding: str) -> np.ndarray:
    dtype, channels = encoding_info(encoding)
    if not isinstance(array, np.ndarray):
        raise ImageConversionError(f"expected a numpy array, got {type(array).__name__}")
    if array.dtype.kind != dtype.kind or array.dtype.itemsize != dtype.itemsize:
        raise ImageConversionError(
            f"encoding {encoding} needs dtype {dtype}, got {array.dtype}")
    if array.ndim == 3 and array.shape[2] == channels:
        pass
    elif array.ndim == 2 and channels == 1:
        pass
    else:
        raise ImageConversionError(
            f"encoding {encoding} needs {channels} channel(s): shape (h, w"
            f"{', %d' % channels if channels > 1 else ''}), got shape {array.shape}")
    if array.shape[0] == 0 or array.shape[1] == 0:
        raise ImageConversionError(f"image has zero size (shape {array.shape})")
    _check_even_width(encoding, int(array.shape[1]))
    return array


def numpy_to_image(array: np.ndarray, encoding: str, header: Any = None, *,
                   types: MessageTypes) -> Any:
    """Build an Image message of ``types`` from a ``(h, w[, c])`` array.

    The dtype must match the encoding (byte order may be either: a non-native array is
    stored as-is with ``is_bigendian`` set accordingly).  Non-contiguous arrays (slices,
    transposes) are copied to a C-contiguous buffer first.  ``header`` defaults to stamp 0
    and an empty frame id.  ``step`` is ``width * bytes_per_pixel`` (no padding).
    """
    arr = _check_array(array, encoding)
    if not arr.flags.c_contiguous:
        arr = np.ascontiguousarray(arr)
    order = arr.dtype.byteorder
    if arr.dtype.itemsize == 1 or order == "|":
        big = False
    elif order == "=":
        big = _MACHINE_BIG_ENDIAN
    else:
        big = order == ">"
    height, width = int(arr.shape[0]), int(arr.shape[1])
    if header is None:
        header = make_header(types, "")
    return types.Image(header=header, height=height, width=width, encoding=encoding,
                       is_bigendian=int(big), step=width * arr.dtype.itemsize *
                       (arr.shape[2] if arr.ndim == 3 else 1),
                       data=types.byte_array(arr))


def _to_uint8(array: np.ndarray) -> np.ndarray:
    """Scale a 16-bit or float single-channel image to uint8 by its own min..max range."""
    # widening a signalling-NaN float32 pixel raises the FPU "invalid" flag (a
    # RuntimeWarning per frame); it becomes a quiet NaN and is mapped to 0 below anyway
    with np.errstate(invalid="ignore"):
        values = np.asarray(array, dtype=np.float64)
    finite = np.isfinite(values)
    if not finite.any():
        return np.zeros(values.shape, np.uint8)
    lo, hi = float(values[finite].min()), float(values[finite].max())
    scale = 255.0 / (hi - lo) if hi > lo else 0.0
    out = np.where(finite, (values - lo) * scale, 0.0)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def to_gray(array: np.ndarray, encoding: str) -> np.ndarray:
    """Single-channel image.  Single-channel encodings are returned unchanged (same dtype,
    e.g. uint16 thermal counts or float32 temperatures); colour encodings become uint8 gray
    with OpenCV's BT.601 weights; YUV 4:2:2 gives its luma, Bayer its demosaiced gray."""
    arr = _check_array(array, encoding)
    if encoding in CAMERA_ENCODINGS:
        return cv2.cvtColor(np.ascontiguousarray(arr), CAMERA_ENCODINGS[encoding][1])
    _, channels = SUPPORTED_ENCODINGS[encoding]
    if channels == 1:
        return arr if arr.ndim == 2 else arr[:, :, 0]
    code = {"rgb8": cv2.COLOR_RGB2GRAY, "bgr8": cv2.COLOR_BGR2GRAY,
            "rgba8": cv2.COLOR_RGBA2GRAY, "bgra8": cv2.COLOR_BGRA2GRAY}[encoding]
    return cv2.cvtColor(np.ascontiguousarray(arr), code)


def to_bgr(array: np.ndarray, encoding: str) -> np.ndarray:
    """uint8 BGR image ``(h, w, 3)`` for colour trackers and display.

    8-bit encodings are converted exactly (``bgr8`` is returned as is); the camera encodings
    by OpenCV (YUV 4:2:2 with BT.601 video-range coefficients, Bayer by bilinear demosaicing).  ``mono16``/``16UC1``
    /``32FC1`` are scaled to 0..255 by the image's own finite min..max (a display mapping, not
    a calibrated one; non-finite pixels become 0).
    """
    arr = _check_array(array, encoding)
    if encoding == "bgr8":
        return arr
    if encoding in CAMERA_ENCODINGS:   # one OpenCV call: YUV 4:2:2 or Bayer demosaicing
        return cv2.cvtColor(np.ascontiguousarray(arr), CAMERA_ENCODINGS[encoding][0])
    if encoding in ("rgb8", "rgba8", "bgra8"):
        code = {"rgb8": cv2.COLOR_RGB2BGR, "rgba8": cv2.COLOR_RGBA2BGR,
                "bgra8": cv2.COLOR_BGRA2BGR}[encoding]
        return cv2.cvtColor(np.ascontiguousarray(arr), code)
    gray = arr if arr.ndim == 2 else arr[:, :, 0]
    if gray.dtype != np.uint8:
        gray = _to_uint8(gray)
    return cv2.cvtColor(np.ascontiguousarray(gray), cv2.COLOR_GRAY2BGR)


def image_message_to_bgr(msg: Any) -> np.ndarray:
    """Shortcut: :func:`to_bgr` of :func:`image_to_numpy`."""
    return to_bgr(image_to_numpy(msg), msg.encoding)


def bgr_to_image(bgr: np.ndarray, types: MessageTypes, frame_id: str = "camera",
                 stamp_ns: int = 0) -> Any:
    """Shortcut: a ``bgr8`` Image with a header built from ``frame_id`` and ``stamp_ns``."""
    return numpy_to_image(bgr, "bgr8", make_header(types, frame_id, stamp_ns), types=types)
