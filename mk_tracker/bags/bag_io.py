"""rosbag2 bags (mcap and sqlite3) read and written with the ``rosbags`` library, no ROS.

* :func:`make_typestore` -- a ROS 2 Jazzy typestore with vision_msgs registered from the
  package's own ``message_definitions/vision_msgs/*.msg``.
* :class:`BagWriter` -- write serialized messages (used by the scene generator, the dataset
  import, the offline pipeline and the recorder).
* :func:`open_bag` / :class:`BagReader` -- read a bag directory (or a single ``.mcap`` /
  ``.db3`` file) in time order over all split files.

Why the reader does not use ``rosbags.rosbag2.Reader`` for the messages: that reader matches
the connections listed in ``metadata.yaml`` to the connections stored in each file by
topic, type *and QoS string*; when the two QoS strings differ (real ``ros2 bag record``
output, e.g. rosbag2's ``talker`` test bag) it silently yields nothing.  :class:`BagReader`
therefore reads each storage file's own topic table (rosbags' MCAP reader for indexed MCAP
files, the ``topics``/``messages`` tables of sqlite3 files directly) and uses
``metadata.yaml`` only as the expected per-topic counts.  Any difference between expected
and found counts is an error (:class:`BagError`) unless ``on_error="skip"``, in which case
every readable message is delivered and the problems are listed in
:attr:`BagReader.problems`.  Type definitions stored in the bag (MCAP schemas, the sqlite3
``message_definitions`` table) are registered in the reader's typestore, so types such as
``test_msgs`` deserialize without being installed.
"""

from __future__ import annotations

import heapq
import sqlite3
import struct
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator, Literal, NamedTuple, Sequence

import yaml

OnError = Literal["raise", "skip"]


class BagError(ValueError):
    """A bag cannot be written or read as a whole: names the file and the problem."""


# --------------------------------------------------------------------------------------
# typestore

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


# --------------------------------------------------------------------------------------
# writer

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


# --------------------------------------------------------------------------------------
# reader: one storage file

@dataclass
class _Topic:
    name: str
    msgtype: str
    definition: tuple[str, str] | None  # (format "msg"/"idl", text)


class _StorageFile:
    """One storage file: topics, per-topic counts, time-ordered (topic, ts, data) stream."""

    path: Path
    topics: dict[str, _Topic]
    counts: dict[str, int]
    problems: list[str]

    def messages(self, topics: set[str] | None, start: int | None, stop: int | None
                 ) -> Iterator[tuple[int, str, bytes]]:
        raise NotImplementedError

    def close(self) -> None:
        pass


class _McapFile(_StorageFile):
    """Indexed MCAP via rosbags' reader."""

    def __init__(self, path: Path):
        from rosbags.interfaces import MessageDefinitionFormat
        from rosbags.rosbag2.storage_mcap import McapReader

        self.path = path
        self.problems = []
        self._reader = McapReader(path)
        self._reader.open()  # errors are translated by the caller
        self.topics, self.counts = {}, {}
        self._by_topic: dict[str, list[Any]] = {}
        for conn in self._reader.connections:
            fmt = conn.msgdef.format
            definition = None
            if fmt == MessageDefinitionFormat.MSG:
                definition = ("msg", conn.msgdef.data)
            elif fmt == MessageDefinitionFormat.IDL:
                definition = ("idl", conn.msgdef.data)
            self.topics.setdefault(conn.topic, _Topic(conn.topic, conn.msgtype, definition))
            self.counts[conn.topic] = self.counts.get(conn.topic, 0) + conn.msgcount
            self._by_topic.setdefault(conn.topic, []).append(conn)

    def messages(self, topics, start, stop):
        conns = [c for t, cs in self._by_topic.items() if topics is None or t in topics
                 for c in cs]
        if not conns:
            return
        for conn, ts, data in self._reader.messages(conns, start, stop):
            yield ts, conn.topic, data

    def close(self) -> None:
        self._reader.close()


