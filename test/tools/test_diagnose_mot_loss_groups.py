"""benchmarks/diagnose_mot_loss.py on a bench_groups scene (``groups-PEOPLE-SEED-WxH``): the
detector's thermal boxes reach the tracker and the scoring in RGB pixels."""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import diagnose_mot_loss as dml  # noqa: E402

from mk_tracker.boxes import iou  # noqa: E402
from mk_tracker.synthetic import scene_bag  # noqa: E402


def test_a_lone_walkers_detections_land_on_the_rgb_ground_truth():
    frames, fps = dml.groups_frames("groups-1-5-320x240", {}, frames=40)
    assert len(frames) == 40 and fps > 0
    ious = []
    for image, _stamp, dets, gt in frames:
        assert image.shape[:2] == (240, 320)
        if len(dets) == 1 and len(gt) == 1:
            ious.append(iou(dets[0][:4], gt[0].box))
    assert len(ious) >= 20                 # detected once the detector has warmed up
    assert np.median(ious) >= 0.5          # on the person in the scored image


def test_the_detections_go_through_the_scenes_homography(monkeypatch):
    """The crowd preset's homography is the identity; with a 12 px shift put in its place
    (thermal images unchanged) every detection moves 12 px right, as the tracker would move
    a thermal-plane box (``prepare_detections``)."""
    plain, _ = dml.groups_frames("groups-1-5-320x240", {}, frames=30)
    real = scene_bag.build_preset

    def shifted(*args, **kwargs):
        scene = real(*args, **kwargs)
        scene.homography = np.array([[1.0, 0.0, 12.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
        return scene
    monkeypatch.setattr(scene_bag, "build_preset", shifted)
    moved, _ = dml.groups_frames("groups-1-5-320x240", {}, frames=30)
    compared = 0
    for (_, _, a, _), (_, _, b, _) in zip(plain, moved):
        assert len(a) == len(b)
        for da, db in zip(a, b):
            if da[0] + da[2] + 12.0 < 320.0:          # not clipped at the right border
                assert db[0] == pytest.approx(da[0] + 12.0)
                assert db[1:] == pytest.approx(da[1:])
                compared += 1
    assert compared >= 10


def test_a_malformed_scene_name_is_refused():
    with pytest.raises(SystemExit, match="groups-PEOPLE-SEED-WxH"):
        dml.groups_frames("groups-8-101", {})
