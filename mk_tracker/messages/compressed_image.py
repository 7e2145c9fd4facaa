"""``sensor_msgs/CompressedImage`` (JPEG, PNG) <-> numpy, following image_transport.

image_transport's ``compressed`` plugin writes ``format`` as ``"<encoding>; <jpeg|png>
compressed <target>"`` (e.g. ``"bgr8; jpeg compressed bgr8"``, ``"mono16; png compressed
mono16"``); older recorders write just ``"jpeg"`` or ``"png"``.  Decoding does not trust the
string: OpenCV reads the codec from the bytes (``IMREAD_UNCHANGED``, so a 16-bit PNG stays
uint16) and the encoding follows from what came out: 1 channel uint8 ``mono8``, uint16
``mono16``, 3 channels ``bgr8``, 4 channels ``bgra8``.  A ``format`` naming ``rgb8`` as the
original encoding does not reorder: the codecs store colour as BGR either way.

:func:`as_image` gives a decoded message the fields of a ``sensor_msgs/Image`` (its own
header kept), so the code that reads Image messages (:mod:`mk_tracker.frame_processing`)
takes it unchanged.  No rclpy here.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from mk_tracker.messages.image_conversion import (ImageConversionError, _check_array,
                                                  numpy_to_image)
from mk_tracker.messages.message_types import MessageTypes, make_header

#: ROS type names of the two image messages a camera topic may carry
IMAGE_TYPE = "sensor_msgs/msg/Image"
COMPRESSED_TYPE = "sensor_msgs/msg/CompressedImage"
#: codec name -> (OpenCV extension, encodings it can hold)
CODECS: dict[str, tuple[str, tuple[str, ...]]] = {
    "jpeg": (".jpg", ("mono8", "bgr8", "rgb8")),
    "png": (".png", ("mono8", "mono16", "16UC1", "bgr8", "rgb8", "bgra8", "rgba8")),
}


@dataclass
class DecodedImage:
    """A decoded CompressedImage with the fields of ``sensor_msgs/Image`` (``data`` a flat
    uint8 array, no row padding) and the decoded ``pixels``."""

    header: Any
    height: int
    width: int
    encoding: str
    is_bigendian: int
    step: int
    data: np.ndarray
    pixels: np.ndarray


def is_compressed(msg: Any) -> bool:
    """True for a CompressedImage-like object (a ``format`` field and no ``encoding``)."""
    return hasattr(msg, "format") and not hasattr(msg, "encoding")


def decode_compressed(msg: Any) -> tuple[np.ndarray, str]:
    """``(pixels, encoding)`` of a CompressedImage; :class:`ImageConversionError` when the
    bytes are not an image OpenCV reads."""
    try:
        data = msg.data
    except AttributeError as exc:
        raise ImageConversionError(f"not a CompressedImage message: {exc}") from exc
    if isinstance(data, np.ndarray):
        buffer = np.ascontiguousarray(data, dtype=np.uint8).reshape(-1)
    else:
        try:
            buffer = np.frombuffer(data, dtype=np.uint8)
        except (TypeError, ValueError) as exc:
            raise ImageConversionError(
                f"compressed image data of type {type(data).__name__} is not a byte "
                f"buffer") from exc
    if buffer.size == 0:
        raise ImageConversionError("compressed image has no data")
    pixels = cv2.imdecode(buffer, cv2.IMREAD_UNCHANGED)
    if pixels is None or pixels.size == 0:
        raise ImageConversionError(
            f"compressed image ({getattr(msg, 'format', '?')!r}, {buffer.size} bytes) could "
            f"not be decoded as JPEG or PNG")
    channels = 1 if pixels.ndim == 2 else pixels.shape[2]
    if pixels.dtype == np.uint16 and channels == 1:
        encoding = "mono16"
    elif pixels.dtype == np.uint8 and channels in (1, 3, 4):
        encoding = {1: "mono8", 3: "bgr8", 4: "bgra8"}[channels]
    else:
        raise ImageConversionError(
            f"compressed image decoded to {pixels.dtype} with {channels} channels, which "
            f"mk_tracker does not take (8-bit grey/BGR/BGRA or 16-bit grey)")
    return pixels, encoding


def as_image(msg: Any) -> Any:
    """An Image-like :class:`DecodedImage` of a CompressedImage; any other message is
    returned unchanged."""
    if not is_compressed(msg):
        return msg
    pixels, encoding = decode_compressed(msg)
    pixels = np.ascontiguousarray(pixels)   # imdecode gives the machine's byte order
    height, width = int(pixels.shape[0]), int(pixels.shape[1])
    return DecodedImage(header=msg.header, height=height, width=width, encoding=encoding,
                        is_bigendian=int(pixels.dtype.itemsize > 1
                                         and sys.byteorder == "big"),
                        step=width * pixels.dtype.itemsize * (
                            1 if pixels.ndim == 2 else pixels.shape[2]),
                        data=pixels.reshape(-1).view(np.uint8), pixels=pixels)


def encode_compressed(array: np.ndarray, encoding: str, codec: str,
                      jpeg_quality: int = 95) -> tuple[bytes, str]:
    """``(bytes, format)`` of ``array`` (``encoding`` gives its channel order) compressed
    with ``codec`` (``"jpeg"`` or ``"png"``); ``format`` as image_transport writes it."""
    if codec not in CODECS:
        raise ImageConversionError(f"codec {codec!r} is not one of {sorted(CODECS)}")
    extension, encodings = CODECS[codec]
    if encoding not in encodings:
        raise ImageConversionError(
            f"{codec} cannot hold a {encoding} image (it holds {', '.join(encodings)})")
    arr = _check_array(array, encoding)
    if encoding in ("rgb8", "rgba8"):      # codecs take BGR(A)
        arr = cv2.cvtColor(np.ascontiguousarray(arr),
                           cv2.COLOR_RGB2BGR if encoding == "rgb8" else cv2.COLOR_RGBA2BGRA)
    if not 0 <= int(jpeg_quality) <= 100:
        raise ImageConversionError(f"jpeg_quality must be 0..100, got {jpeg_quality}")
    params = [cv2.IMWRITE_JPEG_QUALITY, int(jpeg_quality)] if codec == "jpeg" else []
    ok, blob = cv2.imencode(extension, np.ascontiguousarray(arr), params)
    if not ok:
        raise ImageConversionError(f"OpenCV could not encode a {encoding} image as {codec}")
    stored = "bgr8" if encoding == "rgb8" else "bgra8" if encoding == "rgba8" else encoding
    return blob.tobytes(), f"{encoding}; {codec} compressed {stored}"


def numpy_to_compressed(array: np.ndarray, encoding: str, codec: str, header: Any = None, *,
                        types: MessageTypes, jpeg_quality: int = 95) -> Any:
    """A CompressedImage message of ``types`` holding ``array`` compressed with ``codec``."""
    blob, fmt = encode_compressed(array, encoding, codec, jpeg_quality)
    if header is None:
        header = make_header(types, "")
    return types.CompressedImage(header=header, format=fmt,
                                 data=types.byte_array(np.frombuffer(blob, np.uint8)))


def transport_topic(topic: str, codec: str | None) -> str:
    """The topic image_transport publishes ``topic`` on: ``<topic>/compressed`` with a
    codec, ``topic`` itself without."""
    return f"{topic}/compressed" if codec else topic


def transport_type(codec: str | None) -> str:
    """The message type of :func:`transport_topic`."""
    return COMPRESSED_TYPE if codec else IMAGE_TYPE


def image_message(array: np.ndarray, encoding: str, header: Any, *, types: MessageTypes,
                  codec: str | None = None, jpeg_quality: int = 95) -> Any:
    """An Image (``codec`` None) or a CompressedImage of ``array``."""
    if codec is None:
        return numpy_to_image(array, encoding, header, types=types)
    return numpy_to_compressed(array, encoding, codec, header, types=types,
                               jpeg_quality=jpeg_quality)