_U16, _U32, _U64 = struct.Struct("<H"), struct.Struct("<I"), struct.Struct("<Q")
_MCAP_MAGIC = b"\x89MCAP0\r\n"


class _McapScan(_StorageFile):
    """Tolerant linear scan of an MCAP file that may be truncated or damaged.

    Reads records from the start, collecting schemas, channels and messages (also inside
    chunks).  A record whose content does not parse is skipped; a record that runs past the
    end of its chunk ends that chunk, past the end of the file ends the scan (the complete
    records at the start of a truncated uncompressed chunk are kept).  Used only when the
    indexed reader failed and the caller asked to skip what is unreadable.
    """

    def __init__(self, path: Path, reason: str):
        self.path = path
        self.problems = [f"{path}: {reason}; recovered the readable messages by scanning"]
        self.topics, self.counts = {}, {}
        self._messages: list[tuple[int, str, bytes]] = []
        self._schemas: dict[int, tuple[str, str, str]] = {}
        self._channels: dict[int, tuple[str, int]] = {}
        data = path.read_bytes()
        if not data.startswith(_MCAP_MAGIC):
            self.problems.append(f"{path}: not an MCAP file (bad magic); nothing recovered")
            return
        self._scan(data, len(_MCAP_MAGIC), len(data), top_level=True)
        self._messages.sort(key=lambda m: m[0])
        for _, topic, _ in self._messages:
            self.counts[topic] = self.counts.get(topic, 0) + 1

    @staticmethod
    def _string(buf: bytes, pos: int) -> tuple[str, int]:
        (n,) = _U32.unpack_from(buf, pos)
        end = pos + 4 + n
        if end > len(buf):
            raise struct.error("string past the end of its record")
        return buf[pos + 4:end].decode(), end

    def _scan(self, buf: bytes, pos: int, end: int, top_level: bool) -> None:
        from rosbags.rosbag2.storage_mcap import decompress

        while pos < end:
            if pos + 9 > end:
                self.problems.append(f"{self.path}: truncated record header at byte {pos}")
                return
            op = buf[pos]
            (length,) = _U64.unpack_from(buf, pos + 1)
            body_start, body_end = pos + 9, pos + 9 + length
            if body_end > end:
                where = "file" if top_level else "chunk"
                self.problems.append(
                    f"{self.path}: record at byte {pos} runs past the end of the {where} "
                    "(truncated); stopped there")
                if op == 0x06 and top_level:
                    self._partial_chunk(buf[body_start:end])
                return
            body = buf[body_start:body_end]
            try:
                self._record(op, body, decompress)
            except Exception as exc:  # damaged record content: report, skip the record
                self.problems.append(f"{self.path}: damaged record (op {op:#x}) at byte {pos}: "
                                     f"{exc}; skipped")
            if op == 0x02:  # footer: end of file
                return
            pos = body_end

    def _record(self, op: int, body: bytes, decompress: Callable) -> None:
        if op == 0x03:  # schema
            (sid,) = _U16.unpack_from(body, 0)
            name, p = self._string(body, 2)
            encoding, p = self._string(body, p)
            (n,) = _U32.unpack_from(body, p)
            self._schemas[sid] = (name, encoding, body[p + 4:p + 4 + n].decode())
        elif op == 0x04:  # channel
            cid, sid = struct.unpack_from("<HH", body, 0)
            topic, _ = self._string(body, 4)
            self._channels[cid] = (topic, sid)
            name, encoding, text = self._schemas.get(sid, ("", "", ""))
            if topic not in self.topics:
                fmt = {"ros2msg": "msg", "ros2idl": "idl"}.get(encoding)
                self.topics[topic] = _Topic(topic, name, (fmt, text) if fmt else None)
        elif op == 0x05:  # message
            cid, _, log_time = struct.unpack_from("<HIQ", body, 0)
            channel = self._channels.get(cid)
            if channel is None:
                raise ValueError(f"message on unknown channel {cid}")
            self._messages.append((log_time, channel[0], body[22:]))
        elif op == 0x06:  # chunk
            _, _, size, crc = struct.unpack_from("<QQQI", body, 0)
            compression, p = self._string(body, 28)
            (n,) = _U64.unpack_from(body, p)
            if p + 8 + n > len(body):
                raise ValueError("chunk records exceed the chunk")
            raw = decompress(body[p + 8:p + 8 + n], compression, size, crc)
            self._scan(raw, 0, len(raw), top_level=False)

    def _partial_chunk(self, body: bytes) -> None:
        """Salvage the complete records at the start of a truncated uncompressed chunk."""
        try:
            compression, p = self._string(body, 28)
        except struct.error:
            return
        if compression == "":
            self._scan(body, p + 8, len(body), top_level=False)

    def messages(self, topics, start, stop):
        for ts, topic, data in self._messages:
            if (topics is None or topic in topics) and (start is None or ts >= start) \
                    and (stop is None or ts < stop):
                yield ts, topic, data


