"""Log when a subscription gains or loses its publishers (the DDS "matched" event).

A node that sees images but no detections cannot tell from its data whether the detector
is slow, silent or not there at all.  The matched event says it: a reader has matched a
writer (discovery is complete in the direction that matters for this reader) or a writer
went away.  Discovery can take seconds -- e.g. a process restarted in the same domain was
seen to wait 1-3 s for its first detections while images already arrived -- so the nodes
log each change, and the tests wait for that line instead of guessing a delay.
"""

from __future__ import annotations

from typing import Any, Callable

from rclpy.event_handler import SubscriptionEventCallbacks


def matched_text(topic: str, current: int, change: int) -> str:
    """The log line for a change of matched publishers on ``topic``."""
    if current == 0:
        return f"{topic}: no publisher matched any more"
    plural = "" if current == 1 else "s"
    direction = "gained" if change >= 0 else "lost"
    return f"{topic}: {current} publisher{plural} matched ({direction} {abs(change)})"


def log_matches(log: Callable[[str], Any], topic: str) -> SubscriptionEventCallbacks:
    """Event callbacks for ``create_subscription(..., event_callbacks=...)`` that call
    ``log`` with :func:`matched_text` on every change; rclpy's default callbacks (e.g. the
    incompatible-QoS warning) stay on."""

    def on_matched(status: Any) -> None:
        if status.current_count_change != 0:
            log(matched_text(topic, int(status.current_count),
                             int(status.current_count_change)))

    return SubscriptionEventCallbacks(matched=on_matched, use_default_callbacks=True)
