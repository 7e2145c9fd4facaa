"""tracker_node on real data: TUD-Campus (MOT15, 71 frames at 25 fps, 640x480, 8 people)
imported into a bag, played by ``bag_player`` to a tracker_node process, its /tracks
collected in the test process and scored against the sequence's ground truth -- and
compared with the offline pipeline (:func:`mk_tracker.tools.pipeline.process_bag`) on the same
bag with the same parameters, which runs the same per-frame code (frame_processing).

Skipped when ``../shared/data/mot/TUD-Campus`` is absent (a user's fresh clone).

Timing (issue #12): the offline pipeline runs first, and its time per frame on this
machine, in this run, sets the playback rate (:func:`playback_rate`): a frame comes every
``FRAME_BUDGET`` offline processing times at least, and never faster than 0.1x.  A machine
twice as slow plays at half the rate (the node keeps the same margin); a machine twice as
fast keeps 0.1x (more margin).  The detections lead their image by half a frame of bag
time, which scales with the rate.  The waits for the player and the last tracks are bounds
computed from the chosen rate.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

pytest.importorskip("rclpy")
pytest.importorskip("vision_msgs.msg", reason="vision_msgs is not built into this venv")

from vision_msgs.msg import Detection2DArray  # noqa: E402

from mk_tracker.bags.bag_io import open_bag  # noqa: E402
from mk_tracker.bags.bag_writer import BagWriter  # noqa: E402
from mk_tracker.boxes import iou  # noqa: E402
from mk_tracker.bags.dataset_import import import_sequence  # noqa: E402
from mk_tracker.bags.datasets import read_sequence  # noqa: E402
from mk_tracker.messages.detection_messages import read_detection_array  # noqa: E402
from mk_tracker.evaluation.metrics import MotRow, mot_metrics  # noqa: E402
from mk_tracker.messages.message_types import stamp_to_nanoseconds  # noqa: E402
from mk_tracker.tools.pipeline import PipelineOptions, process_bag  # noqa: E402
from mk_tracker.tools.pipeline_config import load_pipeline_config  # noqa: E402

from nodes_harness import (domain, node_group, peer, reliable_qos,  # noqa: E402,F401
                           start_bag_player, stop_process_group)

# The public DPM detections hold many weak and overlapping boxes: gate them and suppress
# duplicates, as the offline TUD-Campus test does (test_pipeline.py).  Both detections and
# images reliable so the node sees every message the player sends; the images with depth 10,
# as a depth-1 reader may have an untaken image replaced by the next one (issue #12, see
# test_nodes_detection_wait.py).
PARAMS = """\
tracker_node:
  ros__parameters:
    image_qos:
      reliability: reliable
      depth: 10
    detections_qos:
      reliability: reliable
      depth: 50
    tracker:
      min_detection_score: 20.0
      new_track_max_iou: 0.3
