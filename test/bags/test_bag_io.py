"""Bag writing and reading: round trips, the real rosbag2 bags, damaged bags."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from mk_tracker.bags.bag_errors import BagError
from mk_tracker.bags.bag_io import open_bag
from mk_tracker.bags.bag_typestore import make_typestore
from mk_tracker.bags.bag_writer import BagWriter
from mk_tracker.messages.detection_messages import Detection, make_detection_array, read_detection_array
from mk_tracker.messages.image_conversion import image_to_numpy, numpy_to_image
from mk_tracker.messages.message_types import bag_message_types, make_header, stamp_to_nanoseconds

STORE = make_typestore()
TYPES = bag_message_types(STORE)
N_FRAMES = 6


def frame(i: int) -> np.ndarray:
    img = np.zeros((48, 64, 3), np.uint8)
    img[..., 0] = i
    img[i, :, 1] = 255
    return img


def boxes(i: int) -> list[Detection]:
    return [Detection((float(i), 2.0, 10.0, 20.0), 1.0, "person", str(k)) for k in range(i % 3)]


def write_scene(path: Path, storage: str, n: int = N_FRAMES, size: tuple = (48, 64)) -> Path:
    with BagWriter(path, storage, typestore=STORE) as bag:
        bag.add_topic("/image_raw", "sensor_msgs/msg/Image")
        for i in range(n):
            stamp = 1_000_000_000 + i * 40_000_000
            header = make_header(TYPES, "camera", stamp)
            img = np.full(size + (3,), i, np.uint8) if size != (48, 64) else frame(i)
            bag.write("/image_raw", stamp, numpy_to_image(img, "bgr8", header, types=TYPES))
            bag.write("/ground_truth", stamp,
                      make_detection_array(boxes(i), header, TYPES))
    return path


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_round_trip_images_and_detections(tmp_path, storage):
    path = write_scene(tmp_path / "bag", storage)
    with open_bag(path) as bag:
        topics = bag.topics
        assert topics["/image_raw"].msgtype == "sensor_msgs/msg/Image"
        assert topics["/ground_truth"].msgtype == "vision_msgs/msg/Detection2DArray"
        assert topics["/image_raw"].count == topics["/image_raw"].expected == N_FRAMES
        assert bag.message_count == 2 * N_FRAMES
        seen = [(m.topic, m.timestamp_ns) for m in bag.messages()]
        assert [t for t, _ in seen[:2]] == ["/image_raw", "/ground_truth"]
        assert [ts for _, ts in seen] == sorted(ts for _, ts in seen)
        images = list(bag.read_messages(["/image_raw"]))
        assert len(images) == N_FRAMES
        for i, (raw, msg) in enumerate(images):
            np.testing.assert_array_equal(image_to_numpy(msg), frame(i))
            assert stamp_to_nanoseconds(msg.header.stamp) == raw.timestamp_ns
            assert msg.header.frame_id == "camera"
        gts = [read_detection_array(msg) for _, msg in bag.read_messages(["/ground_truth"])]
        assert gts == [boxes(i) for i in range(N_FRAMES)]
        window = list(bag.messages(start_ns=1_040_000_000, stop_ns=1_120_000_000))
        assert len(window) == 4
        assert bag.problems == []


def test_writer_errors(tmp_path):
    path = write_scene(tmp_path / "bag", "mcap", n=1)
    with pytest.raises(BagError, match="exists already"):
        BagWriter(path)
    with pytest.raises(BagError, match="storage must be"):
        BagWriter(tmp_path / "other", storage="rosbag1")
    with BagWriter(tmp_path / "w", typestore=STORE) as bag:
        with pytest.raises(BagError, match="not added"):
            bag.write_raw("/x", 0, b"")
        with pytest.raises(BagError, match="unknown to the typestore"):
            bag.add_topic("/x", "nope_msgs/msg/Nope")
        with pytest.raises(BagError, match="not a rosbags message"):
            bag.write("/x", 0, object())
        bag.write("/t", 0, TYPES.Time(sec=1, nanosec=2))
        with pytest.raises(BagError, match="has type"):
            bag.write("/t", 1, make_header(TYPES, "camera"))
        with pytest.raises(BagError, match="negative timestamp"):
            bag.write("/t", -1, TYPES.Time(sec=1, nanosec=2))
    with open_bag(tmp_path / "w") as bag:
        assert bag.topics["/t"].count == 1


def test_topic_selection_rejects_unknown_topics(tmp_path):
    path = write_scene(tmp_path / "bag", "mcap", n=2)
    with open_bag(path) as bag:
        with pytest.raises(BagError, match="no topic"):
            list(bag.messages(["/nope"]))


# --- real bags written by ros2 bag record (rosbag2's own test resources) ---------------

EXPECTED = {  # from each bag's metadata.yaml, as documented in the data README
    "talker": {"/topic": 10, "/rosout": 10, "/parameter_events": 0},
    "wbag": {"AAA": 804, "BBB": 742, "CCC": 742, "DDD": 753, "EEE": 804, "FFF": 772,
             "GGG": 731, "HHH": 726},
    "cdr_test": {"/test_topic": 3, "/array_topic": 4},
}


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_real_bags_read_completely(shared_data, storage, name):
    path = shared_data / "rosbag2_real" / storage / name
    if not path.is_dir():
        pytest.skip(f"{path} absent")
    with open_bag(path) as bag:
        assert {t: i.count for t, i in bag.topics.items()} == EXPECTED[name]
        counts: dict[str, int] = {}
        last = -1
        for msg in bag.messages():
            assert msg.timestamp_ns >= last
            last = msg.timestamp_ns
            counts[msg.topic] = counts.get(msg.topic, 0) + 1
            bag.deserialize(msg)
        assert counts == {t: n for t, n in EXPECTED[name].items() if n}
        assert bag.problems == []
        if name == "wbag":
            assert len(bag.files) == 5


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_talker_trap_is_avoided(shared_data, storage):
    """rosbags' own Reader matches connections by QoS string and yields nothing here."""
    path = shared_data / "rosbag2_real" / storage / "talker"
    if not path.is_dir():
        pytest.skip(f"{path} absent")
    with open_bag(path) as bag:
        texts = [bag.deserialize(m).data for m in bag.messages(["/topic"])]
    assert texts[0] == "Hello, world! 0" and len(texts) == 10


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_stored_definitions_register_unknown_types(shared_data, storage):
    path = shared_data / "rosbag2_real" / storage / "cdr_test"
    if not path.is_dir():
        pytest.skip(f"{path} absent")
    assert "test_msgs/msg/BasicTypes" not in make_typestore().types
    with open_bag(path) as bag:
        basic = [bag.deserialize(m) for m in bag.messages(["/test_topic"])]
    assert len(basic) == 3 and all(b.int32_value == 123 for b in basic)


