"""Load: a node fed faster than it can process, as a real process over DDS.

detector_node gets 640x480 thermal frames of a crowd at 60 Hz, about twice what it
processes on this machine (the test measures its real rate and checks that it is indeed
overloaded).  It must stay current -- each detections message leaves shortly after its
image and the delay does not grow over the run, because the node keeps only the newest frame
(mk_tracker.ros.latest_frame) -- report the frames it dropped in its log, and keep its
memory flat.
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

from mk_tracker.image_conversion import numpy_to_image  # noqa: E402
from mk_tracker.message_types import ros_message_types  # noqa: E402
from mk_tracker.synthetic import crowd_scene  # noqa: E402

from nodes_harness import NodeProcess, Peer, make_stamp, ros_env, stamp_of  # noqa: E402
from quiet_domain import quiet_domain  # noqa: E402

TYPES = ros_message_types()
RATE_HZ = 60.0
SECONDS = 14.0
WARM_UP_S = 3.0


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
        assert node.wait_for_output("detecting people", 30.0), node.output()
        yield node
    finally:
        node.stop()
        assert not node.alive()


def test_detector_at_60_hz_stays_current_reports_drops_and_keeps_memory_flat(domain, detector):
    scene = crowd_scene(n_people=12, seed=3, frames=120)
    frames = [scene.frame(i).thermal for i in range(0, 120, 2)]   # rendered up front
    peer = Peer(domain)
    sent: dict[float, float] = {}          # stamp -> wall time published
    answered: dict[float, float] = {}      # stamp -> wall time the detections arrived
    memory: list[tuple[float, float]] = []
    try:
        pub = peer.publisher(Image, "thermal/image_raw", QoSProfile(
            history=HistoryPolicy.KEEP_LAST, depth=1,
            reliability=ReliabilityPolicy.BEST_EFFORT))
        peer.node.create_subscription(
            Detection2DArray, "thermal/detections",
            lambda m: answered.setdefault(round(stamp_of(m), 6), time.monotonic()),
            QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=50,
                       reliability=ReliabilityPolicy.RELIABLE))
        assert peer.spin_until(lambda: pub.get_subscription_count() > 0
                               and peer.node.count_publishers("thermal/detections") > 0, 20.0)
        n = int(RATE_HZ * SECONDS)
        t0 = time.monotonic()
        for i in range(n):
            stamp = round(10.0 + i / RATE_HZ, 6)
            pub.publish(numpy_to_image(frames[i % len(frames)], "mono8",
                                       Header(stamp=make_stamp(stamp), frame_id="thermal"),
                                       types=TYPES))
            sent[stamp] = time.monotonic()
            if i % int(RATE_HZ / 4) == 0:                   # 4 samples per second
                memory.append((time.monotonic() - t0, rss_mib(detector.proc.pid)))
            peer.spin_until(lambda: time.monotonic() >= t0 + (i + 1) / RATE_HZ,
                            max(0.0, t0 + (i + 1) / RATE_HZ - time.monotonic()))
        elapsed = time.monotonic() - t0
        peer.spin_for(2.0)
        memory.append((time.monotonic() - t0, rss_mib(detector.proc.pid)))
    finally:
        peer.close()
    assert detector.alive()
    assert elapsed < SECONDS * 1.2, f"the publisher itself fell behind ({elapsed:.1f} s)"
    processed = [s for s in sorted(answered) if s in sent]
    rate = len(processed) / elapsed
    # the first start-up pass over the full frame takes ~2 s here: judge the run after it
    warm = [s for s in processed if s >= 10.0 + WARM_UP_S]
    # overloaded: it answers well under the input rate (the premise of this test)
    assert rate < 0.75 * RATE_HZ, f"detector kept up at {rate:.1f} Hz: no overload"
    assert rate > 2.0, f"detector answered only {len(processed)} frames"
    # stays current: latency = answer time - publish time, per answered frame
    latency = np.array([answered[s] - sent[s] for s in warm])
    third = len(latency) // 3
    early, late = np.median(latency[:third]), np.median(latency[-third:])
    assert late < 0.5, f"late-run median latency {late:.3f} s"
    assert late < early + 0.1, f"latency grew from {early:.3f} s to {late:.3f} s"
    # processed frames are spread over the whole run (the newest frame is always taken)
    gaps = np.diff([10.0 + WARM_UP_S] + warm + [10.0 + (len(sent) - 1) / RATE_HZ])
    assert gaps.max() < 1.0, f"a {gaps.max():.2f} s stretch of input was never processed"
    # reports its dropped frames
    log = detector.output()
    dropped = [int(line.split(" frames dropped")[0].rsplit(" ", 1)[-1])
               for line in log.splitlines() if " frames dropped" in line]
    # (frames it never processed were either replaced in its newest-frame slot, which it
    # counts, or overwritten inside DDS by the depth-1 best-effort reader before its
    # callback ran, which it cannot see.  The compiled loops release the GIL (nogil), so
    # the callback runs while a frame is processed and 95-96 % of the skipped frames reach
    # the slot here (3 runs); while they held the GIL only 17-35 % did, which failed CI at
    # a 20 % bound.  The count is a lower bound: never more than the frames really skipped.)
    unprocessed = len(sent) - len(processed)
    assert dropped and 0.5 * unprocessed < dropped[-1] <= unprocessed, (unprocessed,
                                                                         log[-2000:])
    # memory flat: after the warm-up the peak stops rising.  RSS is not a smooth curve here:
    # sampled 4 times a second it jumps between ~275 and ~312 MiB every 1-3 s (the allocator
    # taking and returning large temporary buffers; which ones is not pinned down -- the
    # reconfiguration passes are the likely candidates), keeps the high level for seconds,
    # sometimes to the end of the run, and its peaks differ by up to ~15 MiB (CI: 312 late vs
    # 304 in the middle failed an 8 MiB bound).  What this test is for -- frames queued
    # because the node cannot keep up -- would grow ~10 MiB per second at this overload, far
    # past both bounds; slow leaks are the soak benchmark's job (docs/soak.md).
    settled = [(t, m) for t, m in memory if t >= WARM_UP_S]
    cut = WARM_UP_S + (SECONDS - WARM_UP_S) * 2 / 3
    middle_peak = max(m for t, m in settled if t < cut)
    late_peak = max(m for t, m in settled if t >= cut)
    assert late_peak <= middle_peak + 16.0, memory
    # and no large growth over the run: the peak of the last third against the peak of the
    # first settled seconds (one sample against one sample failed CI once, +27.6 MiB: the
    # early sample in the low state, the last one in the high state).
    early_peak = max(m for t, m in settled if t < WARM_UP_S + 3.0)
    assert late_peak - early_peak < 25.0, memory
    print(f"load: sent {len(sent)} at {RATE_HZ:g} Hz, processed {len(processed)} "
          f"({rate:.1f} Hz), latency median early {early * 1000:.0f} ms late "
          f"{late * 1000:.0f} ms, dropped (node's report) {dropped[-1]}, RSS MiB "
          f"{settled[0][1]:.0f} -> {settled[-1][1]:.0f} (peaks early {early_peak:.0f} middle "
          f"{middle_peak:.0f} late {late_peak:.0f})")
