"""Person size per image row and the split of a group's mask (mk_tracker.detection.person_size),
shared by the background-subtraction and thermal detectors (issues #13, #15)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mk_tracker.detection.person_size import (PersonHeightModel, is_person_shaped,
                                              parts_are_people, people_in_width,
                                              projection_cuts, split_columns,
                                              valley_columns)
from mk_tracker.parameters import updated


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


def test_height_model_keeps_the_range_of_its_sample_rows():
    model = PersonHeightModel(memory=1e9)
    assert model.rows is None
    for y in (250.0, 200.0, 300.0):
        model.add(y, 0.5 * y)
    assert model.rows == (200.0, 300.0)
    # the line extrapolates beyond it: a head's bottom edge above every feet row reads as
    # "a 25 px person" (docs/benchmark_background_detector.md, size_clamp_rows)
    assert model.height_at(50.0) == pytest.approx(25.0)


@pytest.mark.parametrize("rows, heights, tolerance, level", [
    ((100, 150, 200, 250), (80, 80, 80, 80), 0.1, True),      # one height over 150 rows
    ((100, 150, 200, 250), (80, 84, 78, 82), 0.1, True),      # scatter of a few per cent
    ((100, 150, 200, 250), (80, 80, 80, 80), 0.0, False),     # tolerance 0: off
    ((100, 120, 140, 160), (80, 80, 80, 80), 0.1, False),     # 60 rows < one height (80)
    ((100, 150, 200, 250), (40, 60, 80, 100), 0.1, False),    # heights follow the row
    ((100, 150, 200, 250), (60, 100, 100, 60), 0.1, False),   # no slope, scattered by 1/4
    ((100, 250), (80, 80), 0.1, False),                       # fewer than about 3 samples
])
def test_one_height_for_every_row_is_told_from_a_ground_plane_and_from_scatter(
        rows, heights, tolerance, level):
    model = PersonHeightModel(memory=1e9)
    for y, h in zip(rows, heights):
        model.add(float(y), float(h))
    assert model.is_level(tolerance) is level


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


def _split_alone(config):
    """``config`` without the person cover: these scenes test the split by the learnt width
    alone, and every person in them is 40 px tall over ~100 rows, one height for every row,
    so the cover's level form would cut the same groups (test_person_cover.py)."""
    return updated(config, {"person_cover.enabled": False})


@pytest.mark.parametrize("split", [False, True])
def test_thermal_detector_splits_two_people_side_by_side_by_the_learnt_width(split):
    from mk_tracker.detection.thermal_detector import ThermalDetector, ThermalDetectorConfig

    config = dataclasses.replace(ThermalDetectorConfig(), split_by_person_size=split,
                                 person_aspect=0.4, split_ratio=1.5, reconfigure_period=5)
    config = _split_alone(config)
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
    det = ThermalDetector(_split_alone(config))
    for i, f in enumerate(_walkers(40, [(10, 20), (10, 120), (150, 165), (166, 165)])):
        out = det.process(f, i * 0.04, "mono8")     # the pair (rows 165-205) is cut at 200
        if det.last_mode == "reconfiguration":
            last_full = out
    assert det.heights.samples > 3                          # sizes were learnt
    assert len(last_full) == 3                              # the pair stays one detection


def test_samples_on_an_exact_line_have_no_residual_and_the_prior_holds():
    model = PersonHeightModel(memory=1e9, max_relative_residual=0.05, min_samples=3.5)
    for y in (100.0, 150.0, 200.0):
        model.add(y, 0.4 * y)
    assert model.relative_residual() == pytest.approx(0.0, abs=1e-9)
    assert model.explained() == pytest.approx(1.0)
    assert not model.valid() and model.height_at(300.0) is None     # 3 samples < 3.5
    model.add(250.0, 100.0)
    assert model.valid() and model.height_at(300.0) == pytest.approx(120.0)


def test_half_and_whole_bodies_on_the_same_rows_refuse_the_prior():
    # at rows 100 and 200, a half body (h 20 / 40) and a whole body (h 60 / 80): the line
    # h = 0.2 y + 20 (slope from the row means 40 and 60) leaves residuals of +-20 at every
    # sample, std 20 about a mean height of 50: relative spread 0.4, R^2 = 1 - 400/500
    model = PersonHeightModel(memory=1e9, max_relative_residual=0.3, min_samples=3)
    for y, h in ((100, 20), (100, 60), (200, 40), (200, 80)):
        model.add(y, h)
    assert model.relative_residual() == pytest.approx(0.4)
    assert model.explained() == pytest.approx(0.2)
    assert not model.valid() and model.height_at(150) is None
    lenient = PersonHeightModel(memory=1e9, max_relative_residual=0.5, min_samples=3)
    for y, h in ((100, 20), (100, 60), (200, 40), (200, 80)):
        lenient.add(y, h)
    assert lenient.height_at(150) == pytest.approx(50.0)
    # no threshold (the default): the size is used as before
    plain = PersonHeightModel(memory=1e9)
    for y, h in ((100, 20), (100, 60), (200, 40), (200, 80)):
        plain.add(y, h)
    assert plain.height_at(150) == pytest.approx(50.0)


