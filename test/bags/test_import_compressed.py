"""`mk_tracker import --compressed jpeg|png`: the bag a robot's image_transport records
(CompressedImage on <topic>/compressed), and `mk_tracker process` reading it (#20)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from mk_tracker.bags.bag_io import open_bag
from mk_tracker.messages.compressed_image import as_image
from mk_tracker.messages.image_conversion import image_to_numpy
from mk_tracker.tools import cli


def _messages(bag: Path, topic: str) -> list:
    with open_bag(bag) as reader:
        assert reader.topics[topic].msgtype == "sensor_msgs/msg/CompressedImage"
        return [reader.deserialize(m) for m in reader.messages([topic])]


def _thermal_folder(tmp_path: Path) -> Path:
    folder = tmp_path / "lwir"
    folder.mkdir()
    for k in range(4):
        img = np.full((24, 32), 7000 + 100 * k, np.uint16)
        img[5:9, 3 + k:7 + k] = 9000
        cv2.imwrite(str(folder / f"frame_{k}.png"), img)
    return folder


def test_thermal_png_import_is_lossless_and_jpeg_is_refused(tmp_path, capsys):
    folder = _thermal_folder(tmp_path)
    out = tmp_path / "bag"
    assert cli.main(["import", str(folder), "--out", str(out), "--thermal", "--fps", "4",
                     "--compressed", "jpeg", "--quiet"]) == 1
    err = capsys.readouterr().err
    assert "jpeg cannot hold a mono16" in err and "--compressed" in err
    assert not out.exists()
    assert cli.main(["import", str(folder), "--out", str(out), "--thermal", "--fps", "4",
                     "--compressed", "png", "--quiet"]) == 0
    msgs = _messages(out, "/thermal/image_raw/compressed")
    assert [m.format for m in msgs] == ["mono16; png compressed mono16"] * 4
    for k, m in enumerate(msgs):
        np.testing.assert_array_equal(image_to_numpy(as_image(m)),
                                      cv2.imread(str(folder / f"frame_{k}.png"),
                                                 cv2.IMREAD_UNCHANGED))
    assert msgs[0].header.frame_id == "thermal_camera"


def test_rgb_jpeg_import_then_process_finds_the_topic_by_its_type(tmp_path, capsys):
    folder = tmp_path / "frames"
    folder.mkdir()
    for k in range(6):
        img = np.full((48, 64, 3), 30, np.uint8)
        img[10:30, 5 + 4 * k:25 + 4 * k] = (40, 200, 220)
        cv2.imwrite(str(folder / f"{k:04d}.png"), img)
    out = tmp_path / "bag"
    assert cli.main(["import", str(folder), "--out", str(out), "--fps", "10",
                     "--compressed", "jpeg", "--jpeg-quality", "90", "--quiet"]) == 0
    msgs = _messages(out, "/image_raw/compressed")
    assert len(msgs) == 6 and msgs[0].format == "bgr8; jpeg compressed bgr8"
    assert bytes(msgs[0].data[:2]) == b"\xff\xd8"                    # a JPEG stream
    decoded = image_to_numpy(as_image(msgs[3]))
    want = cv2.imread(str(folder / "0003.png"))
    assert np.abs(decoded.astype(int) - want).mean() < 3             # JPEG loss only
    # process: the default /image_raw is missing; the error names the compressed sibling
    assert cli.main(["process", str(out), "--out", str(tmp_path / "p1"), "--quiet"]) == 2
    assert "use --image-topic /image_raw/compressed" in capsys.readouterr().err
    assert cli.main(["process", str(out), "--out", str(tmp_path / "p2"), "--quiet",
                     "--no-video", "--detections", "none",
                     "--image-topic", "/image_raw/compressed",
                     "--init", "5,10,20,20"]) == 0
    summary = capsys.readouterr().out
    assert "processed 6 frames (0 bad, 0 bad messages)" in summary
