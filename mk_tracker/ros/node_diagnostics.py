"""``/diagnostics`` of a node's image input: one ``diagnostic_msgs/DiagnosticStatus`` per
node, published once per ``diagnostics.period`` seconds of wall time.

The figures and the OK / WARN / ERROR rules are :mod:`mk_tracker.node_health`'s; this
module only feeds it and builds the message:

* images received and dropped are the :class:`~mk_tracker.ros.latest_frame.LatestFrameWorker`'s
  counters (its ``submit`` is the subscription callback, which stays as thin as it was);
* :meth:`NodeDiagnostics.published` is called by the worker thread when a frame's output
  is ready, just before it is published (so no subscriber can see it sooner): it counts the frame and records its latency, ``now - header.stamp`` in the
  node's clock (the ROS clock, so with ``use_sim_time`` the simulated time of ``/clock``);
* skipped frames are the node's own count of frames it took but could not use (bad input,
  rejected by the algorithm) plus the worker's count of frames whose processing raised.

The timer runs on a steady clock, so diagnostics keep coming when ``/clock`` stops.  The
status is named ``"<fully qualified node name>: input"``, its ``hardware_id`` is the
``frame_id`` of the last image published (empty before the first), and its values end with
the node's ``statistics()``.
"""

from __future__ import annotations

from typing import Any, Callable

from rclpy.clock import Clock, ClockType

from mk_tracker.messages.message_types import stamp_to_nanoseconds
from mk_tracker.node_health import (DiagnosticsConfig, FrameCounts, HealthWindow,
                                    diagnose)
from mk_tracker.ros.latest_frame import LatestFrameWorker
from mk_tracker.ros.qos import publisher_qos

TOPIC = "/diagnostics"


class NodeDiagnostics:
    """Publishes a node's input health on ``/diagnostics`` (nothing when the period is 0).

    ``config`` returns the current :class:`DiagnosticsConfig` (thresholds may change at run
    time; the period is read once), ``skipped`` the node's count of frames it took but could
    not use, ``extra`` the key/values appended to the status.
    """

    def __init__(self, node: Any, config: Callable[[], DiagnosticsConfig],
                 worker: LatestFrameWorker, skipped: Callable[[], int],
                 extra: Callable[[], dict[str, Any]]) -> None:
        self._node, self._config, self._worker = node, config, worker
        self._skipped, self._extra = skipped, extra
        self.processed = 0
        self.hardware_id = ""
        period = config().period
        self.enabled = period > 0
        if not self.enabled:
            return
        from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
        self._types = (DiagnosticArray, DiagnosticStatus, KeyValue)
        self.name = f"{node.get_fully_qualified_name()}: input"
        self.health = HealthWindow(config().window)
        self._publisher = node.create_publisher(DiagnosticArray, TOPIC, publisher_qos(10))
        self._timer = node.create_timer(period, self.publish,
                                        clock=Clock(clock_type=ClockType.STEADY_TIME))

    def published(self, header: Any) -> None:
        """A frame's output was published (worker thread): count it, record its latency."""
        if not self.enabled:
            return
        now = self._node.get_clock().now().nanoseconds
        self.processed += 1
        self.hardware_id = str(header.frame_id)
        self.health.latency((now - stamp_to_nanoseconds(header.stamp)) / 1e9)

    def counts(self) -> FrameCounts:
        return FrameCounts(received=self._worker.submitted, processed=self.processed,
                           dropped=self._worker.dropped,
                           skipped=int(self._skipped()) + self._worker.errors)

    def publish(self) -> None:
        """Sample the counters and publish one DiagnosticArray (the timer's callback)."""
        DiagnosticArray, DiagnosticStatus, KeyValue = self._types
        config = self._config()
        self.health.window = config.window
        self.health.sample(self.counts())
        level, message, values = diagnose(self.health.summary(), config, self._extra())
        status = DiagnosticStatus(level=bytes([level]), name=self.name, message=message,
                                  hardware_id=self.hardware_id,
                                  values=[KeyValue(key=k, value=v) for k, v in values])
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = self._node.get_clock().now().to_msg()
        self._publisher.publish(msg)
