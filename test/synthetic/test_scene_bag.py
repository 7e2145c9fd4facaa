"""Round trip of a synthetic scene through a rosbag2 bag and the ``mk_tracker generate`` command."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mk_tracker.bags.bag_io import open_bag
from mk_tracker.boxes import transform_box
from mk_tracker.tools.cli import main
from mk_tracker.messages.detection_messages import read_detection_array
from mk_tracker.messages.image_conversion import image_to_numpy
from mk_tracker.messages.message_types import stamp_to_nanoseconds
from mk_tracker.synthetic.scene_bag import (SceneBagError, build_preset, ground_truth_detections,
                                  read_scene_info, write_scene_bag)
from mk_tracker.synthetic.presets import cross_modal_scene, crowd_scene, enter_leave_scene


def read_all(path):
    out: dict[str, list] = {}
    with open_bag(path) as bag:
        for raw, msg in bag.read_messages():
            out.setdefault(raw.topic, []).append((raw.timestamp_ns, msg))
    return out


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_round_trip_reproduces_images_ground_truth_and_stamps(tmp_path, storage):
    scene = crowd_scene(4, seed=9, width=320, height=240, frames=6,
                        thermal_encoding="mono16")
    counts = write_scene_bag(scene, tmp_path / "bag", storage=storage, preset="crowd")
    assert counts == {"/scene_info": 1, "/image_raw": 6, "/thermal/image_raw": 6,
                      "/ground_truth": 6, "/thermal/ground_truth": 6}
    topics = read_all(tmp_path / "bag")
    for i in range(6):
        frame = scene.frame(i)
        ns = round(i / 25.0 * 1e9)
        t_rgb, rgb = topics["/image_raw"][i]
        t_th, th = topics["/thermal/image_raw"][i]
        assert t_rgb == t_th == ns == stamp_to_nanoseconds(rgb.header.stamp)
        assert rgb.encoding == "bgr8" and rgb.header.frame_id == "camera"
        assert th.encoding == "mono16" and th.header.frame_id == "thermal_camera"
        assert np.array_equal(image_to_numpy(rgb), frame.rgb)
        assert np.array_equal(image_to_numpy(th), frame.thermal)
        _, gt = topics["/ground_truth"][i]
        _, gt_th = topics["/thermal/ground_truth"][i]
        assert gt.header.frame_id == "camera" and gt_th.header.frame_id == "thermal_camera"
        dets = {d.id: d for d in read_detection_array(gt)}
        dets_th = {d.id: d for d in read_detection_array(gt_th)}
        visible = {str(o.id): o for o in frame.objects if o.visible_fraction > 0}
        assert set(dets) == set(visible) == set(dets_th)
        for key, obj in visible.items():
            assert dets[key].score == pytest.approx(obj.visible_fraction)
            assert dets[key].class_id == "person"
            x, y, w, h = dets[key].box
            assert x >= 0 and y >= 0 and x + w <= 320 + 1e-9 and y + h <= 240 + 1e-9
            if 0 <= obj.box_rgb[0] and obj.box_rgb[0] + obj.box_rgb[2] <= 320 and \
                    0 <= obj.box_rgb[1] and obj.box_rgb[1] + obj.box_rgb[3] <= 240:
                assert np.allclose(dets[key].box, obj.box_rgb, atol=1e-6)
    (t_info, info_msg), = topics["/scene_info"]
    assert t_info == 0
    info = json.loads(info_msg.data)
    assert info["seed"] == 9 and info["preset"] == "crowd"
    assert info["rgb_size"] == [320, 240] and info["thermal_encoding"] == "mono16"
    assert len(info["config"]["people"]) == 4


def test_scene_info_carries_the_homography_that_maps_thermal_boxes(tmp_path):
    scene = cross_modal_scene(seed=3, frames=4)
    write_scene_bag(scene, tmp_path / "bag")
    info = read_scene_info(tmp_path / "bag")
    H = np.array(info["homography"])
    assert info["thermal_size"] == [320, 240] and info["rgb_size"] == [640, 480]
    assert not np.allclose(H, np.eye(3))
    topics = read_all(tmp_path / "bag")
    _, gt = topics["/ground_truth"][2]
    _, gt_th = topics["/thermal/ground_truth"][2]
    rgb_boxes = {d.id: d.box for d in read_detection_array(gt)}
    assert len(rgb_boxes) == 2
    for d in read_detection_array(gt_th):
        assert np.allclose(transform_box(d.box, H), rgb_boxes[d.id], atol=1e-6)
    thermal = image_to_numpy(topics["/thermal/image_raw"][0][1])
    assert thermal.shape == (240, 320)


def test_people_outside_the_image_are_not_written():
    scene = enter_leave_scene(seed=0, frames=150)
    for plane in ("rgb", "thermal"):
        first = ground_truth_detections(scene, scene.frame(0), plane)
        last = ground_truth_detections(scene, scene.frame(149), plane)
        assert [d.id for d in first] == ["2"] and [d.id for d in last] == ["1"]
        assert first[0].score == 1.0
    with pytest.raises(SceneBagError):
        ground_truth_detections(scene, scene.frame(0), "depth")


def test_generate_command_writes_a_bag(tmp_path, capsys):
    out = tmp_path / "crowd"
    rc = main(["generate", "--preset", "crowd", "--people", "3", "--frames", "4", "--seed",
               "1", "--width", "160", "--height", "120", "--thermal-encoding", "32FC1",
               "--missing-pixels", "0.1", "--out", str(out)])
    assert rc == 0
    assert "4 frames" in capsys.readouterr().out
    info = read_scene_info(out)
    assert info["seed"] == 1 and len(info["config"]["people"]) == 3
    assert info["config"]["missing_pixel_fraction"] == 0.1
    topics = read_all(out)
    thermal = image_to_numpy(topics["/thermal/image_raw"][1][1])
    assert thermal.dtype == np.float32
    assert np.isnan(thermal).mean() == pytest.approx(0.1, abs=0.02)
    # same seed, same command -> identical bag content
    again = tmp_path / "again"
    assert main(["generate", "--preset", "crowd", "--people", "3", "--frames", "4", "--seed",
                 "1", "--width", "160", "--height", "120", "--thermal-encoding", "32FC1",
                 "--missing-pixels", "0.1", "--out", str(again)]) == 0
    rgb_a = image_to_numpy(topics["/image_raw"][3][1])
    rgb_b = image_to_numpy(read_all(again)["/image_raw"][3][1])
    assert np.array_equal(rgb_a, rgb_b)


def test_bad_arguments_give_clear_errors(tmp_path, capsys):
    scene = crowd_scene(1, seed=0, width=64, height=48, frames=1)
    write_scene_bag(scene, tmp_path / "bag")
    with pytest.raises(SceneBagError, match="exists"):
        write_scene_bag(scene, tmp_path / "bag")
    with pytest.raises(SceneBagError):
        write_scene_bag("not a scene", tmp_path / "other")
    with pytest.raises(SceneBagError, match="does not take --people"):
        build_preset("paper", people=3)
    with pytest.raises(SceneBagError, match="unknown preset"):
        build_preset("nope")
    assert main(["generate", "--preset", "paper", "--people", "3", "--out",
                 str(tmp_path / "p")]) == 2
    assert "does not take --people" in capsys.readouterr().err
    assert main(["generate", "--preset", "crowd", "--frames", "0", "--out",
                 str(tmp_path / "z")]) == 2
    assert not (tmp_path / "z").exists()
