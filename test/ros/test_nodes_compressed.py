"""Both nodes on a ``/compressed`` topic (image_transport's compressed transport, #20), and
the warning of a node that receives nothing while a ``/compressed`` sibling is published.

Same timing rules as test_nodes_tracker / test_nodes_detector: connections are matched at
both ends first (``Peer.wait_matched``), frames are played lock-step, and timeouts only
bound waits for something that must happen.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

pytest.importorskip("rclpy")
pytest.importorskip("vision_msgs.msg", reason="vision_msgs is not built into this venv")

from sensor_msgs.msg import CompressedImage  # noqa: E402
from std_msgs.msg import Header  # noqa: E402
from vision_msgs.msg import Detection2DArray  # noqa: E402

from mk_tracker.messages.compressed_image import numpy_to_compressed  # noqa: E402
from mk_tracker.messages.message_types import ros_message_types  # noqa: E402
from mk_tracker.synthetic.presets import cross_modal_scene, paper_scene  # noqa: E402

from nodes_harness import (Peer, domain, latest_at, make_stamp, node_group,  # noqa: E402,F401
                           peer, reliable_qos)
from test_nodes_detector import FRAME, _quality  # noqa: E402
from test_nodes_tracker import Player, _homography_arg, _play_scene, _score  # noqa: E402

TYPES = ros_message_types()
RELIABLE = reliable_qos()


class CompressedPlayer(Player):
    """The tracker test's player, publishing JPEG CompressedImage on image_raw/compressed."""

    def __init__(self, peer: Peer, node):
        self.peer, self.node = peer, node
        self.image_pub = peer.publisher(CompressedImage, "image_raw/compressed", RELIABLE)
        self.det_pub = peer.publisher(Detection2DArray, "thermal/detections", RELIABLE)
        self.tracks = peer.collect(Detection2DArray, "tracks", RELIABLE)

    def wait_connected(self) -> None:
        ok = self.peer.wait_matched(
            publishers=[self.image_pub, self.det_pub], subscriptions=["tracks"],
            node_inputs=[(self.node, "/image_raw/compressed"),
                         (self.node, "/thermal/detections")])
        assert ok, f"tracker_node did not connect:\n{self.node.output()}"

    def send_image(self, image, stamp, encoding="bgr8", frame_id="camera"):
        header = Header(stamp=make_stamp(stamp), frame_id=frame_id)
        self.image_pub.publish(numpy_to_compressed(image, encoding, "jpeg", header,
                                                   types=TYPES, jpeg_quality=90))


def test_tracker_node_tracks_from_a_compressed_topic(peer, node_group):
    scene = cross_modal_scene(frames=40)
    node = node_group.start("mk_tracker.ros.tracker_node", "-p", _homography_arg(scene),
                            "-p", "image_qos.reliability:=reliable",
                            "-p", "image_transport:=compressed")
    player = CompressedPlayer(peer, node)
    player.wait_connected()
    results = _play_scene(player, scene)
    ious, ids = _score(results)
    assert ious.size > 40
    assert np.mean(ious) > 0.75, np.mean(ious)
    assert len(ids) == 2
    assert "skipping an image" not in node.output()


def test_detector_node_detects_in_compressed_png_frames(peer, node_group):
    scene = paper_scene()
    node = node_group.start("mk_tracker.ros.detector_node",
                            "-p", "image_qos.reliability:=reliable",
                            "-p", "image_transport:=compressed")
    pub = peer.publisher(CompressedImage, "thermal/image_raw/compressed", RELIABLE)
    detections = peer.collect(Detection2DArray, "thermal/detections", RELIABLE)
    assert peer.wait_matched(publishers=[pub], subscriptions=["thermal/detections"],
                             node_inputs=[(node, "/thermal/image_raw/compressed")]), \
        node.output()
    results = []
    for i in range(len(scene)):
        frame = scene.frame(i)
        first = len(detections)
        header = Header(stamp=make_stamp(frame.stamp), frame_id=FRAME)
        pub.publish(numpy_to_compressed(frame.thermal, "mono8", "png", header, types=TYPES))
        peer.spin_until(lambda: latest_at(detections, frame.stamp, first) is not None, 60.0)
        msg = latest_at(detections, frame.stamp, first)
        assert msg is not None, f"no detections for frame {i}:\n{node.output()}"
        results.append((frame, msg))
    ious, counts = _quality(results, warmup=8)   # PNG is lossless: the raw test's bounds
    assert np.mean(ious) > 0.8, np.mean(ious)
    assert np.mean(counts == 3) > 0.9, counts


def test_a_silent_node_names_the_compressed_sibling_once(peer, node_group):
    node = node_group.start("mk_tracker.ros.tracker_node", "-p", "no_image_warning:=0.5",
                            "-p", "warm_up:=false")
    peer.publisher(CompressedImage, "image_raw/compressed", RELIABLE)  # never publishes
    text = "/image_raw/compressed carries sensor_msgs/msg/CompressedImage"
    t0 = time.monotonic()
    assert peer.spin_until(lambda: text in node.output(), 60.0), node.output()
    waited = time.monotonic() - t0
    assert "image_transport:=compressed" in node.output()
    # once: the node checks every 0.5 s and the warning took at least one period to come,
    # so waiting as long again spans at least one more check (a bound from this run)
    peer.spin_for(max(waited, 0.5))
    assert node.output().count(text) == 1, node.output()
