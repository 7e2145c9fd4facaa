"""The depth cut of a group's foreground (mk_tracker/detection/depth_split.py): people side
by side at different depths are cut at the step of their feet rows, a person's legs are not."""

from __future__ import annotations

import numpy as np

from mk_tracker.boxes import iou
from mk_tracker.detection.background_detector import BackgroundDetector
from mk_tracker.detection.depth_split import depth_columns, feet_profile

from test_background_detector import BACKGROUND, config, frame_with, run


def half_row(rows):
    """Expected height half the feet row (a ground-plane camera)."""
    return 0.5 * np.asarray(rows, dtype=np.float64)


def test_a_gap_between_legs_is_not_a_depth_step():
    mask = np.zeros((100, 30), np.uint8)
    mask[0:60, 5:25] = 1                 # body
    mask[60:100, 5:12] = 1               # left leg
    mask[60:100, 18:25] = 1              # right leg: columns 12-17 end at row 59
    assert feet_profile(mask, 1)[14] == 59
    assert feet_profile(mask, 10)[14] == 99              # the notch closed
    assert depth_columns(mask, half_row, 0.2, 10, lambda _r: 8.0) == [(5, 25)]
    # without the closing the notch (40 rows > 0.2 x 50) would cut the person in three
    assert len(depth_columns(mask, half_row, 0.2, 1, lambda _r: 1.0)) == 3


def test_people_at_different_depths_are_cut_at_the_step_of_their_feet():
    mask = np.zeros((200, 70), np.uint8)
    mask[100:200, 0:40] = 1              # near: feet at row 199
    mask[75:150, 40:64] = 1              # far: feet at row 149 (50 rows > 0.2 x 100)
    mask[140:142, 64:67] = 1             # a bag: 3 columns, joins its neighbour
    assert depth_columns(mask, half_row, 0.2, 5, lambda r: 0.2 * 0.5 * r) == [(0, 40), (40, 67)]
    assert depth_columns(mask, half_row, 0.6, 5, lambda r: 0.2 * 0.5 * r) == [(0, 67)]


def walkers(k):
    # sizes on a ground plane: height = half the feet row, width 0.4 x height
    return frame_with([(20 + 3 * k, 60, 24, 60), (120 + 3 * k, 100, 40, 100),
                       (250 - 2 * k, 80, 32, 80)])


def test_the_detector_cuts_a_near_and_a_far_person_that_touch():
    near, far = (100, 100, 36, 100), (136, 75, 24, 75)   # feet at rows 200 and 150
    group = frame_with([near, far])
    frames = [BACKGROUND] * 20 + [walkers(k) for k in range(20)]
    found = {}
    for step in (0.0, 0.2):
        det = BackgroundDetector(config(depth_step=step))
        run(det, frames)
        assert abs(det.heights.height_at(200) - 100) < 5
        found[step] = run(det, [group], t0=10.0)
    # 60 px wide against a 40 px person at row 200: the width split leaves it one box
    assert len(found[0.0]) == 1, [d.box for d in found[0.0]]
    assert len(found[0.2]) == 2, [d.box for d in found[0.2]]
    for person in (near, far):
        assert max(iou(person, d.box) for d in found[0.2]) > 0.8, [d.box for d in found[0.2]]
