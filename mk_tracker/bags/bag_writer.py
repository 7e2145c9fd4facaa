"""Writing rosbag2 bags (mcap or sqlite3) with ``rosbags``, no ROS: :class:`BagWriter`.

:class:`BagWriter` writes a new bag directory: topics declared with their type and the
publishers' QoS profiles, messages as rosbags message objects of its typestore
(:func:`~mk_tracker.bags.bag_typestore.make_typestore` by default) or as serialized CDR bytes
copied from another bag.  Its users: the scene generator, the dataset import, the offline
pipeline, the demo and the recorder node.  Errors are
:class:`~mk_tracker.bags.bag_errors.BagError`.  Reading is :mod:`mk_tracker.bags.bag_io`,
which re-exports :class:`BagWriter`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

from mk_tracker.bags.bag_errors import BagError
from mk_tracker.bags.bag_typestore import make_typestore


class BagWriter:
    """Write a rosbag2 bag directory; use as a context manager.

    ``storage`` is ``"mcap"`` or ``"sqlite3"``.  The directory must not exist yet.
    Topics are declared with :meth:`add_topic` (or implicitly by :meth:`write`, which takes
    the type from the message's ``__msgtype__``).  Messages must be instances of the
    writer's typestore classes (``bag_message_types(writer.typestore)``) or already
    serialized CDR bytes.  The bag directory is created by :meth:`open` (called by ``with``
    or, lazily, by the first :meth:`add_topic`); a writer closed before that creates nothing.
    """

    def __init__(self, path: str | Path, storage: str = "mcap", *, typestore: Any = None):
        if storage not in ("mcap", "sqlite3"):
            raise BagError(f"storage must be 'mcap' or 'sqlite3', got {storage!r}")
        self.path = Path(path)
        if self.path.exists():
            raise BagError(f"{self.path} exists already; a bag is never overwritten")
        if not self.path.parent.is_dir():
            raise BagError(f"{self.path.parent} is not a directory")
        self.storage = storage
        self.typestore = typestore if typestore is not None else make_typestore()
        self._writer: Any = None
        self._connections: dict[str, Any] = {}
        self.counts: dict[str, int] = {}

    def open(self) -> "BagWriter":
        from rosbags.rosbag2 import StoragePlugin, Writer

        plugin = StoragePlugin.MCAP if self.storage == "mcap" else StoragePlugin.SQLITE3
        self._writer = Writer(self.path, version=9, storage_plugin=plugin)
        self._writer.open()
        return self

    def __enter__(self) -> "BagWriter":
        return self.open()

    def __exit__(self, *exc_info: Any) -> None:
        self.close()

    def close(self) -> None:
        """Finish the bag (metadata.yaml, indexes); what was written stays readable."""
        if self._writer is not None:
            writer, self._writer = self._writer, None
            writer.close()

    def add_topic(self, topic: str, msgtype: str, qos: Sequence[Any] = (), *,
                  offered_qos_profiles: Sequence[Any] | None = None) -> None:
        """Declare ``topic`` with ROS type ``msgtype`` (e.g. ``sensor_msgs/msg/Image``).

        ``qos`` (alias ``offered_qos_profiles``): the publishers' QoS profiles stored in the
        bag, as rosbags ``Qos`` records or dicts with the rmw enum values of ``history``,
        ``depth``, ``reliability``, ``durability`` (and optionally ``liveliness``).
        """
        if self._writer is None:
            self.open()
        if offered_qos_profiles is not None:
            qos = offered_qos_profiles
        if topic in self._connections:
            known = self._connections[topic].msgtype
            if known != msgtype:
                raise BagError(f"{self.path}: topic {topic} already has type {known}, "
                               f"not {msgtype}")
            return
        if msgtype not in self.typestore.types:
            raise BagError(f"{self.path}: message type {msgtype} is unknown to the typestore")
        self._connections[topic] = self._writer.add_connection(
            topic, msgtype, typestore=self.typestore,
            offered_qos_profiles=[_as_qos(q, self.path) for q in qos])
        self.counts[topic] = 0

    def write_raw(self, topic: str, timestamp_ns: int, cdr: bytes | memoryview) -> None:
        """Write already serialized CDR bytes on a declared topic."""
        connection = self._connections.get(topic)
        if connection is None:
            raise BagError(f"{self.path}: topic {topic} was not added (call add_topic first)")
        ts = int(timestamp_ns)
        if ts < 0:
            raise BagError(f"{self.path}: negative timestamp {ts} on {topic}")
        self._writer.write(connection, ts, cdr)
        self.counts[topic] += 1

    def write(self, topic: str, timestamp_ns: int, msg: Any) -> None:
        """Serialize ``msg`` with the typestore and write it (declaring the topic if new).
        Bytes-like ``msg`` is taken as serialized CDR (:meth:`write_raw`)."""
        if isinstance(msg, (bytes, bytearray, memoryview)):
            self.write_raw(topic, timestamp_ns, msg)
            return
        msgtype = getattr(msg, "__msgtype__", None)
        if msgtype is None:
            raise BagError(f"{self.path}: {type(msg).__name__} is not a rosbags message "
                           "(build it with bag_message_types(writer.typestore))")
        if topic not in self._connections:
            self.add_topic(topic, msgtype)
        elif self._connections[topic].msgtype != msgtype:
            raise BagError(f"{self.path}: topic {topic} has type "
                           f"{self._connections[topic].msgtype}, got a {msgtype}")
        try:
            cdr = self.typestore.serialize_cdr(msg, msgtype)
        except Exception as exc:  # rosbags raises assorted errors for wrong field types
            raise BagError(f"{self.path}: cannot serialize {msgtype} for {topic}: {exc}") from exc
        self.write_raw(topic, timestamp_ns, cdr)


def _as_qos(profile: Any, path: Path) -> Any:
    """A rosbags ``Qos`` from a ``Qos`` or a dict of rmw enum values."""
    from rosbags.interfaces import (Qos, QosDurability, QosHistory, QosLiveliness,
                                    QosReliability, QosTime)

    if isinstance(profile, Qos):
        return profile
    if not isinstance(profile, dict):
        raise BagError(f"{path}: QoS profile {profile!r} is neither a rosbags Qos nor a dict")
    try:
        never = QosTime(0, 0)
        return Qos(history=QosHistory(int(profile.get("history", 1))),
                   depth=int(profile.get("depth", 0)),
                   reliability=QosReliability(int(profile.get("reliability", 1))),
                   durability=QosDurability(int(profile.get("durability", 2))),
                   deadline=never, lifespan=never,
                   liveliness=QosLiveliness(int(profile.get("liveliness", 1))),
                   liveliness_lease_duration=never,
                   avoid_ros_namespace_conventions=False)
    except (TypeError, ValueError) as exc:
        raise BagError(f"{path}: invalid QoS profile {profile!r}: {exc}") from exc

