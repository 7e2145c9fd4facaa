"""tracker_node's ``detection_wait`` over DDS: detections that arrive after their image are
used on their own frame, so the node's tracks equal the offline pipeline's exactly.

A 3-person synthetic scene (320x240) whose ground truth is sent as ``/detections`` after
each image.  The test runs lock-step (issue #12): each image is published, then after a
pause its detections, and the next image only once the node has answered the frame.  So
no frame can be replaced in the node's one-frame mailbox or in a reader queue, whatever
the machine's speed (a playback at a fixed rate lost a frame now and then on a loaded
machine: 3 times in ~20 runs with depth-1 images, and once with depth 10 beside a CPU
burner, where a frame was missing from the node's answers), and nothing in the test
depends on how fast the node is.  The premise -- the node really waited -- is checked:
every frame's tracks left the node after its detections were sent; a node that did not
wait answers during the pause, and its boxes would differ from the offline pipeline's.
``detection_wait`` is 2 s, far above the pause, so a stalled machine does not make a
frame give up waiting.  The tracker is stopped before the comparison so that its
shutdown line (frames tracked, dropped, detection waits timed out) is in any failure
message.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rclpy")
pytest.importorskip("vision_msgs.msg", reason="vision_msgs is not built into this venv")

from rclpy.serialization import deserialize_message  # noqa: E402
from sensor_msgs.msg import Image  # noqa: E402
from vision_msgs.msg import Detection2DArray  # noqa: E402

from mk_tracker.bags.bag_io import open_bag  # noqa: E402
from mk_tracker.messages.detection_messages import read_detection_array  # noqa: E402
from mk_tracker.messages.message_types import stamp_to_nanoseconds  # noqa: E402
from mk_tracker.tools.pipeline import PipelineOptions, load_pipeline_config, process_bag  # noqa: E402
from mk_tracker.synthetic.scene_bag import build_preset, write_scene_bag  # noqa: E402

from late_detections import detections_bag  # noqa: E402
from nodes_harness import domain, node_group, peer, reliable_qos  # noqa: E402,F401


FRAMES = 30
#: between an image and its detections: any value gives the same tracks (the node waits)
PAUSE_S = 0.05
#: bounds a wait for the node's answer to one frame (normally a few ms)
ANSWER_TIMEOUT_S = 30.0
DETECTION_WAIT_S = 2.0
PARAMS = """\
tracker_node:
  ros__parameters:
    thermal_frame_id: unused_thermal_frame
    detection_wait: {wait}
    image_qos:
      reliability: reliable
      depth: 10
    detections_qos:
      reliability: reliable
      depth: 50
"""


@pytest.fixture
def late_bag(tmp_path) -> Path:
    scene = build_preset("crowd", seed=1, people=3, frames=FRAMES, width=320, height=240)
    write_scene_bag(scene, tmp_path / "scene")
    with open_bag(tmp_path / "scene") as reader:
        ns = [m.timestamp_ns for m in reader.messages(["/image_raw"])]
    period = int(np.median(np.diff(ns)))
    detections_bag(tmp_path / "scene", tmp_path / "late", period // 4)
    return tmp_path / "late"


def test_detection_wait_makes_the_node_pair_like_the_offline_pipeline(late_bag, node_group,
                                                                      peer, tmp_path):
    params = tmp_path / "wait.yaml"
    params.write_text(PARAMS.format(wait=DETECTION_WAIT_S))
    # the node gets config/tracker.yaml's values (no overlay): the same tracker profile
    offline = process_bag(late_bag, tmp_path / "offline", config=load_pipeline_config([params]),
                          options=PipelineOptions(progress=False, write_video=False,
                                                  write_plots=False, tracker_profile="own"))

    tracker = node_group.start("mk_tracker.ros.tracker_node", "--params-file", str(params),
                               "-r", "thermal/detections:=/detections")
    image_pub = peer.publisher(Image, "/image_raw", reliable_qos(depth=10))
    det_pub = peer.publisher(Detection2DArray, "/detections", reliable_qos(depth=50))
    arrivals: dict[int, float] = {}
    tracks: list = []

    def on_tracks(msg) -> None:
        arrivals.setdefault(stamp_to_nanoseconds(msg.header.stamp), time.monotonic())
        tracks.append(msg)
    tracks_sub = peer.subscribe(Detection2DArray, "/tracks", on_tracks, reliable_qos(depth=100))
    assert peer.wait_matched(publishers=[image_pub, det_pub], subscriptions=[tracks_sub],
                             node_inputs=[(tracker, "/image_raw"),
                                          (tracker, "/detections")]), tracker.output()

    # lock-step, in bag order: each image, a pause, its detections, then wait for its tracks
    detections_sent: dict[int, float] = {}
    with open_bag(late_bag) as reader:
        for m in reader.messages(["/image_raw", "/detections"]):
            if m.topic == "/image_raw":
                image_pub.publish(deserialize_message(bytes(m.data), Image))
                peer.spin_for(PAUSE_S)
                continue
            msg = deserialize_message(bytes(m.data), Detection2DArray)
            ns = stamp_to_nanoseconds(msg.header.stamp)
            det_pub.publish(msg)
            detections_sent[ns] = time.monotonic()
            if ns in offline.tracks:          # the frame of these detections was played
                assert peer.spin_until(lambda: ns in arrivals, ANSWER_TIMEOUT_S), (
                    ns, tracker.output())
    assert tracker.alive(), tracker.output()
    tracker.stop()                     # its shutdown line counts frames tracked and dropped
    node_log = "\n".join(line for line in tracker.output().splitlines()
                         if "shutting down" in line or "WARN" in line or "ERROR" in line)
    online = {stamp_to_nanoseconds(m.header.stamp):
              sorted((int(d.id), d.box) for d in read_detection_array(m)) for m in tracks}

    assert offline.frames == FRAMES - 1                  # the first image is not in the bag
    assert sum(len(v) for v in offline.tracks.values()) > 2 * FRAMES   # people tracked
    assert set(online) == set(offline.tracks), (sorted(set(offline.tracks) - set(online)),
                                                node_log)
    # the premise: each frame's tracks left the node after its detections were sent, i.e.
    # the node waited for them (without waiting it answers during the pause)
    early = [ns for ns in online if arrivals[ns] < detections_sent[ns]]
    assert not early, (early, node_log)
    for ns_, expected in offline.tracks.items():
        got = online[ns_]
        assert [i for i, _ in got] == [i for i, _ in sorted(expected)], (ns_, got, expected,
                                                                         node_log)
        for (_, a), (_, b) in zip(got, sorted(expected)):
            assert np.allclose(a, b, atol=1e-6), (ns_, a, b, node_log)
    assert "'detection_waits_timed_out': 0" in node_log and "'dropped': 0" in node_log, node_log