def test_forgetting_lets_the_prior_come_back_once_the_line_holds_again():
    # memory 4: every older sample's weight is multiplied by 0.75 at each new one.  Four
    # samples at one row (h 20, 20, 60, 60) have no slope: their spread about the mean
    model = PersonHeightModel(memory=4.0, max_relative_residual=0.1, min_samples=2.5)
    for h in (20, 20, 60, 60):
        model.add(100, h)
    w = [0.75 ** 3, 0.75 ** 2, 0.75, 1.0]                   # oldest first
    total = sum(w)
    mean = (20 * (w[0] + w[1]) + 60 * (w[2] + w[3])) / total
    var = (400 * (w[0] + w[1]) + 3600 * (w[2] + w[3])) / total - mean ** 2
    assert model.relative_residual() == pytest.approx(var ** 0.5 / mean)   # 0.43
    assert model.explained() == 0.0
    assert not model.valid()
    for y in range(150, 650, 25):
        model.add(float(y), 0.4 * y)
    # the one-row samples now weigh 0.75^20 (0.3 %) or less: the line explains what is left
    assert model.valid()
    assert model.height_at(700.0) == pytest.approx(280.0, rel=0.02)


@pytest.mark.parametrize("max_residual", [0.1, 100.0])
def test_the_size_split_stops_while_the_height_fit_is_refused(max_residual):
    """The scene of the split test above, after 200 earlier samples of half and whole
    bodies (h 10 and 70, mean 40) at the isolated people's rows: about 80 exact 40 px
    samples later the spread is still ~25 px over a mean of 40 (0.6), above 0.1: the size is
    refused and the pair stays one detection; without a check (100) it is split."""
    from mk_tracker.detection.thermal_detector import ThermalDetector, ThermalDetectorConfig

    config = dataclasses.replace(ThermalDetectorConfig(), split_by_person_size=True,
                                 person_aspect=0.4, split_ratio=1.5, reconfigure_period=5,
                                 size_max_residual=max_residual, size_min_samples=2.5)
    det = ThermalDetector(_split_alone(config))
    for k in range(200):
        det.heights.add(60.0 + 100.0 * (k % 2), 10.0 if k % 4 < 2 else 70.0)
    for i, f in enumerate(_walkers(40, [(10, 20), (10, 120), (150, 70), (166, 70)])):
        out = det.process(f, i * 0.04, "mono8")
        if det.last_mode == "reconfiguration":
            last = out
    spread = det.heights.relative_residual()
    assert 0.5 < spread < 0.75
    assert len(last) == {0.1: 3, 100.0: 4}[max_residual]     # the pair: one, or two


def test_parts_are_people_only_when_each_is_a_persons_height_at_its_own_row():
    flat = lambda y: 40.0                                        # noqa: E731
    assert parts_are_people([(0, 0, 16, 40), (16, 5, 16, 35)], flat, 0.8)   # 35 >= 32
    assert not parts_are_people([(0, 0, 16, 40), (16, 10, 16, 30)], flat, 0.8)  # 30 < 32
    assert parts_are_people([(0, 0, 16, 40), (16, 30, 16, 2)], flat, 0.0)   # 0: no check
    assert not parts_are_people([(0, 0, 16, 40)], lambda y: None, 0.5)      # no size known
    # the expected height is read at each part's own bottom row: h = y_bottom / 2
    rows = lambda y: y / 2.0                                     # noqa: E731
    assert parts_are_people([(0, 60, 10, 40)], rows, 0.8)         # 40 >= 0.8 * 50
    assert not parts_are_people([(0, 100, 10, 40)], rows, 0.8)    # 40 < 0.8 * 70


