"""Reading one storage file of a rosbag2 bag (MCAP, sqlite3), salvaging damaged ones.

:class:`~mk_tracker.bags.bag_io.BagReader` merges the files of a bag; each file is read here:

* :class:`StorageFile` -- what the reader needs of one file: its own topic table
  (:class:`StoredTopic`: name, type, the message definition stored with it), per-topic
  counts, time-ordered ``(timestamp, topic, CDR bytes)``, and the problems found.
* :class:`McapFile` -- an indexed MCAP file through rosbags' MCAP reader.
* :class:`McapScan` -- a linear, tolerant scan of a truncated or damaged MCAP file (only
  with ``on_error="skip"``): every complete record is kept.
* :class:`SqliteFile` -- the ``topics``/``messages``/``message_definitions`` tables with the
  standard library; a truncated file is salvaged row by row from a repaired copy.
* :func:`open_storage_file` -- the format by file suffix (else the bag's storage
  identifier), the MCAP scan fallback; the place to add another storage format.
* zstd compression as ``ros2 bag record --compression-format zstd`` writes it, with the
  zstd codec rosbags itself uses: ``--compression-mode file`` (``*.mcap.zstd``,
  ``*.db3.zstd``) is decompressed into a temporary file that is then read like any other,
  salvage included; a truncated compressed file keeps what decompressed.  ``message`` mode
  (:class:`ZstdMessages`) decompresses each payload; one that does not decompress is an
  error or, with ``on_error="skip"``, a skipped message and a problem.

The file's own topic table is read, not ``metadata.yaml``'s, because rosbags' bag reader
matches the two by QoS string and silently yields nothing when they differ (real
``ros2 bag record`` output); see :mod:`mk_tracker.bags.bag_io`.  Errors are
:class:`~mk_tracker.bags.bag_errors.BagError` (``sqlite3.DatabaseError`` from
:func:`open_storage_file` for a damaged database).
"""

from __future__ import annotations

import shutil
import sqlite3
import struct
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator

from mk_tracker.bags.bag_errors import BagError, OnError


@dataclass
class StoredTopic:
    """A topic as one storage file lists it, with the message definition stored there."""

    name: str
    msgtype: str
    definition: tuple[str, str] | None  # (format "msg"/"idl", text)


class StorageFile:
    """One storage file: topics, per-topic counts, time-ordered (topic, ts, data) stream."""

    path: Path
    topics: dict[str, StoredTopic]
    counts: dict[str, int]
    problems: list[str]

    def messages(self, topics: set[str] | None, start: int | None, stop: int | None
                 ) -> Iterator[tuple[int, str, bytes]]:
        raise NotImplementedError

    def close(self) -> None:
        pass


class McapFile(StorageFile):
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
            self.topics.setdefault(conn.topic, StoredTopic(conn.topic, conn.msgtype, definition))
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


class McapScan(StorageFile):
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
                self.topics[topic] = StoredTopic(topic, name, (fmt, text) if fmt else None)
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


class SqliteFile(StorageFile):
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
            self.topics[name] = StoredTopic(name, msgtype, definitions.get(msgtype))
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


ZSTD_SUFFIX = ".zstd"


def _zstd() -> Any:
    """The zstd codec rosbags reads compressed bags with (stdlib 3.14, else the backport)."""
    try:
        from compression import zstd  # type: ignore[import-not-found]
    except ImportError:
        from backports import zstd  # type: ignore[import-not-found,no-redef]
    return zstd


class ZstdMessages(StorageFile):
    """A storage file whose message payloads are each zstd-compressed (rosbag2
    ``compression_mode: message``)."""

    def __init__(self, inner: StorageFile, on_error: OnError):
        self.inner, self.on_error = inner, on_error
        self.path, self.topics, self.counts = inner.path, inner.topics, inner.counts
        self.problems = inner.problems

    def messages(self, topics, start, stop):
        zstd = _zstd()
        for ts, topic, data in self.inner.messages(topics, start, stop):
            try:
                yield ts, topic, zstd.decompress(bytes(data))
            except (zstd.ZstdError, ValueError, EOFError) as exc:
                text = (f"{self.path}: a {topic} message at {ts} does not decompress "
                        f"(zstd: {exc})")
                if self.on_error == "raise":
                    raise BagError(text) from exc
                self.problems.append(text + "; skipped")

    def close(self) -> None:
        self.inner.close()


