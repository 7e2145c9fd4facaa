"""``vision_msgs/Detection2DArray`` <-> a plain list of :class:`Detection`.

Conventions (vision_msgs 4.1, used by every node and bag of mk_tracker):

* ``bbox.center.position.x/y`` is the box *centre* in pixels, ``bbox.center.theta`` is 0,
  ``bbox.size_x/size_y`` are the full width and height.  :class:`Detection` keeps the
  project box convention ``(x, y, w, h)`` with ``(x, y)`` the top-left corner
  (:mod:`mk_tracker.boxes`), so the conversion is :func:`~mk_tracker.boxes.xywh_to_center`
  and :func:`~mk_tracker.boxes.center_to_xywh`.
* ``Detection2D.id`` is the track id as a string; empty for a stateless detector.
* ``results`` holds exactly one ``ObjectHypothesisWithPose``: ``hypothesis.class_id`` /
  ``hypothesis.score`` and an identity pose with zero covariance (the pose is unused in 2-D).
* Every ``Detection2D.header`` equals the array's header, which is the source image's header.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Iterable, Literal

from mk_tracker.boxes import InvalidBoxError, as_box, center_to_xywh, xywh_to_center
from mk_tracker.messages.message_types import MessageTypes


class DetectionMessageError(ValueError):
    """A Detection2D cannot be turned into a usable :class:`Detection`."""


@dataclass(frozen=True)
class Detection:
    """One detected or tracked object in one image.

    ``box`` is ``(x, y, w, h)`` (top-left, pixels, floats), ``score`` the detector's
    confidence (any real number: public MOT detections are not in [0, 1]), ``class_id``
    the object class, ``id`` the track id (empty for an untracked detection).
    """

    box: tuple[float, float, float, float]
    score: float
    class_id: str = "person"
    id: str = ""

    def __post_init__(self) -> None:
        try:
            box = tuple(float(v) for v in as_box(self.box))
        except InvalidBoxError as exc:
            raise DetectionMessageError(str(exc)) from exc
        score = float(self.score)
        if not math.isfinite(score):
            raise DetectionMessageError(f"detection score {self.score!r} is not finite")
        object.__setattr__(self, "box", box)
        object.__setattr__(self, "score", score)
        object.__setattr__(self, "class_id", str(self.class_id))
        object.__setattr__(self, "id", str(self.id))


def _identity_pose(types: MessageTypes) -> Any:
    pose = types.Pose(position=types.Point(x=0.0, y=0.0, z=0.0),
                      orientation=types.Quaternion(x=0.0, y=0.0, z=0.0, w=1.0))
    return types.PoseWithCovariance(pose=pose, covariance=types.float64_array([0.0] * 36))


def make_detection(detection: Detection, header: Any, types: MessageTypes) -> Any:
    """One ``Detection2D`` following the module conventions."""
    cx, cy, w, h = xywh_to_center(detection.box)
    bbox = types.BoundingBox2D(
        center=types.Pose2D(position=types.Point2D(x=cx, y=cy), theta=0.0),
        size_x=w, size_y=h)
    result = types.ObjectHypothesisWithPose(
        hypothesis=types.ObjectHypothesis(class_id=detection.class_id,
                                          score=detection.score),
        pose=_identity_pose(types))
    return types.Detection2D(header=header, results=[result], bbox=bbox, id=detection.id)


def make_detection_array(detections: Iterable[Detection], header: Any,
                         types: MessageTypes) -> Any:
    """``Detection2DArray`` with ``header`` on the array and on every detection."""
    return types.Detection2DArray(
        header=header, detections=[make_detection(d, header, types) for d in detections])


def read_detection(msg: Any) -> Detection:
    """One ``Detection2D`` -> :class:`Detection`.

    The class and score come from the first result (the highest-scoring one when a
    producer lists several: the maximum is taken); a detection without results gets
    class ``""`` and score 0.  Raises :class:`DetectionMessageError` for a NaN/inf centre
    or size, a non-positive size, or a non-finite score in any of the results.
    """
    try:
        bbox = msg.bbox
        cx, cy = float(bbox.center.position.x), float(bbox.center.position.y)
        w, h = float(bbox.size_x), float(bbox.size_y)
        results = list(msg.results)
        track_id = str(msg.id)
    except AttributeError as exc:
        raise DetectionMessageError(f"not a vision_msgs/Detection2D: {exc}") from exc
    values = (cx, cy, w, h)
    if not all(math.isfinite(v) for v in values):
        raise DetectionMessageError(f"detection {track_id!r}: box centre/size {values} is not finite")
    if w <= 0 or h <= 0:
        raise DetectionMessageError(f"detection {track_id!r}: non-positive size {w} x {h}")
    try:
        scores = [float(r.hypothesis.score) for r in results]
    except (AttributeError, TypeError, ValueError) as exc:
        raise DetectionMessageError(f"detection {track_id!r}: bad result: {exc}") from exc
    for score in scores:   # any NaN/inf: max() over NaN would depend on the results' order
        if not math.isfinite(score):
            raise DetectionMessageError(f"detection {track_id!r}: score {score} is not finite")
    if results:
        best = max(range(len(scores)), key=scores.__getitem__)   # first of the highest
        class_id, score = str(results[best].hypothesis.class_id), scores[best]
    else:
        class_id, score = "", 0.0
    return Detection(center_to_xywh(cx, cy, w, h), score, class_id, track_id)


def read_detection_array(msg: Any, on_error: Literal["raise", "skip"] = "raise"
                         ) -> list[Detection] | tuple[list[Detection], int]:
    """``Detection2DArray`` -> list of :class:`Detection`.

    ``on_error="raise"`` (default) returns the list and raises
    :class:`DetectionMessageError` naming the index of the first bad detection;
    ``on_error="skip"`` returns ``(detections, n_skipped)``: bad detections are dropped
    and counted.
    """
    if on_error not in ("raise", "skip"):
        raise ValueError(f"on_error must be 'raise' or 'skip', got {on_error!r}")
    try:
        items = list(msg.detections)
    except AttributeError as exc:
        raise DetectionMessageError(f"not a vision_msgs/Detection2DArray: {exc}") from exc
    out: list[Detection] = []
    skipped = 0
    for index, item in enumerate(items):
        try:
            out.append(read_detection(item))
        except DetectionMessageError as exc:
            if on_error == "raise":
                raise DetectionMessageError(f"detection #{index}: {exc}") from exc
            skipped += 1
    return (out, skipped) if on_error == "skip" else out