def _sqlite_truncation(path: Path, header: bytes) -> str:
    """Why an SQLite file is shorter than its header says, or "" (header fields: page size
    at 16, change counter at 24, page count at 28, valid when 92 equals the counter)."""
    if len(header) < 100:
        return f"file truncated inside the 100-byte header ({len(header)} bytes)"
    (page_size,) = struct.unpack_from(">H", header, 16)
    page_size = 65536 if page_size == 1 else page_size
    counter, pages = struct.unpack_from(">II", header, 24)
    (valid_for,) = struct.unpack_from(">I", header, 92)
    size = path.stat().st_size
    if counter == valid_for and pages > 0 and size < pages * page_size:
        return f"file truncated: {size} of {pages * page_size} bytes"
    return ""


class _SqliteFile(_StorageFile):
    """rosbag2 sqlite3 file read with the standard library (tables topics, messages and,
    when present, message_definitions).

    Salvage (``on_error="skip"`` only): SQLite refuses a truncated file as a whole
    ("database disk image is malformed") because the page count in its header exceeds the
    file.  A temporary copy with the page count set to the pages actually present is then
    read row by row, keeping every row that reads back intact.
    """

    def __init__(self, path: Path, on_error: OnError):
        self.path = path
        self.problems = []
        self._on_error = on_error
        self._salvaged: list[tuple[int, int, int]] | None = None  # (timestamp, id, topic_id)
        self._tmp: Any = None
        with open(path, "rb") as fh:
            header = fh.read(100)
        if header[:16] != b"SQLite format 3\x00":
            raise BagError(f"{path}: not an SQLite database (bad header)")
        try:
            truncated = _sqlite_truncation(path, header)
            if truncated:
                # SQLite reads the missing pages as zeros: rows there would come back with
                # zeroed bytes instead of an error, so a short file is damage as a whole
                raise sqlite3.DatabaseError(truncated)
            self._setup(path)
        except sqlite3.DatabaseError as exc:
            if on_error == "raise":
                raise BagError(f"{path}: damaged SQLite database ({exc})") from exc
            self._salvage(str(exc))

    def _connect(self, path: Path) -> None:
        previous = getattr(self, "_db", None)
        if previous is not None:
            previous.close()
        self._db = sqlite3.connect(f"file:{path}?mode=ro&immutable=1", uri=True)
        self._db.text_factory = bytes

    def _setup(self, path: Path) -> None:
        self._connect(path)
        self.topics, self.counts = {}, {}
        self._ids: dict[int, str] = {}
        definitions: dict[str, tuple[str, str]] = {}
        tables = {r[0].decode() for r in self._db.execute(
            "SELECT name FROM sqlite_master WHERE type='table'")}
        if not {"topics", "messages"} <= tables:
            raise BagError(f"{self.path}: not a rosbag2 database (tables topics/messages missing)")
        if "message_definitions" in tables:
            for msgtype, enc, text in self._db.execute(
                    "SELECT topic_type, encoding, encoded_message_definition "
                    "FROM message_definitions"):
                fmt = {b"ros2msg": "msg", b"ros2idl": "idl"}.get(enc)
                if fmt and text:
                    definitions[msgtype.decode()] = (fmt, text.decode())
        for tid, name, msgtype in self._db.execute("SELECT id, name, type FROM topics"):
            name, msgtype = name.decode(), msgtype.decode()
            self._ids[tid] = name
            self.topics[name] = _Topic(name, msgtype, definitions.get(msgtype))
            self.counts[name] = 0
        if self._salvaged is not None:
            return
        for tid, count in self._db.execute(
                "SELECT topic_id, count(*) FROM messages GROUP BY topic_id"):
            if tid in self._ids:
                self.counts[self._ids[tid]] += count
            else:
                self.problems.append(f"{self.path}: {count} messages on unknown topic id {tid}")

    def _salvage(self, reason: str) -> None:
        import tempfile

        data = bytearray(self.path.read_bytes())
        (page_size,) = struct.unpack_from(">H", data, 16)
        page_size = 65536 if page_size == 1 else page_size
        pages = len(data) // page_size
        if page_size < 512 or pages < 1:
            raise BagError(f"{self.path}: damaged SQLite database ({reason}), unrecoverable")
        del data[pages * page_size:]
        struct.pack_into(">I", data, 28, pages)
        self._tmp = tempfile.NamedTemporaryFile(suffix=".db3")
        self._tmp.write(data)
        self._tmp.flush()
        self._salvaged = []
        try:
            self._setup(Path(self._tmp.name))
            ids: list[int] = []
            try:
                for (rowid,) in self._db.execute("SELECT id FROM messages ORDER BY id"):
                    ids.append(rowid)
            except sqlite3.DatabaseError:
                pass
            bad = 0
            for rowid in ids:
                try:
                    row = self._db.execute("SELECT timestamp, topic_id, data FROM messages "
                                           "WHERE id = ?", (rowid,)).fetchone()
                except sqlite3.DatabaseError:
                    bad += 1
                    continue
                if row is not None and row[1] in self._ids:
                    self._salvaged.append((row[0], rowid, row[1]))
                    self.counts[self._ids[row[1]]] += 1
        except sqlite3.DatabaseError as exc:
            raise BagError(f"{self.path}: damaged SQLite database ({reason}); "
                           f"salvage failed ({exc})") from exc
        self._salvaged.sort()
        self.problems.append(f"{self.path}: damaged SQLite database ({reason}); salvaged "
                             f"{len(self._salvaged)} intact messages, {bad} unreadable")

    def _query(self, topics, start, stop) -> tuple[str, list]:
        sql, args, where = "SELECT topic_id, timestamp, data FROM messages", [], []
        if topics is not None:
            ids = [tid for tid, name in self._ids.items() if name in topics]
            where.append(f"topic_id IN ({','.join('?' * len(ids)) or 'NULL'})")
            args += ids
        if start is not None:
            where.append("timestamp >= ?")
            args.append(int(start))
        if stop is not None:
            where.append("timestamp < ?")
            args.append(int(stop))
        if where:
            sql += " WHERE " + " AND ".join(where)
        return sql, args

    def messages(self, topics, start, stop):
        if self._salvaged is not None:
            for ts, rowid, tid in self._salvaged:
                name = self._ids[tid]
                if (topics is None or name in topics) and (start is None or ts >= start) \
                        and (stop is None or ts < stop):
                    (data,) = self._db.execute("SELECT data FROM messages WHERE id = ?",
                                               (rowid,)).fetchone()
                    yield ts, name, data
            return
        sql, args = self._query(topics, start, stop)
        try:
            for tid, ts, data in self._db.execute(sql + " ORDER BY timestamp, id", args):
                if tid in self._ids:
                    yield ts, self._ids[tid], data
        except sqlite3.DatabaseError as exc:
            raise BagError(f"{self.path}: damaged database while reading messages: "
                           f"{exc}") from exc

    def close(self) -> None:
        self._db.close()
        if self._tmp is not None:
            self._tmp.close()