def _decompress_file(path: Path, problems: list[str]) -> Path:
    """Decompress the zstd file ``path`` (``x.mcap.zstd``) into a temporary directory as
    ``x.mcap``; what decompressed before damage or truncation is kept (a problem says so)."""
    zstd = _zstd()
    folder = Path(tempfile.mkdtemp(prefix="mk_tracker_zstd_"))
    target = folder / path.name[:-len(ZSTD_SUFFIX)]
    written, complete = 0, False
    try:
        decompressor = zstd.ZstdDecompressor()
        with path.open("rb") as src, target.open("wb") as dst:
            while not complete:
                block = src.read(1 << 16)
                if not block:
                    break
                out = decompressor.decompress(block)   # what the blocks so far hold
                dst.write(out)
                written += len(out)
                complete = decompressor.eof
        problem = None if complete else "ends before the end of its zstd frame"
    except (zstd.ZstdError, EOFError, OSError, ValueError) as exc:
        problem = f"{type(exc).__name__}: {exc}"
    if problem:
        problems.append(f"{path}: damaged or truncated zstd file ({problem}); reading the "
                        f"{written} bytes that decompressed")
    return target


class _Decompressed(StorageFile):
    """A storage file read from a temporary decompressed copy, removed on close."""

    def __init__(self, inner: StorageFile, folder: Path, problems: list[str]):
        self.inner, self.folder = inner, folder
        self.path, self.topics, self.counts = inner.path, inner.topics, inner.counts
        self.problems = problems + inner.problems
        inner.problems = self.problems

    def messages(self, topics, start, stop):
        return self.inner.messages(topics, start, stop)

    def close(self) -> None:
        try:
            self.inner.close()
        finally:
            shutil.rmtree(self.folder, ignore_errors=True)


def open_storage_file(path: Path, storage: str, on_error: OnError,
                      compression_mode: str = "") -> StorageFile:
    """Open one storage file: MCAP by the ``.mcap`` suffix, sqlite3 by ``.db3``, otherwise
    by ``storage`` (the bag's ``storage_identifier``, "" if unknown).  A ``.zstd`` file is
    decompressed first (file compression); ``compression_mode="message"`` decompresses
    every payload (:class:`ZstdMessages`).

    An MCAP file that the indexed reader refuses raises :class:`BagError` when ``on_error``
    is ``"raise"`` and is scanned (:class:`McapScan`) when it is ``"skip"``.  A damaged
    SQLite database may raise ``sqlite3.DatabaseError``.
    """
    from rosbags.rosbag2 import ReaderError

    if path.suffix == ZSTD_SUFFIX:
        problems: list[str] = []
        plain = _decompress_file(path, problems)
        if problems and on_error == "raise":
            shutil.rmtree(plain.parent, ignore_errors=True)
            raise BagError(problems[0])
        try:
            inner = open_storage_file(plain, storage, on_error, compression_mode)
        except BaseException:
            shutil.rmtree(plain.parent, ignore_errors=True)
            raise
        return _Decompressed(inner, plain.parent, problems)
    if compression_mode == "message":
        return ZstdMessages(open_storage_file(path, storage, on_error), on_error)
    if path.suffix == ".mcap" or (storage == "mcap" and path.suffix != ".db3"):
        try:
            return McapFile(path)
        except (ReaderError, OSError, struct.error, ValueError, KeyError,
                IndexError, EOFError, AssertionError) as exc:
            reason = f"unreadable MCAP ({type(exc).__name__}: {exc})"
            if on_error == "raise":
                raise BagError(f"{path}: {reason}") from exc
            return McapScan(path, reason)
    if path.suffix == ".db3" or storage == "sqlite3":
        return SqliteFile(path, on_error)
    raise BagError(f"{path}: unknown storage format (expected .mcap or .db3)")
