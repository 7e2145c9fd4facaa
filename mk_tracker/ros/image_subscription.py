"""A node's camera subscription by image_transport (``raw`` or ``compressed``), and the one
warning a node gives when it has received no image for a while and the ROS graph shows why.

Shared by both nodes; the naming and the advice are the library's
(:mod:`mk_tracker.messages.image_transport`).  The callback gets the message as it came
(Image or CompressedImage); the nodes decode with
:func:`mk_tracker.messages.compressed_image.as_image` in their worker thread.
"""

from __future__ import annotations

from typing import Any, Callable

from mk_tracker.messages.image_transport import silence_advice, subscription_topic
from mk_tracker.ros.subscription_events import log_matches


class ImageSubscription:
    """Subscribe ``topic`` with ``transport``; after ``silence_period`` s without an image
    (0 = never) look at the graph every ``silence_period`` s and warn once when it shows a
    reason (:func:`~mk_tracker.messages.image_transport.silence_advice`)."""

    def __init__(self, node: Any, topic: str, transport: str,
                 callback: Callable[[Any], None], qos: Any, silence_period: float) -> None:
        from sensor_msgs.msg import CompressedImage, Image

        self.node, self.transport, self._callback = node, transport, callback
        self._base = topic
        # image_transport's rule: the base topic is resolved (namespace, remapping) first
        # and /compressed appended, so remapping image_raw also moves image_raw/compressed
        name = subscription_topic(node.resolve_topic_name(topic), transport)
        self.topic = name
        self.received = False
        self.warned = False
        msg_type = CompressedImage if transport == "compressed" else Image
        self.subscription = node.create_subscription(
            msg_type, name, self._on_message, qos,
            event_callbacks=log_matches(node.get_logger().info, self.topic))
        self._timer = (node.create_timer(float(silence_period), self._check)
                       if silence_period > 0 else None)

    def _on_message(self, msg: Any) -> None:
        self.received = True
        self._callback(msg)

    def _check(self) -> None:
        if not (self.received or self.warned):
            graph = dict(self.node.get_topic_names_and_types())
            advice = silence_advice(self.topic, self.transport, graph)
            if advice is None:
                return                        # nothing to say yet; look again later
            self.node.get_logger().warning(f"{advice} (remap {self._base}, parameter "
                                           f"image_transport)")
            self.warned = True
        if self._timer is not None:
            self._timer.cancel()
