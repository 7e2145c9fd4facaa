"""The rosbags typestore of the bags: ROS 2 Jazzy plus vision_msgs, and definitions stored in a bag.

* :func:`make_typestore` -- a fresh ROS 2 Jazzy typestore with vision_msgs registered from
  the package's own ``messages/definitions/vision_msgs/*.msg`` (vision_msgs is not among
  rosbags' built-in types); the writer and the reader start from it.
* :func:`register_definition` -- add the types of a message definition stored in a bag
  (MCAP schema, sqlite3 ``message_definitions`` row) that the store does not know, so the
  reader deserializes types that are not installed (e.g. rosbag2's ``test_msgs``).
* :func:`vision_msgs_definitions` -- the ``.msg`` texts :func:`make_typestore` registers.

Errors are :class:`~mk_tracker.bags.bag_errors.BagError`.  The names stay importable from
:mod:`mk_tracker.bags.bag_io`.
"""

from __future__ import annotations

from importlib import resources
from typing import Any

from mk_tracker.bags.bag_errors import BagError


def vision_msgs_definitions() -> dict[str, str]:
    """``{"vision_msgs/msg/Name": msg text}`` from the package data."""
    folder = resources.files("mk_tracker.messages.definitions") / "vision_msgs"
    out = {}
    for entry in folder.iterdir():
        if entry.name.endswith(".msg"):
            out[f"vision_msgs/msg/{entry.name[:-4]}"] = entry.read_text()
    if not out:
        raise BagError(f"no vision_msgs .msg files found in {folder}")
    return out


def make_typestore() -> Any:
    """A fresh ROS 2 Jazzy rosbags typestore with vision_msgs registered."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    types: dict[str, Any] = {}
    for name, text in vision_msgs_definitions().items():
        types.update(get_types_from_msg(text, name))
    store.register(types)
    return store


def register_definition(store: Any, msgtype: str, fmt: str, text: str) -> list[str]:
    """Register the types of a stored message definition that ``store`` does not know yet.

    ``fmt`` is ``"msg"`` (ros2msg, possibly with ``MSG:`` sections of dependencies) or
    ``"idl"``.  Types already present are kept (the store's definition wins).  Returns the
    names registered.  Raises :class:`BagError` on an unparsable definition.
    """
    from rosbags.typesys import get_types_from_idl, get_types_from_msg

    try:
        found = get_types_from_idl(text) if fmt == "idl" else get_types_from_msg(text, msgtype)
    except Exception as exc:  # rosbags raises several parser error classes
        raise BagError(f"cannot parse the stored definition of {msgtype}: {exc}") from exc
    new = {k: v for k, v in found.items() if k not in store.types}
    if new:
        store.register(new)
    return sorted(new)
