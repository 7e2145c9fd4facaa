"""Load: a node fed faster than it can process, as a real process over DDS.

detector_node gets 640x480 thermal frames of a crowd.  The test first *measures* how fast
the node processes them on this machine, in this run (stop-and-wait: one frame, wait for its
detections, the next frame), then publishes at three times that rate, so the node is
overloaded on any machine, fast or slow (issue #12: a fixed 60 Hz was no overload on an idle
fast machine).  It must stay current -- each detections message leaves shortly after its
image and the delay does not grow over the run, because the node keeps only the newest frame
(mk_tracker.ros.latest_frame) -- report the frames it dropped in its log, and keep its
memory flat.

Why the assertions hold on a machine twice as fast or twice as slow: every time bound is a
multiple of the round trip measured in the same run (``service``), and the input rate is a
multiple of the measured processing rate; the premise (overload) is checked against the
rates actually achieved.  A node that queued frames instead of dropping them would fall
behind by (1 - 1/3) of the run's length, i.e. several seconds, while the bounds are a few
round trips.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rclpy")
pytest.importorskip("vision_msgs.msg", reason="vision_msgs is not built into this venv")

from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import Image  # noqa: E402
from std_msgs.msg import Header  # noqa: E402
from vision_msgs.msg import Detection2DArray  # noqa: E402

from mk_tracker.messages.image_conversion import numpy_to_image  # noqa: E402
from mk_tracker.messages.message_types import ros_message_types  # noqa: E402
from mk_tracker.synthetic.presets import crowd_scene  # noqa: E402

from nodes_harness import NodeProcess, Peer, make_stamp, ros_env, stamp_of  # noqa: E402
from quiet_domain import quiet_domain  # noqa: E402

TYPES = ros_message_types()
OVERLOAD = 3.0          # input rate / measured processing rate
MAX_RATE_HZ = 300.0     # what the test's publisher is asked for at most
LOAD_SECONDS = 10.0     # shortest overloaded run
QUEUE_SIGNAL_MIB = 60.0  # what a frame queue must add over the run to stand out of RSS noise
MEASURE_FRAMES = 60     # stop-and-wait frames (> 2 reconfiguration periods of 25 frames)


def rss_mib(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    raise AssertionError(f"no VmRSS for {pid}")


@pytest.fixture
def domain(monkeypatch):
    return quiet_domain(monkeypatch)


@pytest.fixture
def detector(domain, tmp_path):
    node = NodeProcess("mk_tracker.ros.detector_node", ["-p", "report_period:=1.0"],
                       ros_env(domain), tmp_path / "detector_node.log")
    try:
        assert node.wait_for_output("detecting people", 60.0), node.output()
        yield node
    finally:
        node.stop()
        assert not node.alive()


class Stream:
    """The test's side: publishes frames with increasing stamps, records send/answer times."""

    def __init__(self, peer: Peer, frames: list[np.ndarray]) -> None:
        self.peer = peer
        self.frames = frames
        self.sent: dict[float, float] = {}       # stamp -> wall time published
        self.answered: dict[float, float] = {}   # stamp -> wall time the detections arrived
        self.count = 0
        self.pub = peer.publisher(Image, "thermal/image_raw", QoSProfile(
            history=HistoryPolicy.KEEP_LAST, depth=1,
            reliability=ReliabilityPolicy.BEST_EFFORT))
        peer.node.create_subscription(
            Detection2DArray, "thermal/detections",
            lambda m: self.answered.setdefault(round(stamp_of(m), 6), time.monotonic()),
            QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=50,
                       reliability=ReliabilityPolicy.RELIABLE))

    def publish(self, stamp: float) -> float:
        stamp = round(stamp, 6)
        frame = self.frames[self.count % len(self.frames)]
        self.count += 1
        self.pub.publish(numpy_to_image(frame, "mono8",
                                        Header(stamp=make_stamp(stamp), frame_id="thermal"),
                                        types=TYPES))
        self.sent[stamp] = time.monotonic()
        return stamp


