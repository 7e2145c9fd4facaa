"""/diagnostics and ~/debug_image/compressed of both nodes over DDS (#14, item 7).

Same timing rules as the other node tests: connections are matched at both ends first
(``Peer.wait_matched``), frames are played lock-step (the next frame once the answer to the
previous one arrived), and timeouts only bound waits for something that must happen.

The images are stamped with the wall clock when they are sent (the nodes run on the system
clock), so the latency a node reports (its publish time minus the stamp) can be checked
against what the test itself measured: the time from the stamp to the answer's arrival,
which contains the node's latency.
"""

from __future__ import annotations

import time

import cv2
import numpy as np
import pytest

pytest.importorskip("rclpy")
pytest.importorskip("vision_msgs.msg", reason="vision_msgs is not built into this venv")

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from sensor_msgs.msg import CompressedImage, Image  # noqa: E402
from std_msgs.msg import Header  # noqa: E402
from vision_msgs.msg import Detection2DArray  # noqa: E402

from mk_tracker.messages.image_conversion import numpy_to_image  # noqa: E402
from mk_tracker.messages.message_types import ros_message_types  # noqa: E402
from mk_tracker.synthetic.presets import cross_modal_scene, paper_scene  # noqa: E402

from nodes_harness import (domain, latest_at, make_stamp, node_group,  # noqa: E402,F401
                           peer, reliable_qos)

TYPES = ros_message_types()
RELIABLE = reliable_qos()
#: thresholds that cannot trip while the test sends frames, so the level must be OK
CALM = ("-p", "diagnostics.period:=0.2", "-p", "diagnostics.warn_latency:=3600.0",
        "-p", "diagnostics.error_no_input_periods:=1000000")
NODES = {
    "detector": ("mk_tracker.ros.detector_node", "thermal/image_raw", "thermal/detections",
                 "/detector_node", "thermal_camera"),
    "tracker": ("mk_tracker.ros.tracker_node", "image_raw", "tracks", "/tracker_node",
                "camera"),
}
FRAMES = 12


def _frames(kind: str) -> list[tuple[np.ndarray, str]]:
    if kind == "detector":
        scene = paper_scene()
        return [(scene.frame(i).thermal, "mono8") for i in range(FRAMES)]
    scene = cross_modal_scene(frames=FRAMES)
    return [(scene.frame(i).rgb, "rgb8") for i in range(FRAMES)]


def _status(msg, name: str):
    for status in msg.status:
        if status.name == name:
            return status
    return None


def _play_lock_step(peer, pub, answers, frames, frame_id):
    """Send ``frames`` one by one, each stamped now; returns the largest time from a stamp to
    the arrival of its answer (s)."""
    longest = 0.0
    for image, encoding in frames:
        stamp = time.time()
        first = len(answers)
        pub.publish(numpy_to_image(image, encoding, Header(stamp=make_stamp(stamp),
                                                           frame_id=frame_id), types=TYPES))
        assert peer.spin_until(lambda: latest_at(answers, stamp, first) is not None, 60.0)
        longest = max(longest, time.time() - stamp)
    return longest


@pytest.mark.parametrize("kind", ["detector", "tracker"])
def test_diagnostics_count_every_frame_sent_with_a_plausible_latency(peer, node_group, kind):
    module, image_topic, out_topic, fqn, frame_id = NODES[kind]
    # a window longer than the test: its figures cover every frame sent
    node = node_group.start(module, "-p", "image_qos.reliability:=reliable", *CALM,
                            "-p", "diagnostics.window:=3600.0")
    pub = peer.publisher(Image, image_topic, RELIABLE)
    answers = peer.collect(Detection2DArray, out_topic, RELIABLE)
    diagnostics = peer.collect(DiagnosticArray, "/diagnostics", RELIABLE)
    assert peer.wait_matched(publishers=[pub], subscriptions=[out_topic, "/diagnostics"],
                             node_inputs=[(node, "/" + image_topic)]), node.output()
    longest = _play_lock_step(peer, pub, answers, _frames(kind), frame_id)
    name = f"{fqn}: input"

    def counted_all():
        status = _status(diagnostics[-1], name) if diagnostics else None
        return status is not None and {kv.key: kv.value for kv in status.values}.get(
            "frames processed") == str(FRAMES)
    assert peer.spin_until(counted_all, 30.0), (node.output(), diagnostics[-1:])
    status = _status(diagnostics[-1], name)
    values = {kv.key: kv.value for kv in status.values}
    assert status.level == DiagnosticStatus.OK, (status.message, values)
    assert status.message.endswith(" Hz processed")
    assert status.hardware_id == frame_id
    for key in ("frames received", "received in window", "processed in window"):
        assert values[key] == str(FRAMES), (key, values)
    for key in ("frames dropped", "frames skipped", "dropped in window", "skipped in window"):
        assert values[key] == "0", (key, values)
    assert values["frames"] == str(FRAMES)          # the node's own statistics() ride along
    assert float(values["processed rate (Hz)"]) > 0.0
    # every frame's latency is contained in the time the test measured for its answer
    median = float(values["latency median (ms)"]) / 1000.0
    maximum = float(values["latency max (ms)"]) / 1000.0
    assert 0.0 < median <= maximum <= longest, (median, maximum, longest)
    # a DiagnosticArray every period, each with this node's status
    assert len(diagnostics) >= 2
    assert all(_status(m, name) is not None for m in diagnostics
               if any(s.name.startswith(fqn) for s in m.status))