# --------------------------------------------------------------------------------------
# reader: a bag

class BagMessage(NamedTuple):
    """One stored message: raw CDR bytes (deserialize with :meth:`BagReader.deserialize`)."""

    topic: str
    msgtype: str
    timestamp_ns: int
    data: bytes | memoryview


@dataclass(frozen=True)
class TopicInfo:
    """A topic of a bag: ``count`` messages found in the storage files, ``expected`` the
    count listed in metadata.yaml (None without metadata)."""

    name: str
    msgtype: str
    count: int
    expected: int | None


class BagReader:
    """A rosbag2 bag opened for reading (see the module docstring).  Prefer :func:`open_bag`.

    ``on_error="raise"``: any unreadable file, missing file, damaged record or count
    mismatch raises :class:`BagError`.  ``on_error="skip"``: read everything readable and
    list each problem in :attr:`problems` (also available after iteration, since damage
    inside a file may only be found while reading it).
    """

    def __init__(self, path: str | Path, on_error: OnError = "raise", typestore: Any = None):
        self.path = Path(path)
        self.on_error = on_error
        self.typestore = typestore
        self.problems: list[str] = []
        if self.on_error not in ("raise", "skip"):
            raise ValueError(f"on_error must be 'raise' or 'skip', got {self.on_error!r}")
        if self.typestore is None:
            self.typestore = make_typestore()
        self._files: list[_StorageFile] = []
        self._expected: dict[str, int] | None = None
        self._expected_types: dict[str, str] = {}
        self._expected_per_file: dict[str, int] = {}
        self.storage: str = ""
        try:
            self._open()
        except BaseException:
            self.close()
            raise

    # -- opening -------------------------------------------------------------------------
    def _problem(self, text: str) -> None:
        if self.on_error == "raise":
            raise BagError(text)
        self.problems.append(text)

    def _open(self) -> None:
        if not self.path.exists():
            raise BagError(f"{self.path}: no such bag (file or directory)")
        if self.path.is_file():
            paths = [self.path]
        else:
            paths = self._paths_from_metadata()
        if not paths:
            raise BagError(f"{self.path}: no storage files to read")
        for p in paths:
            self._open_file(p)
        self._register_definitions()
        self._check_counts()

    def _paths_from_metadata(self) -> list[Path]:
        meta_path = self.path / "metadata.yaml"
        found = sorted(p for p in self.path.iterdir() if p.suffix in (".mcap", ".db3"))
        if not meta_path.is_file():
            self._problem(f"{meta_path}: missing (not a complete rosbag2 bag); "
                          f"reading the {len(found)} storage file(s) found instead")
            return found
        try:
            info = yaml.safe_load(meta_path.read_text())["rosbag2_bagfile_information"]
            files = [str(f) for f in info["relative_file_paths"]]
            self.storage = str(info.get("storage_identifier", ""))
            self._expected = {}
            for entry in info.get("topics_with_message_count") or []:
                name = entry["topic_metadata"]["name"]
                self._expected[name] = self._expected.get(name, 0) + int(entry["message_count"])
                self._expected_types[name] = entry["topic_metadata"]["type"]
            for entry in info.get("files") or []:   # per-file counts name a damaged file
                if isinstance(entry, dict) and "path" in entry and "message_count" in entry:
                    self._expected_per_file[Path(str(entry["path"])).name] = int(
                        entry["message_count"])
        except (OSError, UnicodeDecodeError, yaml.YAMLError, KeyError, TypeError,
                ValueError) as exc:
            self._problem(f"{meta_path}: unreadable or incomplete metadata "
                          f"({type(exc).__name__}: {exc}); reading the storage files found")
            self._expected = None
            return found
        if info.get("compression_mode") not in (None, "", "none", "NONE"):
            raise BagError(f"{meta_path}: compressed bags "
                           f"({info.get('compression_mode')}) are not supported")
        paths = [self.path / Path(f).name for f in files]
        existing = []
        for p in paths:
            if p.is_file():
                existing.append(p)
            else:
                self._problem(f"{p}: split file listed in metadata.yaml is missing")
        return existing

    def _open_file(self, path: Path) -> None:
        from rosbags.rosbag2 import ReaderError

        try:
            if path.suffix == ".mcap" or (self.storage == "mcap" and path.suffix != ".db3"):
                try:
                    f: _StorageFile = _McapFile(path)
                except (ReaderError, OSError, struct.error, ValueError, KeyError,
                        IndexError, EOFError, AssertionError) as exc:
                    reason = f"unreadable MCAP ({type(exc).__name__}: {exc})"
                    if self.on_error == "raise":
                        raise BagError(f"{path}: {reason}") from exc
                    f = _McapScan(path, reason)
            elif path.suffix == ".db3" or self.storage == "sqlite3":
                f = _SqliteFile(path, self.on_error)
            else:
                raise BagError(f"{path}: unknown storage format (expected .mcap or .db3)")
        except sqlite3.DatabaseError as exc:
            self._problem(f"{path}: damaged SQLite database ({exc})")
            return
        except BagError as exc:
            self._problem(str(exc))
            return
        self._files.append(f)
        for text in f.problems:
            self.problems.append(text)
        f.problems.clear()

    def _register_definitions(self) -> None:
        for topic in self._topic_table().values():
            if topic.msgtype in self.typestore.types or topic.definition is None:
                continue
            try:
                register_definition(self.typestore, topic.msgtype, *topic.definition)
            except BagError as exc:
                self.problems.append(f"{self.path}: {exc}")

    def _topic_table(self) -> dict[str, _Topic]:
        table: dict[str, _Topic] = {}
        for f in self._files:
            for name, topic in f.topics.items():
                known = table.get(name)
                if known is None or (known.definition is None and topic.definition):
                    table[name] = topic
        return table

    def _found_counts(self) -> dict[str, int]:
        counts: dict[str, int] = {}
        for f in self._files:
            for name, n in f.counts.items():
                counts[name] = counts.get(name, 0) + n
        return counts

    def _check_counts(self) -> None:
        if self._expected is None:
            return
        for f in self._files:
            listed = self._expected_per_file.get(f.path.name)
            held = sum(f.counts.values())
            if listed is not None and held != listed:
                self._problem(f"{f.path}: metadata.yaml lists {listed} messages in this file, "
                              f"it holds {held} (truncated or damaged file)")
        found = self._found_counts()
        for name, expected in sorted(self._expected.items()):
            got = found.get(name, 0)
            if got != expected:
                self._problem(f"{self.path}: topic {name}: metadata.yaml lists {expected} "
                              f"messages, the storage files hold {got}")

    # -- public --------------------------------------------------------------------------
    @property
    def topics(self) -> dict[str, TopicInfo]:
        """Topics found in the storage files (plus metadata-only topics with count 0)."""
        found = self._found_counts()
        out = {name: TopicInfo(name, t.msgtype, found.get(name, 0),
                               None if self._expected is None else self._expected.get(name))
               for name, t in self._topic_table().items()}
        for name, expected in (self._expected or {}).items():
            if name not in out:
                out[name] = TopicInfo(name, self._expected_types.get(name, ""), 0, expected)
        return out

    @property
    def message_count(self) -> int:
        """Messages found in the storage files."""
        return sum(self._found_counts().values())

    @property
    def files(self) -> list[Path]:
        """Storage files opened."""
        return [f.path for f in self._files]

    def messages(self, topics: Iterable[str] | None = None, start_ns: int | None = None,
                 stop_ns: int | None = None) -> Iterator[BagMessage]:
        """Messages in time order over all files (ties keep file then storage order).

        ``topics`` selects topics (unknown names raise :class:`BagError`); ``start_ns`` /
        ``stop_ns`` bound the timestamps (``start <= t < stop``).  Damage found while reading
        raises :class:`BagError` or is skipped and recorded in :attr:`problems`.  After a
        complete unfiltered pass, fewer messages than the files announced is such damage.
        """
        selected = None if topics is None else set(topics)
        table = self._topic_table()
        if selected is not None:
            unknown = selected - set(table) - set(self._expected or {})
            if unknown:
                raise BagError(f"{self.path}: no topic(s) {sorted(unknown)}; "
                               f"the bag has {sorted(table)}")
        types = {name: t.msgtype for name, t in table.items()}
        streams = [self._guarded(i, f, selected, start_ns, stop_ns)
                   for i, f in enumerate(self._files)]
        delivered: dict[str, int] = {}
        for ts, _, topic, data in heapq.merge(*streams, key=lambda m: (m[0], m[1])):
            delivered[topic] = delivered.get(topic, 0) + 1
            yield BagMessage(topic, types.get(topic, ""), ts, data)
        if selected is None and start_ns is None and stop_ns is None:
            announced = self._found_counts()
            for name, n in sorted(announced.items()):
                if delivered.get(name, 0) < n:
                    self._problem(f"{self.path}: topic {name}: read "
                                  f"{delivered.get(name, 0)} of {n} messages")

    def _guarded(self, index: int, f: _StorageFile, topics, start, stop
                 ) -> Iterator[tuple[int, int, str, bytes]]:
        delivered: dict[tuple[int, str], int] = {}
        try:
            for ts, topic, data in f.messages(topics, start, stop):
                delivered[ts, topic] = delivered.get((ts, topic), 0) + 1
                yield ts, index, topic, data
        except BagError as exc:
            self._problem(str(exc))
        except Exception as exc:  # damage inside a storage file found while reading
            reason = f"damaged data while reading ({type(exc).__name__}: {exc})"
            self._problem(f"{f.path}: {reason}")
            if isinstance(f, _McapFile):
                # skip mode: rescan the file and deliver what the index could not
                scan = _McapScan(f.path, reason)
                self.problems.extend(scan.problems)
                for ts, topic, data in scan.messages(topics, start, stop):
                    if delivered.get((ts, topic), 0) > 0:
                        delivered[ts, topic] -= 1
                        continue
                    yield ts, index, topic, data
        finally:
            self.problems.extend(f.problems)
            f.problems.clear()

    def deserialize(self, message: BagMessage) -> Any:
        """Deserialize a :class:`BagMessage` with the reader's typestore."""
        if message.msgtype not in self.typestore.types:
            raise BagError(f"{self.path}: type {message.msgtype} of {message.topic} is "
                           "unknown and the bag stores no definition for it")
        try:
            return self.typestore.deserialize_cdr(bytes(message.data), message.msgtype)
        except Exception as exc:
            raise BagError(f"{self.path}: cannot deserialize a {message.msgtype} on "
                           f"{message.topic} at {message.timestamp_ns}: {exc}") from exc

    def read_messages(self, topics: Iterable[str] | None = None, **kwargs: Any
                      ) -> Iterator[tuple[BagMessage, Any]]:
        """``(raw message, deserialized message)`` pairs in time order."""
        for m in self.messages(topics, **kwargs):
            yield m, self.deserialize(m)

    def close(self) -> None:
        for f in getattr(self, "_files", []):
            try:
                f.close()
            except Exception:
                pass
        self._files = []

    def __enter__(self) -> "BagReader":
        return self

    def __exit__(self, *exc_info: Any) -> None:
        self.close()


def open_bag(path: str | Path, *, on_error: OnError = "raise", typestore: Any = None
             ) -> BagReader:
    """Open a bag directory (or one ``.mcap``/``.db3`` file) for reading."""
    return BagReader(Path(path), on_error=on_error, typestore=typestore)
