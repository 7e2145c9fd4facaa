"""`mk_tracker import` of recordings without annotations: video files and image folders,
RGB or thermal (mono8 / mono16), with an RGB pair and a homography (issues #13, #19); and
`mk_tracker process` on a thermal-only bag (the thermal image itself is tracked)."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from mk_tracker.bags.bag_io import open_bag
from mk_tracker.bags.recording_import import read_homography
from mk_tracker.bags.video_source import FrameSourceError, open_frames
from mk_tracker.messages.image_conversion import image_to_numpy
from mk_tracker.messages.message_types import stamp_to_nanoseconds
from mk_tracker.tools import cli


def _messages(bag: Path, topic: str) -> list:
    with open_bag(bag) as reader:
        return [(m.timestamp_ns, reader.deserialize(m)) for m in reader.messages([topic])]


def _write_video(path: Path, frames: list[np.ndarray], fps: float) -> None:
    h, w = frames[0].shape[:2]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, (w, h))
    assert writer.isOpened()
    for f in frames:
        writer.write(f)
    writer.release()


def _moving_square(k: int, size: int = 64) -> np.ndarray:
    img = np.full((size, size, 3), 40, np.uint8)
    img[20:36, 4 + 3 * k:20 + 3 * k] = (200, 200, 200)
    return img


def test_video_is_imported_with_the_containers_frame_rate(tmp_path):
    video = tmp_path / "clip.avi"
    frames = [_moving_square(k) for k in range(12)]
    _write_video(video, frames, fps=8.0)
    out = tmp_path / "bag"
    assert cli.main(["import", str(video), "--out", str(out), "--quiet"]) == 0
    msgs = _messages(out, "/image_raw")
    assert len(msgs) == 12
    # frame k at k / 8 s, header stamp equal to the bag time
    assert [ns for ns, _ in msgs] == [round(k * 1e9 / 8) for k in range(12)]
    assert all(stamp_to_nanoseconds(m.header.stamp) == ns for ns, m in msgs)
    first = image_to_numpy(msgs[5][1])
    assert msgs[5][1].encoding == "bgr8" and first.shape == (64, 64, 3)
    # the bright square of frame 5 is where it was drawn (MJPG is lossy: compare means)
    assert first[20:36, 19:35].mean() > 150 and first[40:, :].mean() < 60


def test_thermal_folder_keeps_16_bits_and_needs_a_frame_rate(tmp_path, capsys):
    folder = tmp_path / "lwir"
    folder.mkdir()
    for k in (1, 2, 10):                      # natural order: frame_2 before frame_10
        img = np.full((24, 32), 7000 + 100 * k, np.uint16)
        cv2.imwrite(str(folder / f"frame_{k}.png"), img)
    out = tmp_path / "bag"
    assert cli.main(["import", str(folder), "--out", str(out), "--thermal", "--quiet"]) == 1
    assert "--fps" in capsys.readouterr().err and not out.exists()
    assert cli.main(["import", str(folder), "--out", str(out), "--thermal", "--fps", "4",
                     "--quiet"]) == 0
    msgs = _messages(out, "/thermal/image_raw")
    assert [m.encoding for _, m in msgs] == ["mono16"] * 3
    assert [int(image_to_numpy(m)[0, 0]) for _, m in msgs] == [7100, 7200, 8000]
    assert [ns for ns, _ in msgs] == [0, 250_000_000, 500_000_000]
    assert msgs[0][1].header.frame_id == "thermal_camera"
    with open_bag(out) as reader:
        assert "/image_raw" not in reader.topics


def test_unreadable_folder_image_is_skipped_and_reported(tmp_path, capsys):
    folder = tmp_path / "imgs"
    folder.mkdir()
    for k in range(3):
        cv2.imwrite(str(folder / f"{k:03d}.png"), _moving_square(k))
    (folder / "001.png").write_bytes(b"not a png")
    out = tmp_path / "bag"
    assert cli.main(["import", str(folder), "--out", str(out), "--fps", "5",
                     "--quiet"]) == 0
    assert "1 image file(s) could not be read" in capsys.readouterr().err
    assert len(_messages(out, "/image_raw")) == 2


def test_mixed_frame_sizes_are_an_error_and_leave_no_bag(tmp_path, capsys):
    folder = tmp_path / "imgs"
    folder.mkdir()
    cv2.imwrite(str(folder / "000.png"), _moving_square(0, 64))
    cv2.imwrite(str(folder / "001.png"), _moving_square(0, 32))
    out = tmp_path / "bag"
    assert cli.main(["import", str(folder), "--out", str(out), "--fps", "5",
                     "--quiet"]) == 1
    assert "001.png" in capsys.readouterr().err and not out.exists()


def test_thermal_with_rgb_pair_and_homography(tmp_path):
    thermal = tmp_path / "t.avi"
    rgb = tmp_path / "rgb"
    rgb.mkdir()
    _write_video(thermal, [_moving_square(k) for k in range(6)], fps=10.0)
    for k in range(4):                        # the shorter source sets the length
        cv2.imwrite(str(rgb / f"{k}.png"), _moving_square(k, 128))
    hfile = tmp_path / "h.txt"
    hfile.write_text("# thermal -> rgb\n2 0 0\n0 2 0\n0 0 1\n")
    out = tmp_path / "bag"
    assert cli.main(["import", str(thermal), "--thermal", "--rgb", str(rgb), "--homography",
                     str(hfile), "--out", str(out), "--quiet"]) == 0
    th, im = _messages(out, "/thermal/image_raw"), _messages(out, "/image_raw")
    assert len(th) == len(im) == 4
    assert [ns for ns, _ in th] == [ns for ns, _ in im] == [0, 100_000_000, 200_000_000,
                                                           300_000_000]
    assert th[0][1].encoding == "mono8" and image_to_numpy(im[0][1]).shape == (128, 128, 3)
    (_, info), = _messages(out, "/scene_info")
    assert json.loads(info.data)["homography"] == [2.0, 0, 0, 0, 2.0, 0, 0, 0, 1.0]


def test_rgb_pair_without_thermal_is_refused(tmp_path, capsys):
    video = tmp_path / "clip.avi"
    _write_video(video, [_moving_square(k) for k in range(3)], fps=5.0)
    assert cli.main(["import", str(video), "--rgb", str(video), "--out",
                     str(tmp_path / "bag"), "--quiet"]) == 1
    assert "--thermal" in capsys.readouterr().err


@pytest.mark.parametrize("text, problem", [
    ("1 2 3\n4 5 6\n7 8", "9 numbers"),
    ("1 0 0\n0 1 0\n0 0 0", "invertible"),
    ('{"homography": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}', None),
])
def test_homography_file(tmp_path, text, problem):
    path = tmp_path / "h"
    path.write_text(text)
    if problem is None:
        assert np.array_equal(read_homography(path), np.eye(3))
    else:
        with pytest.raises(FrameSourceError, match=problem):
            read_homography(path)


def test_open_frames_errors(tmp_path):
    with pytest.raises(FrameSourceError, match="no such file"):
        open_frames(tmp_path / "missing.mp4")
    (tmp_path / "notes.txt").write_text("x")
    with pytest.raises(FrameSourceError, match="not a video file"):
        open_frames(tmp_path / "notes.txt")
    (tmp_path / "empty").mkdir()
    with pytest.raises(FrameSourceError, match="no image files"):
        open_frames(tmp_path / "empty")
    (tmp_path / "broken.mp4").write_bytes(b"\x00" * 100)
    with pytest.raises(FrameSourceError, match="cannot open"):
        open_frames(tmp_path / "broken.mp4")
    with pytest.raises(FrameSourceError, match="positive"):
        open_frames(tmp_path / "empty", fps=0.0)


def test_process_tracks_a_thermal_only_bag_in_the_thermal_image(tmp_path):
    """No /image_raw: the pipeline tracks on /thermal/image_raw with the detector's boxes
    (thermal-only mode), and says so in its summary."""
    from mk_tracker.synthetic.scene_bag import build_preset
    scene = build_preset("crowd", seed=3, people=2, frames=40, width=160, height=120)
    folder = tmp_path / "frames"
    folder.mkdir()
    for k in range(40):
        thermal = scene.frame(k).thermal
        assert thermal.dtype in (np.uint8, np.uint16)
        cv2.imwrite(str(folder / f"{k:04d}.png"), thermal)
    bag = tmp_path / "bag"
    assert cli.main(["import", str(folder), "--thermal", "--fps", "25", "--out", str(bag),
                     "--quiet"]) == 0
    out = tmp_path / "run"
    rc = cli.main(["process", str(bag), "--out", str(out), "--quiet", "--no-video"])
    summary = json.loads((out / "summary.json").read_text())
    assert rc == 0, summary
    assert summary["thermal_only"] is True and summary["detection_source"] == "thermal"
    assert summary["frames"] == 40 and summary["detections"] > 0


def test_process_runs_on_a_video_in_one_step(tmp_path):
    """`mk_tracker process VIDEO`: imported into OUT/input_bag, and an RGB recording with
    --detections auto is detected by background subtraction (issue #13)."""
    from mk_tracker.synthetic.scene_bag import build_preset
    scene = build_preset("crowd", seed=5, people=2, frames=40, width=320, height=240)
    video = tmp_path / "clip.avi"
    _write_video(video, [scene.frame(k).rgb for k in range(40)], fps=25.0)
    out = tmp_path / "run"
    rc = cli.main(["process", str(video), "--out", str(out), "--quiet", "--no-video"])
    summary = json.loads((out / "summary.json").read_text())
    assert rc == 0, summary
    assert summary["detection_source"] == "background" and summary["frames"] == 40
    # ... and tracked with the tracker parameters chosen for that detector's boxes
    assert summary["tracker_profile"] == "background"
    assert summary["detections"] > 0
    assert len(_messages(out / "input_bag", "/image_raw")) == 40
    # the same output folder again: refused, nothing overwritten
    assert cli.main(["process", str(video), "--out", str(out), "--quiet", "--no-video"]) != 0
