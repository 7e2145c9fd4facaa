"""image_transport naming and the advice a silent node gives from the ROS graph (#20)."""

import pytest

from mk_tracker.messages.image_transport import (message_type, silence_advice,
                                                 subscription_topic)

IMAGE, COMPRESSED = "sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage"


def test_topics_and_types_of_each_transport():
    assert subscription_topic("/cam/image_raw", "raw") == "/cam/image_raw"
    assert subscription_topic("image_raw", "compressed") == "image_raw/compressed"
    assert message_type("raw") == IMAGE and message_type("compressed") == COMPRESSED
    with pytest.raises(ValueError, match="image_transport"):
        subscription_topic("image_raw", "theora")


def test_a_compressed_sibling_names_the_parameter():
    graph = {"/cam/image_raw/compressed": [COMPRESSED], "/tracks": ["x/msg/Y"]}
    text = silence_advice("/cam/image_raw", "raw", graph)
    assert "/cam/image_raw/compressed carries sensor_msgs/msg/CompressedImage" in text
    assert "image_transport:=compressed" in text


def test_the_topic_with_another_type_is_named():
    text = silence_advice("/cam/image_raw", "raw", {"/cam/image_raw": [COMPRESSED]})
    assert "it carries sensor_msgs/msg/CompressedImage" in text
    assert "image_transport:=compressed" in text
    text = silence_advice("/cam/image_raw", "raw", {"/cam/image_raw": ["std_msgs/msg/String"]})
    assert "std_msgs/msg/String" in text and "Image topic" in text


def test_a_raw_topic_beside_an_unpublished_compressed_one():
    text = silence_advice("/cam/image_raw/compressed", "compressed", {"/cam/image_raw": [IMAGE]})
    assert "image_transport:=raw" in text


def test_nothing_to_say_when_the_graph_shows_no_reason():
    assert silence_advice("/cam/image_raw", "raw", {}) is None
    assert silence_advice("/cam/image_raw", "raw", {"/cam/image_raw": [IMAGE]}) is None
    assert silence_advice("/c/compressed", "compressed", {"/c/compressed": [COMPRESSED]}) is None
