"""image_transport's conventions for a camera topic, for the nodes (no rclpy here).

* ``raw``: ``sensor_msgs/msg/Image`` on the topic itself;
* ``compressed``: ``sensor_msgs/msg/CompressedImage`` (JPEG/PNG) on ``<topic>/compressed``,
  decoded by :mod:`mk_tracker.messages.compressed_image`.

:func:`silence_advice` is what a node that has received no image for a while says after
looking at the ROS graph: the topic exists with another type, or a ``/compressed`` sibling
(or the raw topic of a ``/compressed`` one) exists, and which parameter to set.
"""

from __future__ import annotations

from typing import Any, Iterable, Mapping

from mk_tracker.messages.compressed_image import COMPRESSED_TYPE, IMAGE_TYPE
from mk_tracker.parameters import parameter

TRANSPORTS = ("raw", "compressed")


def image_transport_parameter() -> Any:
    """The ``image_transport`` parameter both nodes declare (a dataclass field)."""
    return parameter(
        "raw", "raw: sensor_msgs/Image on the image topic; compressed: "
        "sensor_msgs/CompressedImage (JPEG or PNG, 16-bit PNG for mono16) on <image topic>/"
        "compressed, as image_transport publishes it (remapping the image topic moves both)", choices=TRANSPORTS, read_only=True)


def no_image_warning_parameter() -> Any:
    """The ``no_image_warning`` parameter both nodes declare (a dataclass field)."""
    return parameter(
        5.0, "Seconds without an image after which the node looks at the ROS graph once and "
        "warns if the image topic has another type or a /compressed (or raw) sibling exists; "
        "0 = never", minimum=0.0, maximum=3600.0, read_only=True)
SUFFIX = "/compressed"


def subscription_topic(topic: str, transport: str) -> str:
    """The topic a node with ``image_transport`` = ``transport`` subscribes."""
    if transport not in TRANSPORTS:
        raise ValueError(f"image_transport: {transport!r} is not one of {list(TRANSPORTS)}")
    return topic + SUFFIX if transport == "compressed" else topic


def message_type(transport: str) -> str:
    """The ROS type name a node with ``image_transport`` = ``transport`` subscribes."""
    return COMPRESSED_TYPE if transport == "compressed" else IMAGE_TYPE


def silence_advice(subscribed: str, transport: str,
                   graph: Mapping[str, Iterable[str]]) -> str | None:
    """Why a node subscribing ``subscribed`` (fully resolved, with ``transport``) may be
    receiving nothing, judged from ``graph`` (topic -> type names, as
    ``Node.get_topic_names_and_types`` gives them), with the fix; None when the graph
    shows no such reason."""
    types = {name: set(kinds) for name, kinds in graph.items()}
    wanted = message_type(transport)
    here = types.get(subscribed, set())
    if here and wanted not in here:
        other = sorted(here)
        fix = (" set image_transport:=compressed and remap the image topic to the topic "
               "without /compressed" if COMPRESSED_TYPE in here else
               " remap the image topic to an Image topic")
        return (f"nothing received on {subscribed}: it carries {', '.join(other)}, this "
                f"node subscribes {wanted};{fix}")
    if transport == "raw" and COMPRESSED_TYPE in types.get(subscribed + SUFFIX, set()):
        return (f"nothing received on {subscribed}; {subscribed}{SUFFIX} carries "
                f"{COMPRESSED_TYPE}: set image_transport:=compressed to use it")
    if transport == "compressed" and subscribed.endswith(SUFFIX):
        base = subscribed[:-len(SUFFIX)]
        if IMAGE_TYPE in types.get(base, set()) and not here:
            return (f"nothing received on {subscribed}; {base} carries {IMAGE_TYPE}: set "
                    f"image_transport:=raw to use it")
    return None
