"""The tracker's live tracks -> ``mk_tracker_msgs/TrackedObjectArray`` (``~/tracks_detailed``).

``tracks`` (vision_msgs/Detection2DArray) carries box, score and id of the tracks a consumer
should draw; ``~/tracks_detailed`` carries every live track with its lifecycle state, its
velocity and the Kalman covariances, its age and the time since its last detection
(interfaces/mk_tracker_msgs/msg/TrackedObject.msg documents every field).

:func:`tracked_objects` is pure: :class:`~mk_tracker.tracking.track.TrackOutput` values in,
:class:`TrackedObjectFields` out (no message classes needed, unit-testable without ROS).
:func:`make_tracked_object_array` fills the message classes of
:func:`ros_track_message_types`, which imports ``mk_tracker_msgs`` lazily and never rclpy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Iterable

from mk_tracker.messages.detection_messages import Detection, make_detection
from mk_tracker.messages.message_types import MessageTypes, _lazy_ros_class

NANOSECONDS_PER_SECOND = 1_000_000_000

#: TrackState value -> the constant of TrackedObject.msg (TENTATIVE=0 ... LOST=3).
STATE_CODES = {"tentative": 0, "confirmed": 1, "occluded": 2, "lost": 3}


@dataclass(frozen=True)
class TrackedObjectFields:
    """The content of one ``TrackedObject``, in plain Python values.

    ``detection`` is exactly what ``tracks`` publishes for the track (id = track id, score =
    the track score clipped to [0, 1]); ``state`` a :data:`STATE_CODES` value; ``velocity``
    px/s; the covariances row-major 2x2; ``age`` and ``time_since_detected`` as
    ``(sec, nanosec)`` of a builtin_interfaces/Duration; ``published``: the track is on
    the ``tracks`` topic this frame.
    """

    detection: Detection
    state: int
    velocity: tuple[float, float]
    velocity_covariance: tuple[float, float, float, float]
    position_covariance: tuple[float, float, float, float]
    age: tuple[int, int]
    time_since_detected: tuple[int, int]
    hits: int
    started_by_hand: bool
    published: bool


def duration_fields(seconds: float) -> tuple[int, int]:
    """``(sec, nanosec)`` of a Duration of ``seconds`` (rounded to the nanosecond;
    ``nanosec`` in [0, 1e9) as the message requires, ``sec`` negative for a negative time).
    """
    value = float(seconds)
    if not math.isfinite(value):
        raise ValueError(f"duration {seconds!r} is not finite")
    total = round(value * NANOSECONDS_PER_SECOND)
    sec, nanosec = divmod(total, NANOSECONDS_PER_SECOND)
    return int(sec), int(nanosec)


def _finite(values: Iterable[float]) -> bool:
    return all(math.isfinite(float(v)) for v in values)


def tracked_object_fields(track: Any, class_id: str, published: bool
                          ) -> TrackedObjectFields | None:
    """One track (a :class:`~mk_tracker.tracking.track.TrackOutput`) -> its fields;
    ``published``: it is on the ``tracks`` topic this frame.

    None for a track that has no message: a deleted one, or one whose box, velocity,
    covariances or times are not finite (a diverged filter is left out, as ``tracks``
    leaves out non-finite boxes).
    """
    state = STATE_CODES.get(str(track.state))
    if state is None:
        return None
    numbers = (*track.box, *track.velocity, *track.velocity_covariance,
               *track.position_covariance, track.age, track.time_since_detection)
    if not _finite(numbers):
        return None
    detection = Detection(box=tuple(track.box), score=min(max(float(track.score), 0.0), 1.0),
                          class_id=class_id, id=str(track.id))
    return TrackedObjectFields(
        detection=detection, state=state,
        velocity=(float(track.velocity[0]), float(track.velocity[1])),
        velocity_covariance=tuple(float(v) for v in track.velocity_covariance),
        position_covariance=tuple(float(v) for v in track.position_covariance),
        age=duration_fields(track.age),
        time_since_detected=duration_fields(track.time_since_detection),
        hits=int(track.hits), started_by_hand=bool(track.manual), published=bool(published))


def tracked_objects(tracks: Iterable[Any], class_id: str, published: Iterable[int]
                    ) -> list[TrackedObjectFields]:
    """Every track that has a message (:func:`tracked_object_fields`), in the given order;
    ``published``: the ids on the ``tracks`` topic this frame."""
    on_topic = {int(i) for i in published}
    out = []
    for track in tracks:
        fields = tracked_object_fields(track, class_id, int(track.id) in on_topic)
        if fields is not None:
            out.append(fields)
    return out


@dataclass(frozen=True)
class TrackMessageTypes:
    """The message classes of ``~/tracks_detailed``."""

    TrackedObject: Any
    TrackedObjectArray: Any
    Duration: Any


def ros_track_message_types() -> TrackMessageTypes:
    """The rclpy classes (mk_tracker_msgs built by scripts/setup_env.sh, or by colcon).

    Imported the way :func:`~mk_tracker.messages.message_types.ros_message_types` imports
    its classes (never rclpy); a class whose package is missing is a placeholder that
    raises :class:`~mk_tracker.messages.message_types.MessageTypesError` when used.
    """
    return TrackMessageTypes(*(_lazy_ros_class(name) for name in (
        "mk_tracker_msgs/msg/TrackedObject", "mk_tracker_msgs/msg/TrackedObjectArray",
        "builtin_interfaces/msg/Duration")))


def make_tracked_object_array(objects: Iterable[TrackedObjectFields], header: Any,
                              types: MessageTypes, track_types: TrackMessageTypes) -> Any:
    """``TrackedObjectArray`` with ``header`` on the array and on every detection."""
    def duration(value: tuple[int, int]) -> Any:
        return track_types.Duration(sec=value[0], nanosec=value[1])

    return track_types.TrackedObjectArray(header=header, tracks=[
        track_types.TrackedObject(
            detection=make_detection(o.detection, header, types), state=o.state,
            velocity_x=o.velocity[0], velocity_y=o.velocity[1],
            velocity_covariance=list(o.velocity_covariance),
            position_covariance=list(o.position_covariance),
            age=duration(o.age), time_since_detected=duration(o.time_since_detected),
            hits=o.hits, started_by_hand=o.started_by_hand, published=o.published)
        for o in objects])