def measure_round_trips(stream: Stream, stamp0: float, frame_dt: float) -> np.ndarray:
    """Stop-and-wait: each frame is sent once the previous one was answered; returns the
    round trips (seconds) after the node's first answer (its start-up pass)."""
    trips = []
    stamp = stamp0
    for i in range(MEASURE_FRAMES + 1):
        sent = stream.publish(stamp)
        # generous: the node's very first full-frame pass; later frames take far less
        assert stream.peer.spin_until(lambda: sent in stream.answered, 60.0), \
            f"no detections for stop-and-wait frame {i}"
        if i > 0:
            trips.append(stream.answered[sent] - stream.sent[sent])
        stamp += frame_dt
    return np.array(trips)


def test_overloaded_detector_stays_current_reports_drops_and_keeps_memory_flat(domain,
                                                                               detector):
    scene = crowd_scene(n_people=12, seed=3, frames=120)
    frames = [scene.frame(i).thermal for i in range(0, 120, 2)]   # rendered up front
    peer = Peer(domain)
    memory: list[tuple[float, float]] = []
    try:
        stream = Stream(peer, frames)
        assert peer.spin_until(lambda: stream.pub.get_subscription_count() > 0
                               and peer.node.count_publishers("thermal/detections") > 0, 20.0)
        trips = measure_round_trips(stream, 10.0, 1.0 / 30.0)
        capacity = len(trips) / trips.sum()           # frames per second, stop-and-wait
        service = float(np.median(trips))
        rate_hz = min(OVERLOAD * capacity, MAX_RATE_HZ)
        # long enough that a queue of the excess frames would add twice QUEUE_SIGNAL_MIB
        # (a slow machine processes fewer frames, so it runs longer)
        frame_mib = frames[0].nbytes / 2 ** 20
        excess_mib_s = max(rate_hz - capacity, 0.1 * capacity) * frame_mib
        load_seconds = max(LOAD_SECONDS, 1.0 + 2.0 * QUEUE_SIGNAL_MIB / excess_mib_s)
        n = int(rate_hz * load_seconds)
        first_load_stamp = max(stream.sent) + 1.0
        t0 = time.monotonic()
        for i in range(n):
            stream.publish(first_load_stamp + i / rate_hz)
            if i % max(1, int(rate_hz / 4)) == 0:                 # 4 samples per second
                memory.append((time.monotonic() - t0, rss_mib(detector.proc.pid)))
            peer.spin_until(lambda: time.monotonic() >= t0 + (i + 1) / rate_hz,
                            max(0.0, t0 + (i + 1) / rate_hz - time.monotonic()))
        elapsed = time.monotonic() - t0
        peer.spin_for(max(1.0, 20 * service))
        memory.append((time.monotonic() - t0, rss_mib(detector.proc.pid)))
    finally:
        peer.close()
    assert detector.alive()
    load = sorted(s for s in stream.sent if s >= first_load_stamp)
    processed = [s for s in load if s in stream.answered]
    sent_rate = len(load) / elapsed
    rate = len(processed) / elapsed
    context = (f"stop-and-wait capacity {capacity:.1f} Hz (median round trip "
               f"{service * 1000:.1f} ms), asked {rate_hz:.1f} Hz, sent {sent_rate:.1f} Hz, "
               f"processed {rate:.1f} Hz")
    # the premise, created rather than assumed: the node got far more than it processes
    assert len(processed) >= 5, context
    assert sent_rate > 1.5 * rate, f"no overload: {context}"
    # stays current: latency = answer time - publish time, per answered frame.  Taking the
    # newest frame, a frame waits at most one processing time before it is taken; a queue
    # would grow by ~2/3 of the elapsed time (seconds)
    latency = np.array([stream.answered[s] - stream.sent[s] for s in processed])
    third = len(latency) // 3
    early, late = np.median(latency[:third]), np.median(latency[-third:])
    bound = 6.0 * service + 0.05
    assert late < bound, f"late-run median latency {late:.3f} s > {bound:.3f} s; {context}"
    assert late < early + 3.0 * service + 0.05, (
        f"latency grew from {early:.3f} s to {late:.3f} s; {context}")
    # processed frames are spread over the whole run (the newest frame is always taken):
    # no stretch of input longer than a few of the slowest measured round trips (which
    # include full-frame reconfiguration passes) goes unprocessed
    gaps = np.diff([first_load_stamp] + processed + [load[-1]])
    gap_bound = 4.0 * float(trips.max()) + 0.2
    assert gaps.max() < gap_bound, (f"a {gaps.max():.2f} s stretch of input was never "
                                    f"processed (bound {gap_bound:.2f} s); {context}")
    # reports its dropped frames.  A frame it never processed was either replaced in its
    # newest-frame slot, which it counts, or overwritten inside DDS by the depth-1
    # best-effort reader before its callback ran, which no subscriber can see.  How many
    # reach the callback depends on how fast this machine runs the executor against the
    # publisher (95-98 % at 60 Hz; about 70 % at 190 Hz on an idle fast machine, issue #12),
    # so the test does not assume a share: it checks that every frame the node received is
    # accounted for (received = processed + dropped + at most the one waiting in the slot,
    # the counters read together), that the node itself was overloaded, and that the count
    # is a lower bound, never more than the frames really skipped.
    log = detector.output()
    reports = [line for line in log.splitlines() if " frames dropped" in line]
    assert reports, f"the node never reported dropped frames; {context}\n{log[-2000:]}"
    last = reports[-1]
    frames = int(last.split(" frames, ")[0].rsplit(" ", 1)[-1])
    dropped = int(last.split(" frames dropped")[0].rsplit(" ", 1)[-1])
    received = int(last.split(" frames received")[0].rsplit(" ", 1)[-1])
    assert "0 bad images" in last and "0 frames rejected" in last, last
    assert 0 <= received - frames - dropped <= 1, (
        f"frames the node received but neither processed nor counted as dropped: {last}")
    assert received > 1.5 * frames, f"the node itself was not overloaded: {last}; {context}"
    unprocessed = len(stream.sent) - sum(s in stream.answered for s in stream.sent)
    assert 0 < dropped <= unprocessed and received <= len(stream.sent), (
        unprocessed, len(stream.sent), last, context)
    # memory flat: after the first seconds the peak stops rising.  RSS is not a smooth
    # curve: sampled 4 times a second it jumps between two levels ~35 MiB apart every 1-3 s
    # (the allocator taking and returning large temporary buffers) and its peaks differ by
    # up to ~15 MiB.  What this test is for -- frames queued because the node cannot keep
    # up -- grows by the excess input rate times 300 KiB per frame: 2/3 of the input, tens
    # of MiB per second at any overload, far past both bounds.  Slow leaks are the soak
    # benchmark's job (docs/soak.md).
    # The bound is relative to this run: a queue of the frames it did not process would have
    # added (sent - processed rate) x frame size x the settled time; the run is long enough
    # (load_seconds) that this is at least QUEUE_SIGNAL_MIB, above the noise, and the peak
    # may grow by at most half of it.  (A fixed 16 MiB bound on late vs middle peaks was
    # exceeded by 0.02 MiB once under a CPU burner: the noise itself.)
    settled = [(t, m) for t, m in memory if t >= 1.0]
    cut = 1.0 + (load_seconds - 1.0) * 2 / 3
    middle_peak = max(m for t, m in settled if t < cut)
    late_peak = max(m for t, m in settled if t >= cut)
    early_peak = max(m for t, m in settled if t < 4.0)
    queue_mib = (sent_rate - rate) * frame_mib * (elapsed - 1.0)
    assert queue_mib >= QUEUE_SIGNAL_MIB, f"a queue would not show: {queue_mib:.0f} MiB"
    assert late_peak - early_peak < 0.5 * queue_mib, (queue_mib, memory)
    print(f"load: {context}; {len(load)} sent, {len(processed)} processed, latency median "
          f"early {early * 1000:.0f} ms late {late * 1000:.0f} ms, dropped (node's report) "
          f"{dropped} of {unprocessed} unprocessed, {received} received, RSS MiB {settled[0][1]:.0f} -> "
          f"{settled[-1][1]:.0f} (peaks early {early_peak:.0f} middle {middle_peak:.0f} "
          f"late {late_peak:.0f}; a queue would have added {queue_mib:.0f})")