@pytest.mark.parametrize("fraction, expected", [(0.0, 4), (0.4, 4), (0.8, 3)])
def test_a_split_with_a_part_shorter_than_a_person_keeps_the_footprint_whole(fraction,
                                                                            expected):
    """The split scene above, but the right member of the touching pair is 20 px tall (its
    lower body only) beside a 40 px person whose feet are on the same row: the cut at
    column 16 gives parts 40 and 20 px tall, against 40 px expected at that row.  20 >=
    0.4 * 40 keeps the split (4 detections); 20 < 0.8 * 40 keeps the pair one (3)."""
    from mk_tracker.detection.thermal_detector import ThermalDetector, ThermalDetectorConfig

    config = dataclasses.replace(ThermalDetectorConfig(), split_by_person_size=True,
                                 person_aspect=0.4, split_ratio=1.5, reconfigure_period=5,
                                 min_part_height_fraction=fraction)
    det = ThermalDetector(_split_alone(config))
    rng = np.random.default_rng(0)
    base = rng.integers(40, 60, (200, 320)).astype(np.uint8)
    for i in range(40):
        f = base.copy()
        x = 2 * i
        for x0, y0 in [(10, 20), (10, 120), (150, 70)]:
            f[y0 + 10:y0 + 40, x0 + x:x0 + x + 16] = 200      # body
            f[y0:y0 + 10, x0 + x + 4:x0 + x + 12] = 200       # head
        f[90:110, 166 + x:182 + x] = 200                       # the short member, feet at 110
        out = det.process(f, i * 0.04, "mono8")
        if det.last_mode == "reconfiguration":
            last, shift = out, x
    assert det.heights.height_at(110.0) == pytest.approx(40.0, abs=2.0)
    assert len(last) == expected
    pair = [d for d in last if 150 <= d.centroid[0] - shift <= 200]
    if expected == 4:
        assert sorted(round(d.box[3]) for d in pair) == [20, 40]
    else:
        assert len(pair) == 1 and round(pair[0].box[2]) == 32 and round(pair[0].box[3]) == 40


def _two_people_in_four_parts() -> np.ndarray:
    """Labels of a footprint two people make side by side, as a valley split may give them:
    each person cut into a head part above a body part.  Person A: head 1 (rows 0-2,
    columns 1-3), body 2 (rows 3-9, columns 0-4, plus a two-pixel bridge at column 5 where
    it touches B); person B: head 3 (rows 0-2, columns 7-9), body 4 (rows 3-9, columns
    6-10).  Column sums: 7, 10, 10, 10, 7, 2, 7, 10, 10, 10, 7."""
    labels = np.zeros((10, 11), dtype=np.int32)
    labels[0:3, 1:4] = 1
    labels[3:10, 0:5] = 2
    labels[5:7, 5] = 2
    labels[0:3, 7:10] = 3
    labels[3:10, 6:11] = 4
    return labels


def test_valley_columns_joins_stacked_parts_and_cuts_between_people():
    """Head 1 shares all of its 3 columns with body 2 (>= 0.5 x 3): one person, and so are 3
    and 4; the two people's mean columns are 2.13 and 8 (A: 46 pixels, sum of columns 98),
    the emptiest column strictly between them is 5 (2 pixels): A gets columns 0-4, B 5-10,
    each with whole rows."""
    assert valley_columns(_two_people_in_four_parts(), 4) == [(0, 5), (5, 11)]


def test_valley_columns_keeps_a_person_cut_across_whole():
    """A valley split across one body (a head part above a torso part above a leg part, all
    in columns 2-6 of 9) is one upright person: one range, the footprint's columns."""
    labels = np.zeros((12, 9), dtype=np.int32)
    labels[0:3, 3:6] = 1
    labels[3:7, 2:7] = 2
    labels[7:12, 2:7] = 3
    assert valley_columns(labels, 3) == [(2, 7)]


@pytest.mark.parametrize("overlap, expected", [(0.5, [(0, 5), (5, 9)]), (0.3, [(0, 9)])])
def test_valley_columns_overlap_decides_between_neighbours_and_stacked_parts(overlap,
                                                                              expected):
    """Part 1 in rows 0-3, columns 0-4, part 2 in rows 4-7, columns 3-8 (a slanted
    watershed between two neighbours): they share 2 columns, 0.4 of the narrower (5).  At
    0.5 they are two people, cut at the emptiest column strictly between their mean columns
    2.0 and 5.5 (columns 3, 4, 5 hold 8, 8, 4 pixels: column 5); at 0.3 they are stacked,
    one person."""
    labels = np.zeros((8, 9), dtype=np.int32)
    labels[0:4, 0:5] = 1
    labels[4:8, 3:9] = 2
    assert valley_columns(labels, 2, overlap) == expected


def test_valley_columns_of_an_empty_footprint_is_empty():
    assert valley_columns(np.zeros((4, 4), dtype=np.int32), 0) == []


def test_heights_at_is_height_at_for_every_row_from_one_fit():
    model = PersonHeightModel(memory=100.0)
    rows = np.array([100.0, 150.0, 230.0])
    assert model.heights_at(rows) is None                 # no samples yet: no size
    for y in (120.0, 160.0, 200.0, 240.0):
        model.add(y, 20.0 + 0.3 * y + (1.0 if y == 160.0 else 0.0))
    heights = model.heights_at(rows)
    assert heights.shape == (3,)
    assert heights == pytest.approx([model.height_at(y) for y in rows])
