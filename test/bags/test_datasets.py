"""MOTChallenge / OTB readers and the `mk_tracker import` command."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from mk_tracker.tools import cli
from mk_tracker.bags.bag_io import open_bag
from mk_tracker.bags.datasets import (DatasetError, read_mot_sequence, read_otb_sequence,
                                 read_sequence, subsampled)
from mk_tracker.messages.detection_messages import read_detection_array
from mk_tracker.messages.image_conversion import image_to_numpy
from mk_tracker.messages.message_types import stamp_to_nanoseconds


def picture(k: int) -> np.ndarray:
    img = np.zeros((24, 32, 3), np.uint8)
    img[k, :, 2] = 200
    img[..., 0] = 10 * k
    return img


def make_mot(root: Path, n: int = 3, gt: str | None = None, det: str | None = None,
             seqinfo: str | None = None) -> Path:
    (root / "img1").mkdir(parents=True)
    (root / "gt").mkdir()
    for k in range(n):
        cv2.imwrite(str(root / "img1" / f"{k + 1:06d}.png"), picture(k))
    (root / "gt" / "gt.txt").write_text(gt if gt is not None else
                                        "1,1,11,21,5,10,-1\n1,2,1,1,4,4,-1\n3,1,13,22,5,10,-1\n")
    if det is not None:
        (root / "det").mkdir()
        (root / "det" / "det.txt").write_text(det)
    if seqinfo is not None:
        (root / "seqinfo.ini").write_text(seqinfo)
    return root


def make_otb(root: Path, lines: str, n: int = 3) -> Path:
    (root / "img").mkdir(parents=True)
    for k in range(n):
        cv2.imwrite(str(root / "img" / f"{k + 1:04d}.png"), picture(k))
    (root / "groundtruth_rect.txt").write_text(lines)
    return root


def test_mot_reader(tmp_path):
    root = make_mot(tmp_path / "seq", det="2,-1,3.5,4.5,6,8,51.818\n2,-1,1,1,2,2,-3\n")
    seq = read_mot_sequence(root)
    assert len(seq) == 3 and seq.frame_rate == 25.0 and seq.layout == "mot"
    # boxes exactly as in the file (no 1-pixel shift; see mk_tracker.bags.datasets)
    assert seq.ground_truth[0] == {1: (11.0, 21.0, 5.0, 10.0), 2: (1.0, 1.0, 4.0, 4.0)}
    assert seq.ground_truth[1] == {}
    assert seq.track(1) == {0: (11.0, 21.0, 5.0, 10.0), 2: (13.0, 22.0, 5.0, 10.0)}
    assert seq.identities == [1, 2] and seq.ground_truth_count == 3
    assert [len(d) for d in seq.detections] == [0, 2, 0]
    first = seq.detections[1][0]
    assert first.box == (3.5, 4.5, 6.0, 8.0) and first.score == 51.818 and first.id == ""
    np.testing.assert_array_equal(seq.image(2), picture(2))
    assert seq.timestamp_ns(2) == 80_000_000


def test_subsampled_keeps_every_step_th_frame_with_its_annotations(tmp_path):
    gt = "".join(f"{f},1,{10 + f},20,5,10,-1\n" for f in range(1, 8)) + "4,2,1,1,4,4,-1\n"
    det = "".join(f"{f},-1,{10 + f},20,5,10,0.{f}\n" for f in (2, 6, 7))
    seq = read_mot_sequence(make_mot(tmp_path / "seq", n=7, gt=gt, det=det,
                                     seqinfo="[Sequence]\nframeRate=20\nseqLength=7\n"))
    low = subsampled(seq, 3, 1)                  # 0-based frames 1, 4 (file frames 2, 5)
    assert len(low) == 2 and low.frame_rate == pytest.approx(20.0 / 3)
    assert [p.name for p in low.image_paths] == ["000002.png", "000005.png"]
    assert low.ground_truth == ({1: (12.0, 20.0, 5.0, 10.0)}, {1: (15.0, 20.0, 5.0, 10.0)})
    assert [[d.score for d in frame] for frame in low.detections] == [[0.2], []]
    np.testing.assert_array_equal(low.image(1), picture(4))
    assert low.timestamp_ns(1) == 150_000_000   # stamps at the lower rate
    assert low.info["framerate"] == "6.66667" and low.info["seqlength"] == "2"
    # offset 0 keeps file frames 1, 4, 7; identity 2 lives on file frame 4 only
    assert subsampled(seq, 3).identities == [1, 2]
    assert len(subsampled(seq, 3)) == 3 and len(subsampled(seq, 3, 2)) == 2
    assert subsampled(seq, 1) is seq
    assert subsampled(read_otb_sequence(make_otb(tmp_path / "otb", "1,1,2,2\n" * 3)),
                      2).detections is None


@pytest.mark.parametrize("step, offset", [(0, 0), (-2, 0), (2.0, 0), (True, 0), (3, 3),
                                          (3, -1), (2, 0.5), (9, 8)])
def test_subsampled_refuses_bad_steps(tmp_path, step, offset):
    seq = read_mot_sequence(make_mot(tmp_path / "seq"))
    with pytest.raises(DatasetError, match="step|offset|no frame"):
        subsampled(seq, step, offset)


def test_mot_seqinfo_and_ignore_rows(tmp_path):
    gt = ("1,1,1,1,4,4,1,1,1.0\n"     # pedestrian
          "1,2,1,1,4,4,0,1,1.0\n"     # ignore flag
          "2,3,1,1,4,4,1,7,1.0\n")    # class 7 (not a pedestrian)
    info = "[Sequence]\nname=Synth\nimDir=img1\nframeRate=14\nseqLength=3\nimExt=.png\n" \
           "imWidth=32\nimHeight=24\n"
    seq = read_mot_sequence(make_mot(tmp_path / "a", gt=gt, seqinfo=info))
    assert seq.name == "Synth" and seq.frame_rate == 14.0 and seq.image_size == (32, 24)
    assert seq.ground_truth_count == 1 and seq.detections is None
    assert read_mot_sequence(tmp_path / "a", frame_rate=5).frame_rate == 5.0
    bad = info.replace("seqLength=3", "seqLength=4")
    with pytest.raises(DatasetError, match="seqLength 4 but 3 images"):
        read_mot_sequence(make_mot(tmp_path / "b", seqinfo=bad))


@pytest.mark.parametrize("gt, words", [
    ("1,1,1,1,4\n", r"gt.txt:1: expected at least 6 values"),
    ("1,1,1,1,4,4,-1\n4,1,1,1,4,4,-1\n", r"gt.txt:2: frame 4 outside 1..3"),
    ("1,1,1,1,4,x,-1\n", r"gt.txt:1: not a number"),
    ("1,1,1,1,0,4,-1\n", r"gt.txt:1: invalid box"),
    ("1,1,1,1,4,4,-1\n1,1,2,2,4,4,-1\n", r"identity 1 appears twice"),
    ("1,1.5,1,1,4,4,-1\n", r"not an integer"),
])
def test_mot_malformed_ground_truth(tmp_path, gt, words):
    with pytest.raises(DatasetError, match=words):
        read_mot_sequence(make_mot(tmp_path / "seq", gt=gt))


def test_mot_missing_pieces(tmp_path):
    root = make_mot(tmp_path / "seq")
    (root / "img1" / "000002.png").unlink()
    with pytest.raises(DatasetError, match="missing frame numbers \\[2\\]"):
        read_mot_sequence(root)
    root = make_mot(tmp_path / "seq2")
    (root / "gt" / "gt.txt").unlink()
    with pytest.raises(DatasetError, match="gt.txt: ground truth file is missing"):
        read_mot_sequence(root)
    root = make_mot(tmp_path / "seq3")
    (root / "img1" / "000003.png").write_bytes(b"not a png")
    seq = read_mot_sequence(root)
    with pytest.raises(DatasetError, match="000003.png: cannot decode"):
        seq.image(2)
    with pytest.raises(DatasetError, match="outside"):
        seq.image(3)
    with pytest.raises(DatasetError, match="not a directory"):
        read_mot_sequence(tmp_path / "nothing")
    with pytest.raises(DatasetError, match="neither"):
        read_sequence(tmp_path)


@pytest.mark.parametrize("text", ["11,21,5,10\n12,22,5,10\n13,23,5,10\n",
                                  "11\t21\t5\t10\n12 22 5 10\n13 ,23, 5,10\n"])
def test_otb_reader_accepts_both_separators(tmp_path, text):
    seq = read_otb_sequence(make_otb(tmp_path / "Walk", text))
    assert seq.name == "Walk" and seq.layout == "otb" and len(seq) == 3
    assert [f[1] for f in seq.ground_truth] == [(11.0, 21.0, 5.0, 10.0),
                                                (12.0, 22.0, 5.0, 10.0),
                                                (13.0, 23.0, 5.0, 10.0)]
    assert seq.detections is None


def test_otb_absent_target_and_errors(tmp_path):
    seq = read_otb_sequence(make_otb(tmp_path / "a", "1 1 4 4\n0 0 0 0\nNaN NaN NaN NaN\n"))
    assert [len(f) for f in seq.ground_truth] == [1, 0, 0]
    with pytest.raises(DatasetError, match=r"groundtruth_rect.txt:2: not a number"):
        read_otb_sequence(make_otb(tmp_path / "b", "1 1 4 4\n1 1 four 4\n1 1 4 4\n"))
    with pytest.raises(DatasetError, match=r"groundtruth_rect.txt:1: expected at least 4"):
        read_otb_sequence(make_otb(tmp_path / "c", "1 1 4\n1 1 4 4\n1 1 4 4\n"))
    with pytest.raises(DatasetError, match="2 boxes for 3 images"):
        read_otb_sequence(make_otb(tmp_path / "d", "1 1 4 4\n1 1 4 4\n"))
    with pytest.raises(DatasetError, match="expected 4 values"):
        read_otb_sequence(make_otb(tmp_path / "e", "1 1 4 4 9\n1 1 4 4\n1 1 4 4\n"))


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_import_command_writes_images_truth_and_detections(tmp_path, storage, capsys):
    root = make_mot(tmp_path / "seq", det="2,-1,3.5,4.5,6,8,51.818\n")
    out = tmp_path / "bag"
    assert cli.main(["import", str(root), "--out", str(out), "--fps", "10",
                     "--storage", storage]) == 0
    assert "3/3 frames" in capsys.readouterr().err
    with open_bag(out) as bag:
        assert {t: i.count for t, i in bag.topics.items()} == {
            "/image_raw": 3, "/ground_truth": 3, "/detections": 3}
        images = [msg for _, msg in bag.read_messages(["/image_raw"])]
        truth = [read_detection_array(msg) for _, msg in bag.read_messages(["/ground_truth"])]
        dets = [read_detection_array(msg) for _, msg in bag.read_messages(["/detections"])]
        stamps = [m.timestamp_ns for m in bag.messages(["/image_raw"])]
    assert stamps == [0, 100_000_000, 200_000_000]
    for k, msg in enumerate(images):
        assert msg.encoding == "bgr8" and msg.header.frame_id == "camera"
        assert stamp_to_nanoseconds(msg.header.stamp) == stamps[k]
        np.testing.assert_array_equal(image_to_numpy(msg), picture(k))
    assert [(d.id, d.box, d.score) for d in truth[0]] == [("1", (11.0, 21.0, 5.0, 10.0), 1.0),
                                                          ("2", (1.0, 1.0, 4.0, 4.0), 1.0)]
    assert truth[1] == []
    assert [(d.id, d.score) for d in dets[1]] == [("", 51.818)] and dets[0] == []


def test_import_command_errors(tmp_path, capsys):
    out = tmp_path / "bag"
    assert cli.main(["import", str(tmp_path / "missing"), "--out", str(out)]) == 1
    assert "not a directory" in capsys.readouterr().err
    root = make_mot(tmp_path / "seq")
    out.mkdir()
    assert cli.main(["import", str(root), "--out", str(out)]) == 1
    assert "exists already" in capsys.readouterr().err
    (root / "img1" / "000002.png").write_bytes(b"garbage")
    out2 = tmp_path / "bag2"
    assert cli.main(["import", str(root), "--out", str(out2), "--quiet"]) == 1
    assert "000002.png: cannot decode" in capsys.readouterr().err
    assert not out2.exists()  # no half-written bag left behind


# --- real data (numbers from /work/shared/data/README.md and `wc -l` of the files) -------

def test_tud_campus(shared_data):
    folder = shared_data / "mot" / "TUD-Campus"
    if not folder.is_dir():
        pytest.skip(f"{folder} absent")
    seq = read_sequence(folder)
    assert seq.layout == "mot" and len(seq) == 71
    assert len(seq.identities) == 8 and seq.ground_truth_count == 359
    assert sum(len(d) for d in seq.detections) == 344  # lines of det/det.txt
    assert seq.ground_truth[0][1] == (399.0, 182.0, 121.0, 229.0)  # "1,1,399,182,121,229"
    assert seq.image(70).shape == (480, 640, 3)


def test_otb_crossing_import(shared_data, tmp_path):
    folder = shared_data / "otb" / "Crossing"
    if not folder.is_dir():
        pytest.skip(f"{folder} absent")
    seq = read_sequence(folder)
    assert seq.layout == "otb" and len(seq) == 120 and seq.ground_truth_count == 120
    assert seq.ground_truth[0][1] == (205.0, 151.0, 17.0, 50.0)  # "205 151 17 50"
    out = tmp_path / "crossing"
    assert cli.main(["import", str(folder), "--out", str(out), "--quiet"]) == 0
    with open_bag(out) as bag:
        assert {t: i.count for t, i in bag.topics.items()} == {"/image_raw": 120,
                                                              "/ground_truth": 120}
        last = None
        for raw, msg in bag.read_messages(["/image_raw"]):
            last = image_to_numpy(msg)
    assert last.shape == (240, 360, 3)


def test_dataset_readers_and_scoring_read_the_same_rows(tmp_path):
    """One parser: the rows a MOT folder's ground truth holds for the dataset reader are the
    rows evaluation.read_mot_file reads from the same file (ignore rows and other classes
    dropped by both), and the OTB boxes are read_box_list's."""
    from mk_tracker.evaluation.metrics import EvaluationError, read_box_list, read_mot_file
    gt = ("# comment line\n"
          "1,1,1,1,4,4,1,1,1.0\n"
          "1,2,2,2,4,4,0,1,1.0\n"      # ignore flag
          "2,3,1,1,4,4,1,7,1.0\n"      # not a pedestrian
          "3 4 5.5 6.5 7 8 1 1 0.5\n")
    root = make_mot(tmp_path / "seq", gt=gt, det="3,-1,1,2,3,4,0.25\n")
    seq = read_mot_sequence(root)
    rows = read_mot_file(root / "gt" / "gt.txt", ground_truth=True)
    assert [(r.frame, r.id, r.box, r.line) for r in rows] == [
        (1, 1, (1.0, 1.0, 4.0, 4.0), 2), (3, 4, (5.5, 6.5, 7.0, 8.0), 5)]
    assert [{i: b for i, b in f.items()} for f in seq.ground_truth] == [
        {1: (1.0, 1.0, 4.0, 4.0)}, {}, {4: (5.5, 6.5, 7.0, 8.0)}]
    (det,) = read_mot_file(root / "det" / "det.txt", require_score=True)
    assert seq.detections[2][0].box == det.box == (1.0, 2.0, 3.0, 4.0)
    assert seq.detections[2][0].score == det.score == 0.25
    # a det.txt score that is not finite is an error in both
    (root / "det" / "det.txt").write_text("3,-1,1,2,3,4,nan\n")
    with pytest.raises(DatasetError, match=r"det.txt:1: score nan is not finite"):
        read_mot_sequence(root)
    with pytest.raises(EvaluationError, match=r"det.txt:1: score nan is not finite"):
        read_mot_file(root / "det" / "det.txt", require_score=True)
    otb = make_otb(tmp_path / "o", "1,1,4,4\nnan nan nan nan\n2\t2\t5\t5\n")
    assert [f.get(1) for f in read_otb_sequence(otb).ground_truth] == \
        read_box_list(otb / "groundtruth_rect.txt") == [(1.0, 1.0, 4.0, 4.0), None,
                                                        (2.0, 2.0, 5.0, 5.0)]
    # a binary file is our error in both, not a UnicodeDecodeError
    (otb / "groundtruth_rect.txt").write_bytes(b"\xff\xfe\x00\x81")
    with pytest.raises(DatasetError, match="not a text file"):
        read_otb_sequence(otb)
    with pytest.raises(EvaluationError, match="not a text file"):
        read_box_list(otb / "groundtruth_rect.txt")