"""
# 71 frames at 25 fps last 2.84 s; at 0.1x (28 s) a frame comes every 0.4 s, several times
# the node's processing time of a 640x480 frame, so its newest-frame-only worker drops none
# and has taken each frame's detections before the next ones arrive.  At 0.2x this held on
# an idle machine (8 of 8 runs) but not with two busy processes on the 2 cores (the slow
# first frames let a later detection batch in; online then diverged from offline).  So the
# rate is at most 0.1x and lower when the offline pipeline measured in the run is slower
# than 1/FRAME_BUDGET of a frame period at 0.1x.  The offline pipeline measured 50-90 ms a
# frame here (idle to loaded; it includes reading the bag and the metrics), so 0.1x gave
# the node 4-8 such times per frame, and 0.2x, which failed, 2-4.
MAX_RATE = 0.1
MIN_RATE = 0.02
FRAME_BUDGET = 4.0


def playback_rate(seconds_per_frame: float, frame_period_s: float) -> float:
    """Rate at which a frame comes every ``FRAME_BUDGET`` processing times
    (``seconds_per_frame``, the offline pipeline's in this run), within [MIN_RATE,
    MAX_RATE]."""
    fitting = frame_period_s / (FRAME_BUDGET * seconds_per_frame)
    return max(MIN_RATE, min(MAX_RATE, fitting))


START_NS = 1_000_000_000        # stamp of the first frame (room for the shift below)
#: /detections are stored (and so played) this long before their image, header stamps
#: unchanged.  Imported as is, a frame's detections follow its image within microseconds,
#: and whether the node's frame worker has already taken the detection buffer when they
#: arrive is a race (they are used at this frame or at the next one); the offline pipeline
#: always uses them at the next frame.  Half a frame earlier (0.2 s of wall time at RATE),
#: both use each frame's detections at that frame, so their results can be compared.
DETECTION_LEAD_NS = 20_000_000


@pytest.fixture
def tud_bag(shared_data, tmp_path):
    folder = shared_data / "mot" / "TUD-Campus"
    if not folder.is_dir():
        pytest.skip("TUD-Campus is not in the shared data")
    sequence = read_sequence(folder)
    imported = tmp_path / "tud_imported"
    counts = import_sequence(sequence, imported, start_ns=START_NS)
    assert counts["/image_raw"] == len(sequence) == 71
    assert counts["/detections"] == 71
    bag = tmp_path / "tud"
    with open_bag(imported) as reader:
        topics = reader.topics
        moved = sorted(((m.timestamp_ns - DETECTION_LEAD_NS * (m.topic == "/detections"), i, m)
                        for i, m in enumerate(reader.messages())), key=lambda t: t[:2])
        with BagWriter(bag, "mcap", typestore=reader.typestore) as writer:
            for name, info in topics.items():
                writer.add_topic(name, info.msgtype)
            for stamp, _, m in moved:
                writer.write_raw(m.topic, stamp, m.data)
    return sequence, bag


def ground_truth_rows(sequence) -> list[MotRow]:
    """The sequence's own gt.txt boxes, frames numbered 1..N (what was written to the bag's
    /ground_truth)."""
    return [MotRow(k + 1, identity, tuple(box))
            for k, frame in enumerate(sequence.ground_truth)
            for identity, box in sorted(frame.items())]


def rows_by_stamp(tracks_by_ns: dict[int, list[tuple[int, tuple]]], frame_of_ns: dict[int, int]
                  ) -> list[MotRow]:
    return [MotRow(frame_of_ns[ns], track_id, tuple(box))
            for ns, tracks in tracks_by_ns.items() if ns in frame_of_ns
            for track_id, box in tracks]


def test_tracker_node_on_tud_campus_matches_the_offline_pipeline(tud_bag, node_group, peer,
                                                                 domain, tmp_path):
    sequence, bag = tud_bag
    params = tmp_path / "tud.yaml"
    params.write_text(PARAMS)
    # offline first: the reference tracks, and this machine's time per frame right now
    t0 = time.monotonic()
    offline = process_bag(bag, tmp_path / "offline", config=load_pipeline_config([params]),
                          options=PipelineOptions(progress=False, write_video=False))
    # TUD-Campus's public scores reach 133: not the [0, 1] scale of the public-detections
    # overlay, so offline keeps config/tracker.yaml's values, as the node does
    assert offline.tracker_profile == "own"
    seconds_per_frame = (time.monotonic() - t0) / len(sequence)
    rate = playback_rate(seconds_per_frame, 1.0 / sequence.frame_rate)
    playing_s = len(sequence) / sequence.frame_rate / rate
    context = (f"offline {seconds_per_frame * 1000:.0f} ms/frame, played at {rate:.3f}x "
               f"(a frame every {1000 / sequence.frame_rate / rate:.0f} ms)")

    tracker = node_group.start("mk_tracker.ros.tracker_node", "--params-file", str(params),
                               "-r", "thermal/detections:=/detections")
    tracks = peer.collect(Detection2DArray, "/tracks", reliable_qos(depth=100))
    assert peer.wait_matched(subscriptions=["/tracks"]), tracker.output()

    log = tmp_path / "player.log"
    player = start_bag_player(bag, domain, log, rate, ["/image_raw", "/detections"])
    try:
        # the player waits up to 20 s for the node's subscriptions, then plays; bounds only
        finished = peer.spin_until(lambda: player.poll() is not None, 30.0 + 2 * playing_s)
        assert finished and player.returncode == 0, log.read_text()
        frame_of_ns = {sequence.timestamp_ns(k, START_NS): k + 1 for k in range(len(sequence))}
        peer.spin_until(lambda: len(tracks) >= len(sequence), 30.0)
    finally:
        stop_process_group(player)
    assert tracker.alive(), tracker.output()

    online: dict[int, list[tuple[int, tuple]]] = {}
    for msg in tracks:
        ns = stamp_to_nanoseconds(msg.header.stamp)
        online[ns] = [(int(d.id), d.box) for d in read_detection_array(msg)]
    answered = set(online) & set(frame_of_ns)
    # a /tracks message for (nearly) every frame: at most one lost on a loaded machine
    assert len(answered) >= len(sequence) - 1, (
        f"tracks for {len(answered)} of {len(sequence)} frames; {context}\n{log.read_text()}\n"
        f"{tracker.output()}")

    gt = ground_truth_rows(sequence)
    m_online = mot_metrics(gt, rows_by_stamp(online, frame_of_ns))
    # test_pipeline.py's offline TUD-Campus test (same parameters) guards MOTA >= 0.25 and
    # IDF1 >= 0.55 below the figure recorded there (MOTA 0.382 / IDF1 0.673); at this commit
    # the offline pipeline measures MOTA 0.599 / IDF1 0.696 on the imported bag and 0.593 /
    # 0.692 on this re-timed one, and the node measured the same 0.593 / 0.692 at 0.2x.
    # The node runs the same per-frame code, so it must pass the same guards
    # (published MOT15 trackers reach MOTA 0.5-0.7 here; ungated detections: MOTA -0.38).
    assert m_online["mota"] >= 0.25 and m_online["idf1"] >= 0.55, m_online

    assert offline.frames == len(sequence)
    m_offline = mot_metrics(gt, rows_by_stamp(offline.tracks, frame_of_ns))
    # Same bag, same parameters, same per-frame decisions: online normally equals offline
    # exactly; the tolerance allows a frame where the node saw its input differently
    # (a lost frame, a detection batch taken one frame late on a loaded machine).
    assert abs(m_online["idf1"] - m_offline["idf1"]) <= 0.05, (m_online, m_offline, context)
    assert abs(m_online["mota"] - m_offline["mota"]) <= 0.05, (m_online, m_offline, context)
    # per frame: each offline box has an online box of the same frame with IoU > 0.5 in
    # nearly every case (only frames where the node saw different input can differ)
    overlaps, differing = [], []
    for ns, boxes in sorted(offline.tracks.items()):
        if ns not in online:
            continue
        for track_id, box in boxes:
            best = max((iou(box, b) for _, b in online[ns]), default=0.0)
            overlaps.append(best)
            if best <= 0.5:
                differing.append((frame_of_ns[ns], track_id))
    assert len(overlaps) > 200, len(overlaps)
    assert np.mean(np.array(overlaps) > 0.5) >= 0.95, (
        f"offline boxes without an online match (frame, offline id): {differing}\n"
        f"{tracker.output()}")
    print(context)
