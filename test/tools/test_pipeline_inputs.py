"""`mk_tracker process` on bags in the forms real robots record (issue #20): camera images
as sensor_msgs/CompressedImage, zstd-compressed bags, camera encodings, and the errors a
wrong topic or unusable frames give up front."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mk_tracker.bags.bag_io import open_bag
from mk_tracker.bags.bag_writer import BagWriter
from mk_tracker.boxes import iou
from mk_tracker.messages.compressed_image import COMPRESSED_TYPE, numpy_to_compressed
from mk_tracker.messages.image_conversion import image_to_numpy
from mk_tracker.messages.message_types import bag_message_types
from mk_tracker.synthetic.scene_bag import build_preset, write_scene_bag
from mk_tracker.tools.cli import main as cli_main
from mk_tracker.tools.pipeline import PipelineOptions, process_bag

FRAMES = 24
COMPRESSED = "/camera/image_raw/compressed"


@pytest.fixture(scope="module")
def raw_bag(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("scene") / "crowd"
    scene = build_preset("crowd", seed=1, people=3, frames=FRAMES, width=320, height=240)
    write_scene_bag(scene, path, preset="crowd")
    return path


def rewrite(src: Path, dst: Path, image, image_topic: str, image_type: str) -> None:
    """Copy ``src`` with every /image_raw message replaced by ``image(types, msg)`` on
    ``image_topic`` (of ``image_type``)."""
    with open_bag(src) as reader, BagWriter(dst, typestore=reader.typestore) as writer:
        types = bag_message_types(reader.typestore)
        for t in reader.topics.values():
            writer.add_topic(*((image_topic, image_type) if t.name == "/image_raw"
                               else (t.name, t.msgtype)))
        for m in reader.messages():
            if m.topic == "/image_raw":
                writer.write(image_topic, m.timestamp_ns, image(types, reader.deserialize(m)))
            else:
                writer.write(m.topic, m.timestamp_ns, m.data)


def jpeg(types, msg):
    return numpy_to_compressed(image_to_numpy(msg), msg.encoding, "jpeg", msg.header,
                               types=types, jpeg_quality=90)


@pytest.fixture(scope="module")
def jpeg_bag(raw_bag, tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("jpeg") / "compressed"
    rewrite(raw_bag, path, jpeg, COMPRESSED, COMPRESSED_TYPE)
    return path


def run(bag: Path, out: Path, topic: str):
    return process_bag(bag, out, options=PipelineOptions(
        image_topic=topic, progress=False, write_video=False, write_bag=False))


def compare(a, b) -> tuple[int, float]:
    """Frames whose track sets differ in ids, and the smallest IoU of same-id boxes."""
    differ, worst = 0, 1.0
    for stamp in a.tracks:
        ta, tb = dict(a.tracks[stamp]), dict(b.tracks.get(stamp, []))
        if set(ta) != set(tb):
            differ += 1
        for tid in set(ta) & set(tb):
            worst = min(worst, iou(ta[tid], tb[tid]))
    return differ, worst


def test_a_jpeg_topic_tracks_like_the_raw_images(raw_bag, jpeg_bag, tmp_path):
    raw = run(raw_bag, tmp_path / "raw", "/image_raw")
    comp = run(jpeg_bag, tmp_path / "jpeg", COMPRESSED)
    assert raw.tracked_frames == comp.tracked_frames == FRAMES
    assert comp.bad_messages == 0 and comp.track_ids
    assert sorted(raw.tracks) == sorted(comp.tracks)      # the same header stamps
    differ, worst = compare(raw, comp)
    assert differ <= FRAMES // 10 and worst > 0.8, (differ, worst)


def test_missing_topic_with_a_compressed_sibling_names_the_fix(jpeg_bag, tmp_path, capsys):
    rc = cli_main(["process", str(jpeg_bag), "--out", str(tmp_path), "--quiet",
                   "--image-topic", "/camera/image_raw"])
    err = capsys.readouterr().err
    assert rc == 2
    assert "no /camera/image_raw topic" in err
    assert f"use --image-topic {COMPRESSED}" in err
    assert not (tmp_path / "summary.json").exists()


def test_a_topic_of_another_type_stops_before_processing(raw_bag, tmp_path, capsys):
    rc = cli_main(["process", str(raw_bag), "--out", str(tmp_path), "--quiet",
                   "--image-topic", "/ground_truth"])
    err = capsys.readouterr().err
    assert rc == 2
    assert "/ground_truth holds vision_msgs/msg/Detection2DArray" in err
    assert "/image_raw (Image)" in err and "/thermal/image_raw (Image)" in err
    assert not (tmp_path / "summary.json").exists()


def test_unusable_frames_exit_non_zero_with_a_summary(raw_bag, tmp_path, capsys):
    def unusable(types, msg):          # a 16-bit Bayer camera: not a supported encoding
        msg.encoding = "bayer_rggb16"
        return msg

    bag = tmp_path / "bayer16"
    rewrite(raw_bag, bag, unusable, "/image_raw", "sensor_msgs/msg/Image")
    rc = cli_main(["process", str(bag), "--out", str(tmp_path / "out"), "--quiet",
                   "--no-video"])
    err = capsys.readouterr().err
    assert rc == 3
    assert f"only 0 of {FRAMES} image messages on /image_raw could be tracked" in err
    assert "bayer_rggb16" in err
    # the same run with the threshold set to zero is accepted
    assert cli_main(["process", str(bag), "--out", str(tmp_path / "out2"), "--quiet",
                     "--no-video", "--min-usable", "0"]) == 0


def uyvy(types, msg):
    """The image as UYVY bytes, built with BT.601 video-range formulas written here."""
    bgr = image_to_numpy(msg).astype(np.float64)
    b, g, r = bgr[..., 0], bgr[..., 1], bgr[..., 2]
    y = 16 + (65.481 * r + 128.553 * g + 24.966 * b) / 255
    u = 128 + (-37.797 * r - 74.203 * g + 112.0 * b) / 255
    v = 128 + (112.0 * r - 93.786 * g - 18.214 * b) / 255
    u2 = (u[:, 0::2] + u[:, 1::2]) / 2
    v2 = (v[:, 0::2] + v[:, 1::2]) / 2
    packed = np.stack([u2, y[:, 0::2], v2, y[:, 1::2]], axis=-1)
    data = np.clip(np.rint(packed), 0, 255).astype(np.uint8).reshape(msg.height, -1)
    return types.Image(header=msg.header, height=msg.height, width=msg.width,
                       encoding="yuv422", is_bigendian=0, step=msg.width * 2,
                       data=data.reshape(-1))


def test_a_yuv422_topic_tracks_like_the_raw_images(raw_bag, tmp_path):
    bag = tmp_path / "yuv"
    rewrite(raw_bag, bag, uyvy, "/image_raw", "sensor_msgs/msg/Image")
    raw = run(raw_bag, tmp_path / "raw", "/image_raw")
    yuv = run(bag, tmp_path / "yuv_out", "/image_raw")
    assert yuv.tracked_frames == FRAMES and yuv.bad_messages == 0
    differ, worst = compare(raw, yuv)
    assert differ <= FRAMES // 10 and worst > 0.8, (differ, worst)
