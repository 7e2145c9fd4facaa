"""mk_tracker.ros.debug_image_publisher: the raw and the JPEG debug image, each converted and
published only while its topic has a subscriber."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

pytest.importorskip("rclpy")

from mk_tracker.messages.message_types import ros_message_types  # noqa: E402
from mk_tracker.ros.debug_image_publisher import (COMPRESSED_TOPIC, TOPIC,  # noqa: E402
                                                  DebugImagePublisher)

TYPES = ros_message_types()


class FakePublisher:
    def __init__(self, subscribers: int) -> None:
        self.subscribers = subscribers
        self.sent: list = []

    def get_subscription_count(self) -> int:
        return self.subscribers

    def publish(self, msg) -> None:
        self.sent.append(msg)


class FakeNode:
    def __init__(self, raw: int, compressed: int) -> None:
        self.publishers = {TOPIC: FakePublisher(raw), COMPRESSED_TOPIC: FakePublisher(compressed)}
        self.types = {}

    def create_publisher(self, msg_type, topic, qos):
        self.types[topic] = msg_type
        return self.publishers[topic]


def _drawing() -> np.ndarray:
    image = np.zeros((48, 64, 3), np.uint8)
    image[10:30, 20:40] = (0, 0, 255)           # a red box on black (BGR)
    return image


@pytest.mark.parametrize("raw,compressed", [(0, 0), (1, 0), (0, 1), (2, 3)])
def test_each_topic_gets_the_drawing_only_while_subscribed(raw, compressed):
    node = FakeNode(raw, compressed)
    debug = DebugImagePublisher(node, TYPES)
    assert node.types == {TOPIC: TYPES.Image, COMPRESSED_TOPIC: TYPES.CompressedImage}
    assert debug.wanted() == bool(raw or compressed)
    header = TYPES.Header(frame_id="camera")
    debug.publish(_drawing(), header, jpeg_quality=90)
    assert len(node.publishers[TOPIC].sent) == (1 if raw else 0)
    assert len(node.publishers[COMPRESSED_TOPIC].sent) == (1 if compressed else 0)


def test_the_compressed_image_is_a_jpeg_as_image_transport_names_it():
    node = FakeNode(0, 1)
    DebugImagePublisher(node, TYPES).publish(_drawing(), TYPES.Header(frame_id="cam"), 95)
    msg = node.publishers[COMPRESSED_TOPIC].sent[0]
    assert msg.format == "bgr8; jpeg compressed bgr8"
    assert msg.header.frame_id == "cam"
    pixels = cv2.imdecode(np.frombuffer(bytes(msg.data), np.uint8), cv2.IMREAD_COLOR)
    assert pixels.shape == (48, 64, 3)
    # lossy, but the red box is still red and the background black
    assert pixels[20, 30, 2] > 200 and pixels[20, 30, :2].max() < 60
    assert pixels[2, 2].max() < 30


def test_a_lower_quality_gives_fewer_bytes():
    rng = np.random.default_rng(3)
    texture = rng.integers(0, 255, size=(120, 160, 3), dtype=np.uint8)
    sizes = []
    for quality in (95, 30):
        node = FakeNode(0, 1)
        DebugImagePublisher(node, TYPES).publish(texture, TYPES.Header(), quality)
        sizes.append(len(node.publishers[COMPRESSED_TOPIC].sent[0].data))
    assert sizes[1] < sizes[0]
