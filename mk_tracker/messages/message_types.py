"""One namespace of message classes for two worlds: live ROS 2 nodes and offline bags.

The nodes publish rclpy message classes (``sensor_msgs.msg.Image`` ...); the offline tools
write bags with the ``rosbags`` typestore dataclasses.  Both have the same field names, so
the builders in :mod:`mk_tracker.messages.image_conversion` and :mod:`mk_tracker.messages.detection_messages`
take a :class:`MessageTypes` and pass every field by keyword (rosbags dataclasses have no
defaults).  The only real difference is how arrays are handed over:

* rosbags wants numpy arrays for ``uint8[]`` and ``float64[36]`` (no copy needed);
* rclpy stores ``uint8[]`` as ``array.array('B')``.  Handing it a numpy array makes rclpy
  iterate element-wise in Python (measured: ~150 ms for a 640x480 bgr8 image), whereas an
  ``array.array`` filled with ``frombytes`` is one ~1 ms memcpy.  :meth:`MessageTypes.byte_array`
  picks the fast path for each world.

:func:`ros_message_types` imports the ROS message packages lazily and never imports rclpy
itself; :func:`bag_message_types` takes a rosbags typestore
(see :func:`mk_tracker.bags.bag_io.make_typestore`).
"""

from __future__ import annotations

import array
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

NANOSECONDS_PER_SECOND = 1_000_000_000


class MessageTypesError(ValueError):
    """A message class is missing from the requested world (e.g. vision_msgs not built)."""


# attribute name -> ROS 2 message type name
_TYPE_NAMES: dict[str, str] = {
    "Time": "builtin_interfaces/msg/Time",
    "Header": "std_msgs/msg/Header",
    "Image": "sensor_msgs/msg/Image",
    "CompressedImage": "sensor_msgs/msg/CompressedImage",
    "Point": "geometry_msgs/msg/Point",
    "Quaternion": "geometry_msgs/msg/Quaternion",
    "Pose": "geometry_msgs/msg/Pose",
    "PoseWithCovariance": "geometry_msgs/msg/PoseWithCovariance",
    "Point2D": "vision_msgs/msg/Point2D",
    "Pose2D": "vision_msgs/msg/Pose2D",
    "BoundingBox2D": "vision_msgs/msg/BoundingBox2D",
    "ObjectHypothesis": "vision_msgs/msg/ObjectHypothesis",
    "ObjectHypothesisWithPose": "vision_msgs/msg/ObjectHypothesisWithPose",
    "Detection2D": "vision_msgs/msg/Detection2D",
    "Detection2DArray": "vision_msgs/msg/Detection2DArray",
}


class _Missing:
    """Placeholder for a class that could not be loaded; fails loudly when used."""

    def __init__(self, type_name: str, reason: str):
        self._type_name = type_name
        self._reason = reason

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        raise MessageTypesError(f"message type {self._type_name} is unavailable: {self._reason}")

    def __repr__(self) -> str:
        return f"<missing {self._type_name}: {self._reason}>"


@dataclass(frozen=True)
class MessageTypes:
    """Message classes of one world (``kind`` is ``"ros"`` or ``"bag"``)."""

    kind: str
    Time: Any
    Header: Any
    Image: Any
    CompressedImage: Any
    Point: Any
    Quaternion: Any
    Pose: Any
    PoseWithCovariance: Any
    Point2D: Any
    Pose2D: Any
    BoundingBox2D: Any
    ObjectHypothesis: Any
    ObjectHypothesisWithPose: Any
    Detection2D: Any
    Detection2DArray: Any

    def byte_array(self, data: np.ndarray) -> Any:
        """Value for a ``uint8[]`` field from a C-contiguous uint8 array.

        bag world: a flat uint8 view, no copy.  ros world: an ``array.array('B')`` filled
        with one memcpy (rclpy would otherwise iterate over a numpy array in Python).
        """
        flat = np.ascontiguousarray(data).reshape(-1).view(np.uint8)
        if self.kind == "bag":
            return flat
        out = array.array("B")
        out.frombytes(memoryview(flat))
        return out

    def float64_array(self, values: Any) -> np.ndarray:
        """Value for a fixed ``float64[N]`` field (both worlds accept a float64 array)."""
        return np.asarray(values, dtype=np.float64).reshape(-1).copy()


def _lazy_ros_class(type_name: str) -> Any:
    package, _, name = type_name.split("/")
    try:
        module = __import__(f"{package}.msg", fromlist=[name])
        return getattr(module, name)
    except (ImportError, AttributeError) as exc:
        return _Missing(type_name, f"cannot import {package}.msg.{name} ({exc})")


def ros_message_types() -> MessageTypes:
    """Message classes of the rclpy world (imports ``*.msg`` packages, never rclpy).

    A class whose package is not installed (typically vision_msgs while it is being built)
    is replaced by a placeholder that raises :class:`MessageTypesError` when called.
    """
    classes = {attr: _lazy_ros_class(name) for attr, name in _TYPE_NAMES.items()}
    return MessageTypes(kind="ros", **classes)


def bag_message_types(typestore: Any) -> MessageTypes:
    """Message classes of a rosbags typestore (vision_msgs must be registered in it)."""
    classes = {}
    for attr, name in _TYPE_NAMES.items():
        cls = typestore.types.get(name)
        classes[attr] = cls if cls is not None else _Missing(
            name, "not registered in this typestore (use mk_tracker.bags.bag_io.make_typestore())")
    return MessageTypes(kind="bag", **classes)


def stamp_to_nanoseconds(stamp: Any) -> int:
    """``builtin_interfaces/Time`` (fields ``sec``, ``nanosec``) -> integer nanoseconds."""
    return int(stamp.sec) * NANOSECONDS_PER_SECOND + int(stamp.nanosec)


def stamp_to_seconds(stamp: Any) -> float:
    """``builtin_interfaces/Time`` -> float seconds."""
    return stamp_to_nanoseconds(stamp) / NANOSECONDS_PER_SECOND


def nanoseconds_to_stamp(nanoseconds: int, types: MessageTypes) -> Any:
    """Integer nanoseconds (>= 0) -> ``Time`` message of ``types``."""
    ns = int(nanoseconds)
    if ns < 0:
        raise ValueError(f"time stamps must be non-negative, got {ns} ns")
    sec, nanosec = divmod(ns, NANOSECONDS_PER_SECOND)
    return types.Time(sec=sec, nanosec=nanosec)


def seconds_to_stamp(seconds: float, types: MessageTypes) -> Any:
    """Float seconds (finite, >= 0) -> ``Time`` message, rounded to the nearest nanosecond."""
    t = float(seconds)
    if not math.isfinite(t) or t < 0:
        raise ValueError(f"time stamps must be finite and non-negative, got {seconds!r}")
    return nanoseconds_to_stamp(round(t * NANOSECONDS_PER_SECOND), types)


def make_header(types: MessageTypes, frame_id: str, nanoseconds: int = 0) -> Any:
    """``std_msgs/Header`` with the given frame and stamp (nanoseconds since the epoch)."""
    return types.Header(stamp=nanoseconds_to_stamp(nanoseconds, types), frame_id=str(frame_id))
