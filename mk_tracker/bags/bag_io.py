"""Reading rosbag2 bags (mcap, sqlite3) with ``rosbags``, no ROS; the front of the bag modules.

* :func:`open_bag` / :class:`BagReader` -- read a bag directory (or a single ``.mcap`` /
  ``.db3`` file) in time order over all split files: :class:`BagMessage` records (raw CDR
  bytes), :class:`TopicInfo` per topic, the problems found in :attr:`BagReader.problems`.

Also importable from here, as before the split (issue #18): :class:`BagError` and
``OnError`` (:mod:`~mk_tracker.bags.bag_errors`), :class:`BagWriter`
(:mod:`~mk_tracker.bags.bag_writer`), :func:`make_typestore`, :func:`register_definition`
and :func:`vision_msgs_definitions` (:mod:`~mk_tracker.bags.bag_typestore`).  Each storage
file is read by :mod:`~mk_tracker.bags.bag_storage`.

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
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Iterator, NamedTuple

import yaml

from mk_tracker.bags.bag_errors import BagError, OnError
from mk_tracker.bags.bag_storage import (McapFile, McapScan, StorageFile, StoredTopic,
                                         open_storage_file)
from mk_tracker.bags.bag_typestore import (make_typestore, register_definition,
                                           vision_msgs_definitions)
from mk_tracker.bags.bag_writer import BagWriter

__all__ = ["BagError", "BagMessage", "BagReader", "BagWriter", "OnError", "TopicInfo",
           "make_typestore", "open_bag", "register_definition", "vision_msgs_definitions"]


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
        self._files: list[StorageFile] = []
        self._expected: dict[str, int] | None = None
        self._expected_types: dict[str, str] = {}
        self._expected_per_file: dict[str, int] = {}
        self.storage: str = ""
        #: rosbag2 ``compression_mode`` of the bag ("" none, "file", "message"; zstd only)
        self.compression_mode: str = ""
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
        found = sorted(p for p in self.path.iterdir() if p.suffix in (".mcap", ".db3") or
                       p.name.endswith((".mcap.zstd", ".db3.zstd")))
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
        mode = str(info.get("compression_mode") or "").lower()
        if mode not in ("", "none"):
            fmt = str(info.get("compression_format") or "").lower()
            if mode not in ("file", "message") or fmt != "zstd":
                raise BagError(f"{meta_path}: compressed bags ({mode}, {fmt or 'no format'})"
                               f" are read only in file or message mode with zstd")
            self.compression_mode = mode
        paths = [self.path / Path(f).name for f in files]
        existing = []
        for p in paths:
            if p.is_file():
                existing.append(p)
            else:
                self._problem(f"{p}: split file listed in metadata.yaml is missing")
        return existing

    def _open_file(self, path: Path) -> None:
        try:
            f = open_storage_file(path, self.storage, self.on_error, self.compression_mode)
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

    def _topic_table(self) -> dict[str, StoredTopic]:
        table: dict[str, StoredTopic] = {}
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

    def _guarded(self, index: int, f: StorageFile, topics, start, stop
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
            if isinstance(f, McapFile):
                # skip mode: rescan the file and deliver what the index could not
                scan = McapScan(f.path, reason)
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
