"""How the bag modules report a bag they cannot use: :class:`BagError` and the ``on_error`` policy.

* :class:`BagError` -- raised by :mod:`~mk_tracker.bags.bag_io` (reading),
  :mod:`~mk_tracker.bags.bag_storage` (one storage file), :mod:`~mk_tracker.bags.bag_writer`
  and :mod:`~mk_tracker.bags.bag_typestore`; the message names the file and the problem.
* :data:`OnError` -- ``"raise"`` (any problem is a :class:`BagError`) or ``"skip"`` (read
  what is readable and list the problems), the reader's choice.
* :func:`require_bag_io` -- :mod:`~mk_tracker.bags.bag_io` imported on first use, or
  :class:`RosbagsMissing` with the fix when the ``rosbags`` package is not installed (a
  colcon/rosdep install has no package for it; the nodes do not need it).

A module of its own so that the reader, the writer and the typestore share one error class
without importing each other.  Importers may keep taking both names from
:mod:`mk_tracker.bags.bag_io`.
"""

from __future__ import annotations

from types import ModuleType
from typing import Literal

OnError = Literal["raise", "skip"]


class BagError(ValueError):
    """A bag cannot be written or read as a whole: names the file and the problem."""


class RosbagsMissing(ImportError):
    """The Python package ``rosbags``, which the bag tools read and write bags with, is not
    installed."""


def require_bag_io(tool: str) -> ModuleType:
    """:mod:`mk_tracker.bags.bag_io` (which needs ``rosbags``); :class:`RosbagsMissing`
    naming ``tool`` and how to install rosbags when it is missing."""
    try:
        import rosbags.typesys  # noqa: F401  (bag_io imports rosbags only where it is used)

        from mk_tracker.bags import bag_io
    except ImportError as exc:
        if (exc.name or "").split(".")[0] != "rosbags":
            raise
        raise RosbagsMissing(
            f"{tool} needs the Python package rosbags, which is not installed ({exc}): "
            "pip install rosbags (it has no apt or rosdep package). On a ROS 2 install, "
            "ros2 bag play / ros2 bag record work without it.") from exc
    return bag_io