def test_missing_split_file_of_real_bag(shared_data, tmp_path):
    source = shared_data / "rosbag2_real" / "sqlite3" / "wbag"
    if not source.is_dir():
        pytest.skip(f"{source} absent")
    copy = Path(shutil.copytree(source, tmp_path / "wbag"))
    (copy / "wbag_2.db3").unlink()
    with pytest.raises(BagError, match="wbag_2.db3.*missing"):
        open_bag(copy)
    with open_bag(copy, on_error="skip") as bag:
        n = sum(1 for _ in bag.messages())
    assert n == 6074 - 1240
    assert any("wbag_2.db3" in p for p in bag.problems)


# --- damaged bags ------------------------------------------------------------------------

def storage_file(path: Path) -> Path:
    (found,) = [p for p in path.iterdir() if p.suffix in (".mcap", ".db3")]
    return found


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_truncated_storage_file(tmp_path, storage):
    path = write_scene(tmp_path / "bag", storage, n=8, size=(240, 320))
    data_file = storage_file(path)
    data = data_file.read_bytes()
    data_file.write_bytes(data[: len(data) * 6 // 10])
    with pytest.raises(BagError, match=data_file.name):
        with open_bag(path) as bag:
            list(bag.messages())
    with open_bag(path, on_error="skip") as bag:
        got = [m for m in bag.messages()]
        images = [image_to_numpy(bag.deserialize(m)) for m in got if m.topic == "/image_raw"]
    assert 0 < len(images) < 8
    for i, img in enumerate(images):  # what is delivered is intact and in order
        assert img.shape == (240, 320, 3) and np.all(img == i)
    assert any(data_file.name in p for p in bag.problems)


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_garbage_storage_file(tmp_path, storage):
    path = write_scene(tmp_path / "bag", storage, n=2)
    data_file = storage_file(path)
    data_file.write_bytes(b"this is not a bag" * 100)
    with pytest.raises(BagError, match=data_file.name):
        open_bag(path)
    with open_bag(path, on_error="skip") as bag:
        assert list(bag.messages()) == []
        assert any(data_file.name in p for p in bag.problems)


def test_missing_metadata(tmp_path):
    path = write_scene(tmp_path / "bag", "mcap", n=3)
    (path / "metadata.yaml").unlink()
    with pytest.raises(BagError, match="metadata.yaml: missing"):
        open_bag(path)
    with open_bag(path, on_error="skip") as bag:
        assert sum(1 for m in bag.messages() if m.topic == "/image_raw") == 3


def test_single_storage_file_can_be_opened(tmp_path):
    path = write_scene(tmp_path / "bag", "sqlite3", n=3)
    with open_bag(storage_file(path)) as bag:
        assert bag.topics["/image_raw"].count == 3
        assert bag.topics["/image_raw"].expected is None


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_metadata_count_mismatch_is_reported(tmp_path, storage):
    path = write_scene(tmp_path / "bag", storage, n=3)
    meta_path = path / "metadata.yaml"
    meta = yaml.safe_load(meta_path.read_text())
    for entry in meta["rosbag2_bagfile_information"]["topics_with_message_count"]:
        if entry["topic_metadata"]["name"] == "/image_raw":
            entry["message_count"] = 5
    meta_path.write_text(yaml.safe_dump(meta))
    with pytest.raises(BagError, match="/image_raw: metadata.yaml lists 5 messages.*hold 3"):
        open_bag(path)
    with open_bag(path, on_error="skip") as bag:
        assert sum(1 for m in bag.messages() if m.topic == "/image_raw") == 3
        assert len(bag.problems) == 1


def test_missing_listed_file_and_missing_bag(tmp_path):
    path = write_scene(tmp_path / "bag", "mcap", n=2)
    meta_path = path / "metadata.yaml"
    meta = yaml.safe_load(meta_path.read_text())
    meta["rosbag2_bagfile_information"]["relative_file_paths"].append("bag_1.mcap")
    meta_path.write_text(yaml.safe_dump(meta))
    with pytest.raises(BagError, match="bag_1.mcap: split file .* missing"):
        open_bag(path)
    with pytest.raises(BagError, match="no such bag"):
        open_bag(tmp_path / "nothing")
    (meta_path).write_text("rosbag2_bagfile_information: [unclosed")
    with pytest.raises(BagError, match="metadata.yaml: unreadable"):
        open_bag(path)


def test_raw_cdr_lazy_open_and_qos(tmp_path):
    path = tmp_path / "rec"
    writer = BagWriter(path, "sqlite3", typestore=STORE)
    assert not path.exists()  # nothing created before the first topic
    writer.add_topic("/image_raw", "sensor_msgs/msg/Image",
                     offered_qos_profiles=[{"history": 1, "depth": 5, "reliability": 2,
                                            "durability": 2}])
    img = numpy_to_image(frame(1), "bgr8", make_header(TYPES, "camera", 7), types=TYPES)
    writer.write("/image_raw", 7, bytes(STORE.serialize_cdr(img, "sensor_msgs/msg/Image")))
    with pytest.raises(BagError, match="invalid QoS"):
        writer.add_topic("/x", "std_msgs/msg/Header", [{"reliability": 42}])
    writer.close()
    meta = yaml.safe_load((path / "metadata.yaml").read_text())
    (entry,) = meta["rosbag2_bagfile_information"]["topics_with_message_count"]
    (profile,) = entry["topic_metadata"]["offered_qos_profiles"]
    assert (profile["reliability"], profile["durability"], profile["depth"]) == \
        ("best_effort", "volatile", 5)
    with open_bag(path) as bag:
        (msg,) = [bag.deserialize(m) for m in bag.messages()]
    np.testing.assert_array_equal(image_to_numpy(msg), frame(1))
    BagWriter(tmp_path / "unused").close()
    assert not (tmp_path / "unused").exists()


def test_damaged_record_inside_mcap_chunk(tmp_path):
    """A broken record in the middle chunk: raise, or deliver the other chunks."""
    import struct

    path = write_scene(tmp_path / "bag", "mcap", n=12, size=(240, 320))
    data_file = storage_file(path)
    data = bytearray(data_file.read_bytes())
    pos, chunks = 8, []
    while data[pos] != 0x02:  # walk the top-level records up to the footer
        (length,) = struct.unpack_from("<Q", data, pos + 1)
        if data[pos] == 0x06:
            chunks.append(pos)
        pos += 9 + length
    assert len(chunks) >= 3  # 230 kB frames, rosbags closes a chunk after 1 MiB
    first_record = chunks[1] + 9 + 28 + 4 + 8  # header, times/sizes/crc, "", records length
    struct.pack_into("<Q", data, first_record + 1, 10**12)  # absurd record length
    data_file.write_bytes(bytes(data))
    with pytest.raises(BagError, match="bag.mcap: damaged data"):
        with open_bag(path) as bag:
            list(bag.messages())
    with open_bag(path, on_error="skip") as bag:
        stamps = [m.timestamp_ns for m in bag.messages(["/image_raw"])]
    all_stamps = [1_000_000_000 + i * 40_000_000 for i in range(12)]
    assert set(stamps) < set(all_stamps)
    assert stamps[-1] == all_stamps[-1]  # the chunk after the damage was recovered
    assert len(stamps) == len(set(stamps))  # nothing delivered twice
    assert any("damaged" in p for p in bag.problems)
