"""tracker_node's ``detection_wait`` over DDS: detections that arrive after their image are
used on their own frame, so the node's tracks equal the offline pipeline's exactly -- at a
playback speed where, without waiting, a frame's detections arrive after the node has
already tracked it (and would land on the next frame).

A 3-person synthetic scene (320x240) whose ground truth is played as ``/detections`` a
quarter frame after each image, by our ``bag_player``, to a tracker_node process.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rclpy")
pytest.importorskip("vision_msgs.msg", reason="vision_msgs is not built into this venv")

from vision_msgs.msg import Detection2DArray  # noqa: E402

from mk_tracker.bags.bag_io import open_bag  # noqa: E402
from mk_tracker.messages.detection_messages import read_detection_array  # noqa: E402
from mk_tracker.messages.message_types import stamp_to_nanoseconds  # noqa: E402
from mk_tracker.tools.pipeline import PipelineOptions, load_pipeline_config, process_bag  # noqa: E402
from mk_tracker.synthetic.scene_bag import build_preset, write_scene_bag  # noqa: E402

from late_detections import detections_bag  # noqa: E402
from nodes_harness import (domain, node_group, peer, reliable_qos,  # noqa: E402,F401
                           start_bag_player, stop_process_group)

FRAMES = 30
#: 0.25x: a frame every 160 ms of wall time, its detections 40 ms after it -- long after
#: the node (a few ms per 320x240 frame) has taken the frame up.
RATE = 0.25
PARAMS = """\
tracker_node:
  ros__parameters:
    detections_topic: /detections
    thermal_frame_id: unused_thermal_frame
    detection_wait: 0.5
    image_qos:
      reliability: reliable
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
                                                                      peer, domain,
                                                                      tmp_path):
    params = tmp_path / "wait.yaml"
    params.write_text(PARAMS)
    tracker = node_group.start("mk_tracker.ros.tracker_node", "--params-file", str(params))
    tracks = peer.collect(Detection2DArray, "/tracks", reliable_qos(depth=100))
    assert peer.spin_until(lambda: peer.node.count_publishers("/tracks") > 0, 20.0)
    peer.spin_for(1.0)
    log = tmp_path / "player.log"
    player = start_bag_player(late_bag, domain, log, RATE, ["/image_raw", "/detections"])
    try:
        finished = peer.spin_until(lambda: player.poll() is not None, 60.0)
        assert finished and player.returncode == 0, log.read_text()
        peer.spin_until(lambda: len(tracks) >= FRAMES - 1, 5.0)
    finally:
        stop_process_group(player)
    assert tracker.alive(), tracker.output()
    online = {stamp_to_nanoseconds(m.header.stamp):
              sorted((int(d.id), d.box) for d in read_detection_array(m)) for m in tracks}

    offline = process_bag(late_bag, tmp_path / "offline", config=load_pipeline_config([params]),
                          options=PipelineOptions(progress=False, write_video=False,
                                                  write_plots=False))
    assert offline.frames == FRAMES - 1                  # the first image is not in the bag
    assert sum(len(v) for v in offline.tracks.values()) > 2 * FRAMES   # people tracked
    for ns, expected in offline.tracks.items():
        if ns not in online:
            continue
        got = online[ns]
        assert [i for i, _ in got] == [i for i, _ in sorted(expected)], (ns, got, expected)
        for (_, a), (_, b) in zip(got, sorted(expected)):
            assert np.allclose(a, b, atol=1e-6), (ns, a, b)
    assert set(online) == set(offline.tracks), (sorted(online), sorted(offline.tracks))
    # the node logged no frame that gave up waiting
    assert "stopped waiting" not in tracker.output() or \
        " 0 frames stopped waiting" in tracker.output()
