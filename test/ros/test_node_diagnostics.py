"""mk_tracker.ros.node_diagnostics with a fake node: what it counts, the latency it records
in the node's clock, and the DiagnosticArray it builds (the DDS side:
test_nodes_diagnostics.py)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

pytest.importorskip("rclpy")
from diagnostic_msgs.msg import DiagnosticStatus  # noqa: E402

from mk_tracker.messages.message_types import ros_message_types  # noqa: E402
from mk_tracker.node_health import DiagnosticsConfig  # noqa: E402
from mk_tracker.ros.latest_frame import LatestFrameWorker  # noqa: E402
from mk_tracker.ros.node_diagnostics import TOPIC, NodeDiagnostics  # noqa: E402

TYPES = ros_message_types()


class FakeNode:
    """The node calls NodeDiagnostics makes; its ROS clock is set by the test (ns)."""

    def __init__(self) -> None:
        self.now_ns = 0
        self.published: list = []
        self.timers: list = []
        self.topics: list = []

    def get_fully_qualified_name(self) -> str:
        return "/robot/tracker_node"

    def get_clock(self):
        return SimpleNamespace(now=lambda: SimpleNamespace(
            nanoseconds=self.now_ns,
            to_msg=lambda: TYPES.Time(sec=self.now_ns // 10**9, nanosec=self.now_ns % 10**9)))

    def create_publisher(self, msg_type, topic, qos):
        self.topics.append(topic)
        return SimpleNamespace(publish=self.published.append)

    def create_timer(self, period, callback, clock=None):
        self.timers.append((period, callback, clock))


def _header(seconds: float, frame_id: str = "camera"):
    ns = round(seconds * 1e9)
    return TYPES.Header(stamp=TYPES.Time(sec=ns // 10**9, nanosec=ns % 10**9),
                        frame_id=frame_id)


def test_period_0_creates_nothing_and_published_is_a_no_op():
    node = FakeNode()
    worker = LatestFrameWorker(lambda item: None)
    diag = NodeDiagnostics(node, lambda: DiagnosticsConfig(period=0.0), worker,
                           lambda: 0, dict)
    diag.published(_header(1.0))
    assert not diag.enabled and node.topics == [] and node.timers == []
    assert diag.processed == 0


def test_latency_in_the_node_clock_and_the_status_it_publishes():
    node = FakeNode()
    worker = LatestFrameWorker(lambda item: None)     # not started: counters only
    skipped = [0]
    diag = NodeDiagnostics(node, lambda: DiagnosticsConfig(period=0.5, warn_latency=0.2),
                           worker, lambda: skipped[0], lambda: {"tracks": 3})
    assert node.topics == [TOPIC]
    (period, callback, clock), = node.timers
    assert period == 0.5 and clock is not None          # a steady clock, not the ROS one
    # 6 images arrived, 2 were replaced before they were taken; of the 4 taken, 2 were
    # answered, 1 was bad input (the node's count) and 1 raised (the worker's count)
    worker.submitted, worker.dropped, worker.errors = 6, 2, 1
    skipped[0] = 1
    # simulated time: stamps at 100 s; the node's clock reads 100.25 / 100.35 s
    node.now_ns = 100_250_000_000
    diag.published(_header(100.0, "cam_left"))
    node.now_ns = 100_350_000_000
    diag.published(_header(100.0, "cam_left"))
    callback()
    msg = node.published[-1]
    (status,) = msg.status
    values = {kv.key: kv.value for kv in status.values}
    assert status.name == "/robot/tracker_node: input"
    assert status.hardware_id == "cam_left"
    assert status.level == DiagnosticStatus.WARN       # median 300 ms > 200 ms; 4 of 6 lost
    assert status.message.startswith("4 of 6 images lost in ")    # in the window's span
    assert status.message.endswith(" s (2 dropped, 2 skipped); median latency 300.0 ms "
                                   "above 200.0 ms")
    assert values["latency median (ms)"] == "300.0"    # (250 + 350) / 2
    assert values["latency max (ms)"] == "350.0"
    assert values["frames received"] == "6"
    assert values["frames dropped"] == "2"
    assert values["frames processed"] == "2"
    assert values["frames skipped"] == "2"             # the node's 1 + the worker's error
    assert values["tracks"] == "3"
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (100, 350_000_000)
