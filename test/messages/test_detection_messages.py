"""Detection2DArray conventions in the rclpy world and the rosbags world."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mk_tracker.bags.bag_typestore import make_typestore
from mk_tracker.messages.detection_messages import (Detection, DetectionMessageError,
                                           make_detection_array, read_detection_array)
from mk_tracker.messages.message_types import bag_message_types, make_header, ros_message_types

STORE = make_typestore()
WORLDS = {"bag": bag_message_types(STORE)}
try:
    import vision_msgs.msg  # noqa: F401
    WORLDS["ros"] = ros_message_types()
except ImportError:
    pass

DETECTIONS = [Detection((10.0, 20.0, 30.0, 60.0), 0.9, "person", "7"),
              Detection((100.5, 0.0, 4.0, 2.0), -1.25)]


@pytest.mark.parametrize("world", sorted(WORLDS))
def test_vision_msgs_conventions(world):
    types = WORLDS[world]
    header = make_header(types, "camera", 2_000_000_123)
    msg = make_detection_array(DETECTIONS, header, types)
    first = msg.detections[0]
    # centre, full size, theta 0
    assert (first.bbox.center.position.x, first.bbox.center.position.y) == (25.0, 50.0)
    assert (first.bbox.size_x, first.bbox.size_y) == (30.0, 60.0)
    assert first.bbox.center.theta == 0.0
    assert first.id == "7" and msg.detections[1].id == ""
    assert len(first.results) == 1
    hyp = first.results[0]
    assert hyp.hypothesis.class_id == "person" and hyp.hypothesis.score == 0.9
    assert hyp.pose.pose.orientation.w == 1.0 and hyp.pose.pose.position.x == 0.0
    assert np.all(np.asarray(hyp.pose.covariance) == 0.0) and len(hyp.pose.covariance) == 36
    for det in msg.detections:
        assert det.header.frame_id == "camera"
        assert (det.header.stamp.sec, det.header.stamp.nanosec) == (2, 123)
    assert read_detection_array(msg) == DETECTIONS


def test_cdr_round_trip():
    types = WORLDS["bag"]
    msg = make_detection_array(DETECTIONS, make_header(types, "thermal_camera", 5), types)
    raw = STORE.serialize_cdr(msg, "vision_msgs/msg/Detection2DArray")
    back = STORE.deserialize_cdr(raw, "vision_msgs/msg/Detection2DArray")
    assert read_detection_array(back) == DETECTIONS
    assert back.detections[1].header.frame_id == "thermal_camera"


def test_empty_array():
    types = WORLDS["bag"]
    msg = make_detection_array([], make_header(types, "camera"), types)
    assert read_detection_array(msg) == []
    assert read_detection_array(msg, on_error="skip") == ([], 0)


@pytest.mark.parametrize("size, centre, words", [
    ((0.0, 5.0), (1.0, 1.0), "non-positive size"),
    ((5.0, -2.0), (1.0, 1.0), "non-positive size"),
    ((float("nan"), 5.0), (1.0, 1.0), "not finite"),
    ((5.0, 5.0), (float("inf"), 1.0), "not finite"),
])
def test_bad_detections_raise_or_are_skipped(size, centre, words):
    types = WORLDS["bag"]
    msg = make_detection_array(DETECTIONS, make_header(types, "camera"), types)
    bad = msg.detections[1]
    bad.bbox.size_x, bad.bbox.size_y = size
    bad.bbox.center.position.x, bad.bbox.center.position.y = centre
    with pytest.raises(DetectionMessageError, match=f"#1.*{words}"):
        read_detection_array(msg)
    good, skipped = read_detection_array(msg, on_error="skip")
    assert good == DETECTIONS[:1] and skipped == 1


def test_non_finite_score_is_rejected():
    types = WORLDS["bag"]
    msg = make_detection_array(DETECTIONS[:1], make_header(types, "camera"), types)
    msg.detections[0].results[0].hypothesis.score = math.nan
    with pytest.raises(DetectionMessageError, match="score"):
        read_detection_array(msg)


def test_detection_validates_its_box_and_score():
    with pytest.raises(DetectionMessageError, match="non-positive"):
        Detection((0, 0, 0, 5), 1.0)
    with pytest.raises(DetectionMessageError, match="score"):
        Detection((0, 0, 5, 5), float("inf"))
    d = Detection([1, 2, 3, 4], 1, 5, 9)
    assert d.box == (1.0, 2.0, 3.0, 4.0) and d.class_id == "5" and d.id == "9"
    with pytest.raises(ValueError):
        read_detection_array(make_detection_array([], None, WORLDS["bag"]), on_error="x")


def test_cdr_is_identical_between_rclpy_and_rosbags():
    """Nodes publish rclpy messages, bags hold rosbags CDR: the bytes must interconvert."""
    pytest.importorskip("vision_msgs.msg")
    serialization = pytest.importorskip("rclpy.serialization")
    ros, bag = WORLDS["ros"], WORLDS["bag"]
    live = make_detection_array(DETECTIONS, make_header(ros, "camera", 3_000_000_004), ros)
    stored = STORE.deserialize_cdr(serialization.serialize_message(live),
                                   "vision_msgs/msg/Detection2DArray")
    assert read_detection_array(stored) == DETECTIONS
    assert (stored.header.stamp.sec, stored.header.stamp.nanosec) == (3, 4)
    offline = make_detection_array(DETECTIONS, make_header(bag, "camera", 5), bag)
    raw = bytes(STORE.serialize_cdr(offline, "vision_msgs/msg/Detection2DArray"))
    played = serialization.deserialize_message(raw, type(live))
    assert read_detection_array(played) == DETECTIONS
