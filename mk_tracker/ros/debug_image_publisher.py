"""A node's annotated debug image on ``~/debug_image`` (sensor_msgs/Image bgr8) and, as
image_transport's ``compressed`` transport names it, ``~/debug_image/compressed``
(sensor_msgs/CompressedImage JPEG, ``format`` ``"bgr8; jpeg compressed bgr8"``), so a robot
on WiFi can watch it with ``rqt_image_view`` or ``ros2 run image_transport republish``.

Drawing and encoding cost time on the worker thread; :meth:`DebugImagePublisher.wanted`
says whether anyone subscribes to either topic (the node draws only then), and
:meth:`~DebugImagePublisher.publish` converts the drawing only for the topics with a
subscriber.  The JPEG encoding is :func:`mk_tracker.messages.compressed_image
.numpy_to_compressed` (pure OpenCV).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mk_tracker.messages.compressed_image import numpy_to_compressed
from mk_tracker.messages.image_conversion import numpy_to_image
from mk_tracker.messages.message_types import MessageTypes
from mk_tracker.parameters import parameter
from mk_tracker.ros.qos import publisher_qos

TOPIC = "~/debug_image"
COMPRESSED_TOPIC = TOPIC + "/compressed"


def jpeg_quality_parameter() -> Any:
    """The ``debug_image_jpeg_quality`` parameter both nodes declare (a dataclass field)."""
    return parameter(80, "JPEG quality of ~/debug_image/compressed (0-100; higher: larger "
                     "and sharper)", minimum=0, maximum=100)


class DebugImagePublisher:
    """The raw and the JPEG debug-image publishers of ``node``."""

    def __init__(self, node: Any, types: MessageTypes) -> None:
        self._types = types
        self.raw = node.create_publisher(types.Image, TOPIC, publisher_qos(1))
        self.compressed = node.create_publisher(types.CompressedImage, COMPRESSED_TOPIC,
                                                publisher_qos(1))

    def wanted(self) -> bool:
        """True when either topic has a subscriber."""
        return bool(self.raw.get_subscription_count()
                    or self.compressed.get_subscription_count())

    def publish(self, bgr: np.ndarray, header: Any, jpeg_quality: int) -> None:
        """Publish the bgr8 drawing on each topic that has a subscriber."""
        if self.raw.get_subscription_count():
            self.raw.publish(numpy_to_image(bgr, "bgr8", header, types=self._types))
        if self.compressed.get_subscription_count():
            self.compressed.publish(numpy_to_compressed(bgr, "bgr8", "jpeg", header,
                                                        types=self._types,
                                                        jpeg_quality=jpeg_quality))
