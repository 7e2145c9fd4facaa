"""Which topics of a bag carry camera images, and whether the chosen one can be used.

A camera topic holds ``sensor_msgs/msg/Image`` or, recorded through image_transport's
``compressed`` plugin, ``sensor_msgs/msg/CompressedImage`` on ``<topic>/compressed``.  The
offline tools check the chosen topic before reading a single message
(:func:`check_image_topic`), so a wrong name or type stops the run with a message that
lists the bag's image topics and names the option to set.  No rclpy here.
"""

from __future__ import annotations

from typing import Any, Mapping

from mk_tracker.messages.compressed_image import COMPRESSED_TYPE, IMAGE_TYPE

IMAGE_TYPES = (IMAGE_TYPE, COMPRESSED_TYPE)


class ImageTopicError(ValueError):
    """The chosen image topic is missing from the bag or has a type the tools cannot use."""


def _msgtype(info: Any) -> str:
    return str(getattr(info, "msgtype", info) or "")


def image_like_topics(topics: Mapping[str, Any]) -> dict[str, str]:
    """``{name: msgtype}`` of the topics holding Image or CompressedImage messages
    (``topics`` maps a name to an object with ``msgtype``, or to the type name itself)."""
    return {name: _msgtype(info) for name, info in sorted(topics.items())
            if _msgtype(info) in IMAGE_TYPES}


def compressed_topics(topics: Mapping[str, Any]) -> set[str]:
    """Names of the topics holding CompressedImage messages."""
    return {name for name, kind in image_like_topics(topics).items()
            if kind == COMPRESSED_TYPE}


def check_image_topic(topics: Mapping[str, Any], name: str, option: str) -> str:
    """The message type of ``name``; :class:`ImageTopicError` when it is missing or not an
    image type, saying which image topics there are and that ``option`` chooses one."""
    images = image_like_topics(topics)
    listing = ", ".join(f"{n} ({t.rsplit('/', 1)[-1]})" for n, t in images.items()) or "none"
    if name in images:
        return images[name]
    if name in topics:
        problem = (f"{name} holds {_msgtype(topics[name]) or 'an unknown type'}, not "
                   f"sensor_msgs/msg/Image or CompressedImage")
    else:
        problem = f"no {name} topic in the bag"
    hint = f"{name}/compressed" if f"{name}/compressed" in images else (
        next(iter(images)) if len(images) == 1 else None)
    fix = (f"; use {option} {hint}" if hint else
           f"; choose one with {option}" if images else "")
    return _raise(f"{problem} (image topics in this bag: {listing}){fix}")


def _raise(text: str) -> str:
    raise ImageTopicError(text)
