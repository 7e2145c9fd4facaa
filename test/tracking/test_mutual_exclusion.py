"""Mutual exclusion: a refined box on another track's detection is refused
(mk_tracker.tracking.mutual_exclusion, ``refinement_exclusion_iou``)."""

from __future__ import annotations

import numpy as np
import pytest

from mk_tracker.parameters import ParameterError, updated
from mk_tracker.tracking.multi_object_tracker import (FrameDetection, MultiObjectTracker,
                                                      MultiObjectTrackerConfig)
from mk_tracker.tracking.mutual_exclusion import claimed_by_other

IMG = np.zeros((240, 320, 3), np.uint8)
DT = 1.0 / 25.0


def test_claimed_by_other_finds_the_most_overlapping_other_track():
    claimed = {1: np.array([0.0, 0.0, 20.0, 40.0]), 2: np.array([100.0, 0.0, 20.0, 40.0]),
               3: np.array([104.0, 0.0, 20.0, 40.0])}
    box = np.array([102.0, 0.0, 20.0, 40.0])
    assert claimed_by_other(9, box, claimed, 0.5) in (2, 3)
    # its own detection never excludes it
    assert claimed_by_other(1, np.array([0.0, 0.0, 20.0, 40.0]), claimed, 0.5) is None
    # IoU 360/1240 = 0.29 with track 3, 200/1400 = 0.14 with track 2
    far = np.array([115.0, 0.0, 20.0, 40.0])
    assert claimed_by_other(9, far, claimed, 0.3) is None
    assert claimed_by_other(9, far, claimed, 0.25) == 3
    assert claimed_by_other(9, box, claimed, 0.0) is None           # 0 = off
    assert claimed_by_other(9, box, {}, 0.5) is None


class NeighbourRefiner:
    """Fake refiner that always finds the target at ``self.found`` with a high similarity
    (a look-alike neighbour that matches the kernels as well as the person)."""

    def __init__(self):
        self.found = None

    def start(self, image, box):
        return "target"

    def refine(self, image, state, predicted_center=None):
        return type("R", (), {"box": self.found, "similarity": 0.95, "lost": False})()

    def appearance_similarity(self, image, state, box):
        return 0.9


def _run(level: float):
    """Two people 60 px apart, both detected for 1 s; then A is missed for one frame while B
    is detected, and A's refinement lands on B.  Returns A's reported x after that frame."""
    ref = NeighbourRefiner()
    cfg = updated(MultiObjectTrackerConfig(), {"refinement_exclusion_iou": level,
                                               "use_multi_kernel": False})
    trk = MultiObjectTracker(cfg, refiner=ref)
    a, b = (60.0, 80.0, 20.0, 50.0), (120.0, 80.0, 20.0, 50.0)
    for i in range(25):
        trk.step(IMG, i * DT, [FrameDetection(a, 0.9), FrameDetection(b, 0.9)])
    ids = sorted(t.id for t in trk.tracks)
    ref.found = b                                     # A's kernels match B's place
    r = trk.step(IMG, 25 * DT, [FrameDetection(b, 0.9)])
    boxes = {t.id: t.box for t in r.tracks}
    return boxes[ids[0]][0], r, trk


def test_a_refinement_onto_a_detected_neighbour_is_refused():
    x_off, r_off, trk_off = _run(0.0)
    x_on, r_on, trk_on = _run(0.5)
    assert trk_off.totals["excluded_refinements"] == 0
    assert trk_on.totals["excluded_refinements"] == 1
    assert any("refused" in e for e in r_on.events)
    assert x_on == pytest.approx(60.0, abs=3.0)       # coasts where A was
    assert x_off > x_on + 10.0                        # off: pulled towards B


def test_the_level_is_a_checked_parameter():
    with pytest.raises(ParameterError):
        MultiObjectTracker(updated(MultiObjectTrackerConfig(),
                                   {"refinement_exclusion_iou": 1.5}))
