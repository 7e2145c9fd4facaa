"""zstd-compressed bags (``ros2 bag record --compression-mode file|message
--compression-format zstd``) written by rosbags' own Writer, read by BagReader."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from rosbags.rosbag2 import Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode, StoragePlugin

from mk_tracker.bags.bag_errors import BagError
from mk_tracker.bags.bag_io import open_bag
from mk_tracker.bags.bag_typestore import make_typestore
from mk_tracker.messages.image_conversion import image_to_numpy, numpy_to_image
from mk_tracker.messages.message_types import bag_message_types, make_header

STORE = make_typestore()
TYPES = bag_message_types(STORE)
N = 12


def frame(i: int) -> np.ndarray:
    """Noise (so that zstd cannot shrink it: the file spans many zstd blocks) tagged i."""
    image = np.random.default_rng(i).integers(0, 256, size=(120, 160), dtype=np.uint8)
    image[0, 0] = i
    return image


def write(path: Path, mode: CompressionMode, plugin: StoragePlugin) -> Path:
    writer = Writer(path, version=9, storage_plugin=plugin)
    writer.set_compression(mode, CompressionFormat.ZSTD)
    with writer:
        conn = writer.add_connection("/thermal/image_raw", "sensor_msgs/msg/Image",
                                     typestore=STORE)
        for i in range(N):
            msg = numpy_to_image(frame(i), "mono8", make_header(TYPES, "cam", 1000 + i),
                                 types=TYPES)
            writer.write(conn, 1000 + i, STORE.serialize_cdr(msg, "sensor_msgs/msg/Image"))
    return path


MODES = [(m, p) for m in (CompressionMode.FILE, CompressionMode.MESSAGE)
         for p in (StoragePlugin.MCAP, StoragePlugin.SQLITE3)]


@pytest.mark.parametrize("mode,plugin", MODES, ids=lambda v: v.name.lower())
def test_zstd_bags_read_every_message(tmp_path, mode, plugin):
    bag = write(tmp_path / "bag", mode, plugin)
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["compression_mode"] == mode.name.lower()   # the bag is what we think it is
    if mode == CompressionMode.FILE:
        assert all(str(f).endswith(".zstd") for f in meta["relative_file_paths"])
    with open_bag(bag) as reader:
        assert reader.topics["/thermal/image_raw"].count == N
        got = [(m.timestamp_ns, image_to_numpy(reader.deserialize(m)))
               for m in reader.messages()]
        assert reader.problems == []
    assert [ts for ts, _ in got] == [1000 + i for i in range(N)]
    for i, (_, image) in enumerate(got):
        np.testing.assert_array_equal(image, frame(i))


def test_a_truncated_zstd_file_raises_or_keeps_what_decompressed(tmp_path):
    bag = write(tmp_path / "bag", CompressionMode.FILE, StoragePlugin.MCAP)
    (stored,) = [p for p in bag.iterdir() if p.name.endswith(".zstd")]
    data = stored.read_bytes()
    stored.write_bytes(data[:int(len(data) * 0.6)])
    with pytest.raises(BagError, match="truncated zstd"):
        open_bag(bag).close()
    with open_bag(bag, on_error="skip") as reader:
        got = [image_to_numpy(reader.deserialize(m)) for m in reader.messages()]
        problems = list(reader.problems)
    assert any("truncated zstd" in p for p in problems)
    assert 0 < len(got) < N            # the start of the file was salvaged, in order
    for i, image in enumerate(got):
        np.testing.assert_array_equal(image, frame(i))


def test_a_payload_that_does_not_decompress_is_skipped_and_named(tmp_path):
    import sqlite3
    bag = write(tmp_path / "bag", CompressionMode.MESSAGE, StoragePlugin.SQLITE3)
    (db,) = bag.glob("*.db3")
    with sqlite3.connect(db) as con:
        con.execute("UPDATE messages SET data = ? WHERE timestamp = 1005", (b"not zstd",))
    with open_bag(bag) as reader, pytest.raises(BagError, match="does not decompress"):
        list(reader.messages())
    with open_bag(bag, on_error="skip") as reader:
        stamps = [m.timestamp_ns for m in reader.messages()]
        problems = list(reader.problems)
    assert stamps == [1000 + i for i in range(N) if i != 5]
    assert any("at 1005 does not decompress" in p for p in problems)


def test_another_compression_format_is_refused_clearly(tmp_path):
    bag = write(tmp_path / "bag", CompressionMode.MESSAGE, StoragePlugin.MCAP)
    meta = bag / "metadata.yaml"
    meta.write_text(meta.read_text().replace("compression_format: zstd",
                                             "compression_format: lz4"))
    with pytest.raises(BagError, match="zstd"):
        open_bag(bag)
