"""Person size per image row and the split of a group's mask (mk_tracker.detection.person_size),
shared by the background-subtraction and thermal detectors (issues #13, #15)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mk_tracker.detection.person_size import (PersonHeightModel, is_person_shaped,
                                              people_in_width, projection_cuts, split_columns)


def test_person_shape_is_an_upright_box_near_the_aspect():
    assert is_person_shaped(20, 50, 0.4)
    assert not is_person_shaped(45, 50, 0.4)          # two side by side
    assert not is_person_shaped(5, 50, 0.4)           # a fragment
    assert is_person_shaped(0.6 * 0.4 * 50, 50, 0.4) and is_person_shaped(30, 50, 0.4)


def test_people_in_width_counts_only_past_the_split_ratio():
    assert people_in_width(30, 20, 1.6) == 1
    assert people_in_width(32, 20, 1.6) == 1
    assert people_in_width(33, 20, 1.6) == 2          # past 1.6 widths, rounds to 2
    assert people_in_width(61, 20, 1.6) == 3
    assert people_in_width(100, 0.0, 1.6) == 1        # no size known


def test_cuts_fall_in_the_gaps_of_the_projection():
    # three blobs with gaps at columns 9 and 21 (not at the even positions 10 and 20)
    columns = np.array([5] * 9 + [0] + [5] * 11 + [0] + [5] * 8, dtype=float)
    assert projection_cuts(columns, 3) == [9, 21]
    # without gaps: the even positions
    assert projection_cuts(np.ones(30), 3) == [10, 20]


def test_split_columns_gives_the_parts_of_two_people_side_by_side():
    mask = np.zeros((40, 34), bool)
    mask[:, 0:15] = True
    mask[5:, 18:34] = True
    # the gap is columns 15-17; among the empty columns the one nearest the middle (17)
    assert split_columns(mask, 2) == [(0, 17), (17, 34)]
    # a part with no mask pixel is left out
    assert split_columns(np.pad(mask[:, :15], ((0, 0), (0, 15))), 2) == [(0, 15)]


def test_height_model_learns_a_line_and_forgets():
    model = PersonHeightModel(memory=1e9)
    assert model.height_at(100) is None
    for y in (100.0, 150.0, 200.0, 250.0):
        model.add(y, 0.4 * y)
    assert model.height_at(300.0) == pytest.approx(120.0)


def _walkers(n_frames, people, shape=(200, 320)):
    """mono8 frames of warm 16x40 people (a 16x30 body under an 8x10 head) walking right
    2 px/frame on a textured background; ``people`` = list of (x0, y0) start corners."""
    rng = np.random.default_rng(3)
    base = rng.integers(40, 60, shape).astype(np.uint8)
    frames = []
    for i in range(n_frames):
        f = base.copy()
        for x0, y0 in people:
            x = x0 + 2 * i
            f[y0 + 10:y0 + 40, x:x + 16] = 200          # body
            f[y0:y0 + 10, x + 4:x + 12] = 200           # head
        frames.append(f)
    return frames


@pytest.mark.parametrize("split", [False, True])
def test_thermal_detector_splits_two_people_side_by_side_by_the_learnt_width(split):
    from mk_tracker.detection.thermal_detector import ThermalDetector, ThermalDetectorConfig

    config = dataclasses.replace(ThermalDetectorConfig(), split_by_person_size=split,
                                 person_aspect=0.4, split_ratio=1.5, reconfigure_period=5)
    # two isolated people (size samples), and a pair that touches (one 32 x 40 footprint)
    people = [(10, 20), (10, 120), (150, 70), (166, 70)]
    det = ThermalDetector(config)
    counts = []
    for i, f in enumerate(_walkers(40, people)):
        out = det.process(f, i * 0.04, "mono8")
        if det.last_mode == "reconfiguration":
            counts.append(len(out))
            last_full, x_shift = out, 2 * i
    assert len(counts) >= 5, "the premise: full-frame passes ran"
    pair = [d for d in last_full if 150 <= d.centroid[0] - x_shift <= 200]
    if split:
        assert counts[-1] == 4 and len(pair) == 2
        assert det.heights.height_at(110.0) == pytest.approx(40.0, abs=2.0)
        widths = sorted(d.box[2] for d in pair)
        assert widths[0] >= 12 and widths[1] <= 20
    else:
        assert counts[-1] == 3 and len(pair) == 1      # the pair is one detection


def test_split_takes_one_person_fewer_while_a_part_is_no_person():
    mask = np.zeros((40, 30), bool)
    mask[:, 0:4] = True            # an arm
    mask[:, 6:30] = True           # one person
    assert split_columns(mask, 2) == [(0, 15), (15, 30)]       # no test: cut anywhere
    assert split_columns(mask, 2, min_width=16) == [(0, 30)]    # a part narrower
    # three people where the region is only wide enough for two people
    wide = np.zeros((40, 62), bool)
    wide[:, 0:20] = True
    wide[:, 22:40] = True
    wide[:, 42:62] = True
    assert len(split_columns(wide, 3, min_width=15)) == 3
    assert len(split_columns(wide, 4, min_width=16)) == 3


def test_a_group_cut_off_by_the_image_bottom_is_not_split():
    """Its feet are outside the image, so the row its size would be read at is unknown."""
    from mk_tracker.detection.thermal_detector import ThermalDetector, ThermalDetectorConfig

    config = dataclasses.replace(ThermalDetectorConfig(), split_by_person_size=True,
                                 person_aspect=0.4, split_ratio=1.5, reconfigure_period=5)
    det = ThermalDetector(config)
    for i, f in enumerate(_walkers(40, [(10, 20), (10, 120), (150, 165), (166, 165)])):
        out = det.process(f, i * 0.04, "mono8")     # the pair (rows 165-205) is cut at 200
        if det.last_mode == "reconfiguration":
            last_full = out
    assert det.heights.samples > 3                          # sizes were learnt
    assert len(last_full) == 3                              # the pair stays one detection