def test_a_node_without_images_reports_an_error(peer, node_group):
    node = node_group.start("mk_tracker.ros.tracker_node", "-p", "warm_up:=false",
                            "-p", "diagnostics.period:=0.2",
                            "-p", "diagnostics.error_no_input_periods:=2")
    diagnostics = peer.collect(DiagnosticArray, "/diagnostics", RELIABLE)
    assert peer.wait_matched(subscriptions=["/diagnostics"]), node.output()

    def error():
        return any(s.level == DiagnosticStatus.ERROR for m in diagnostics for s in m.status)
    assert peer.spin_until(error, 30.0), (node.output(), diagnostics[-1:])
    status = next(s for m in diagnostics for s in m.status if s.level == DiagnosticStatus.ERROR)
    assert status.name == "/tracker_node: input"
    assert status.message.startswith("no image for ")
    assert status.message.endswith("(none since start)")
    assert status.hardware_id == ""                 # no image, no frame


def test_diagnostics_period_0_publishes_none(peer, node_group):
    node = node_group.start("mk_tracker.ros.tracker_node", "-p", "warm_up:=false",
                            "-p", "diagnostics.period:=0.0")

    def mine(infos):
        return [i for i in infos if i.node_name == "tracker_node"]
    # ~/start_track is the node's last endpoint; once the graph shows it, it shows the others
    assert peer.spin_until(lambda: mine(peer.node.get_subscriptions_info_by_topic(
        "/tracker_node/start_track")), 30.0), node.output()
    assert mine(peer.node.get_publishers_info_by_topic("/tracks"))
    assert not mine(peer.node.get_publishers_info_by_topic("/diagnostics"))


@pytest.mark.parametrize("kind", ["detector", "tracker"])
def test_debug_image_compressed_is_a_jpeg_of_the_image_size(peer, node_group, kind):
    module, image_topic, out_topic, fqn, frame_id = NODES[kind]
    node = node_group.start(module, "-p", "image_qos.reliability:=reliable",
                            "-p", "publish_debug_image:=true",
                            "-p", "debug_image_jpeg_quality:=70")
    pub = peer.publisher(Image, image_topic, RELIABLE)
    answers = peer.collect(Detection2DArray, out_topic, RELIABLE)
    topic = f"{fqn}/debug_image/compressed"
    jpegs = peer.collect(CompressedImage, topic, RELIABLE)
    assert peer.wait_matched(publishers=[pub], subscriptions=[out_topic, topic],
                             node_inputs=[(node, "/" + image_topic)]), node.output()
    frames = _frames(kind)[:3]
    _play_lock_step(peer, pub, answers, frames, frame_id)
    assert peer.spin_until(lambda: len(jpegs) >= len(frames), 30.0), node.output()
    height, width = frames[0][0].shape[:2]
    for msg in jpegs:
        assert msg.format == "bgr8; jpeg compressed bgr8"
        assert bytes(msg.data[:2]) == b"\xff\xd8"         # a JPEG's start-of-image marker
        pixels = cv2.imdecode(np.frombuffer(bytes(msg.data), np.uint8), cv2.IMREAD_COLOR)
        assert pixels is not None and pixels.shape == (height, width, 3)
        assert msg.header.frame_id == frame_id
