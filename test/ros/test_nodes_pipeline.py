"""Both nodes as separate processes, wired over DDS: thermal -> detector_node -> detections
-> tracker_node (+ RGB) -> tracks, on simulated time (/clock, use_sim_time).

The test process plays the paper's synthetic scene (thermal and RGB planes, identity
homography) in lock-step and scores the tracks against the ground truth.

Timing (issue #12): the test waits until every connection has matched at both ends it can
see -- the nodes log their readers' matches, including the tracker's reader of the
detector's output, which is discovered between the two node processes -- and then plays
lock-step: each frame is sent once the answer to the previous one came.  Nothing depends on
how fast the machine is; the timeouts only bound waits for answers that must come (60 s for
a detection, ~1000x the observed few ms; 30 s for tracks).
"""

from __future__ import annotations

from collections import Counter, defaultdict

import numpy as np
import pytest

pytest.importorskip("rclpy")
pytest.importorskip("vision_msgs.msg", reason="vision_msgs is not built into this venv")

from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import Image  # noqa: E402
from std_msgs.msg import Header  # noqa: E402
from vision_msgs.msg import Detection2DArray  # noqa: E402

from mk_tracker.boxes import iou  # noqa: E402
from mk_tracker.messages.detection_messages import read_detection_array  # noqa: E402
from mk_tracker.messages.image_conversion import numpy_to_image  # noqa: E402
from mk_tracker.messages.message_types import ros_message_types  # noqa: E402
from mk_tracker.synthetic.presets import paper_scene  # noqa: E402

from nodes_harness import (domain, latest_at, make_stamp, node_group,  # noqa: E402,F401
                           peer, reliable_qos)

TYPES = ros_message_types()
RELIABLE = reliable_qos()


@pytest.fixture
def nodes(node_group):
    common = ["-p", "use_sim_time:=true", "-p", "image_qos.reliability:=reliable"]
    return [node_group.start(module, *common)
            for module in ("mk_tracker.ros.detector_node", "mk_tracker.ros.tracker_node")]


def test_detector_and_tracker_nodes_track_the_paper_scene(peer, nodes):
    scene = paper_scene()
    clock_pub = peer.publisher(Clock, "/clock", RELIABLE)
    thermal_pub = peer.publisher(Image, "thermal/image_raw", RELIABLE)
    rgb_pub = peer.publisher(Image, "image_raw", RELIABLE)
    detections = peer.collect(Detection2DArray, "thermal/detections", RELIABLE)
    tracks = peer.collect(Detection2DArray, "tracks", RELIABLE)
    # the tracker must also be matched with the detector's output, or the first detections
    # go nowhere: its log says when its reader matched (counting the peer's own
    # subscription from here did not say whether the two node processes had matched)
    detector, tracker = nodes
    assert peer.wait_matched(
        publishers=[thermal_pub, rgb_pub], subscriptions=["thermal/detections", "tracks"],
        node_inputs=[(detector, "/thermal/image_raw"), (tracker, "/image_raw"),
                     (tracker, "/thermal/detections")]), tracker.output()
    # /clock: both nodes subscribe (use_sim_time); they do not log that reader's matches
    assert peer.spin_until(lambda: clock_pub.get_subscription_count() >= 2, 30.0)
    results = []
    for i in range(len(scene)):
        frame = scene.frame(i)
        clock_pub.publish(Clock(clock=make_stamp(frame.stamp)))
        thermal_pub.publish(numpy_to_image(
            frame.thermal, "mono8",
            Header(stamp=make_stamp(frame.stamp), frame_id="thermal_camera"), types=TYPES))
        assert peer.spin_until(lambda: latest_at(detections, frame.stamp) is not None, 60.0), \
            f"no detections for frame {i}"
        rgb_pub.publish(numpy_to_image(
            frame.rgb, "bgr8", Header(stamp=make_stamp(frame.stamp), frame_id="camera"),
            types=TYPES))
        assert peer.spin_until(lambda: latest_at(tracks, frame.stamp) is not None, 30.0), \
            f"no tracks for frame {i}"
        results.append((frame, read_detection_array(latest_at(tracks, frame.stamp))))
    ious, ids = [], defaultdict(list)
    for frame, found in results[12:]:      # detector warm-up (6 frames) + confirmation
        for obj in frame.objects:
            best = max(((iou(t.box, obj.box_rgb), t.id) for t in found), default=(0.0, ""))
            ious.append(best[0])
            if best[0] > 0.3:
                ids[obj.id].append(best[1])
    ious = np.array(ious)
    assert np.mean(ious) > 0.7, np.mean(ious)
    assert np.mean(ious > 0.5) > 0.9
    majority = {}
    for obj_id, seen in ids.items():
        top, count = Counter(seen).most_common(1)[0]
        assert count / len(seen) > 0.95, (obj_id, Counter(seen))
        majority[obj_id] = top
    assert len(set(majority.values())) == 3
    for node in nodes:
        assert node.alive()
