"""The ground-truth convention of bench_multi_object.py's generated sequences
(``--gt-min-visible``): which people of a generated scene enter the ground truth."""

import argparse
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import bench_multi_object as bench  # noqa: E402
from mk_tracker.synthetic.presets import occlusion_scene  # noqa: E402


def _gt_frames(scene, *gt_min_visible):
    """Frame numbers (1-based) in which person 1 is in the ground truth."""
    frames, _ = bench.scene_frames(scene, 1, 0.5, 0.0, 0.0, 0.0, *gt_min_visible)
    return {row.frame for _, _, _, gt in frames for row in gt if row.id == 1}


def _visible(scene):
    """(frame number, visible_fraction) of person 1 in the frames it is in the RGB image."""
    out = []
    for k in range(len(scene)):
        (o,) = [o for o in scene.ground_truth(k) if o.id == 1]
        if o.in_frame_rgb:
            out.append((k + 1, o.visible_fraction))
    return out


def test_by_default_a_fully_hidden_person_in_the_frame_counts_as_in_the_real_clips():
    scene = occlusion_scene(seed=0, hidden_frames=12, full=True, frames=60)
    visible = _visible(scene)
    hidden = {k for k, v in visible if v == 0.0}
    assert len(hidden) >= 8                          # the pillar hides the whole body
    assert _gt_frames(scene) == {k for k, _ in visible}
    assert _gt_frames(scene, 0.0) == _gt_frames(scene)
    # the convention before: any visible pixel
    assert _gt_frames(scene, 1e-6) == {k for k, v in visible if v > 0.0}
    assert not hidden & _gt_frames(scene, 1e-6)


def test_a_person_below_the_level_is_left_out():
    scene = occlusion_scene(seed=0, hidden_frames=12, full=False, frames=60)
    visible = _visible(scene)
    below = {k for k, v in visible if v < 0.7}
    assert below and all(v > 0.3 for _, v in visible)   # the wall hides the legs only
    kept = _gt_frames(scene, 0.7)
    assert kept == {k for k, v in visible if v >= 0.7}
    assert not below & kept
    assert below <= _gt_frames(scene)                # the default keeps them


def test_the_convention_is_stated_and_its_level_checked():
    assert "hidden or not" in bench.gt_convention(0.0)
    assert "visible_fraction >= 0.5" in bench.gt_convention(0.5)
    assert bench.GT_MIN_VISIBLE == 0.0
    assert bench._fraction("0.25") == 0.25
    for bad in ("1.5", "-0.1", "half"):
        with pytest.raises(argparse.ArgumentTypeError):
            bench._fraction(bad)


def test_a_joint_grid_dimension_varies_its_parameters_together():
    value = bench.grid_value("0.1&0.03")
    assert value == (0.1, 0.03)
    assert bench.grid_value("0.2") == 0.2
    key = "lifecycle.min_noise_px&lifecycle.measurement_noise"
    settings = bench.grid_settings({key: ((0.0, 0.02), value), "lifecycle.min_hits": (2, 3)})
    assert len(settings) == 4                       # two values of the joint dimension x 2
    assert bench.expanded(settings[-1]) == {"lifecycle.min_noise_px": 0.1,
                                            "lifecycle.measurement_noise": 0.03,
                                            "lifecycle.min_hits": 3}
    from mk_tracker.tracking.multi_object_tracker import MultiObjectTrackerConfig
    assert bench.default_value(MultiObjectTrackerConfig(), key) == (1.0, 0.02)
