"""A person standing still (issue #19): the kernel covariance detector finds only what moves,
so a visible track slower than ``lifecycle.still_speed`` is not lost for lack of
detections; the appearance (the multiple-kernel similarity) decides."""

from __future__ import annotations

import numpy as np
import pytest

from mk_tracker.parameters import updated
from mk_tracker.tracking.multi_object_tracker import (FrameDetection, MultiObjectTracker,
                                                      MultiObjectTrackerConfig)

IMG = np.zeros((480, 640, 3), np.uint8)
DT = 1.0 / 25.0


def config(**changes) -> MultiObjectTrackerConfig:
    return updated(MultiObjectTrackerConfig(), changes)


class FollowRefiner:
    """Fake refiner that always sees the person at the predicted centre (a 30 x 60 box),
    with similarity 0.9: a multiple-kernel search whose appearance still matches."""

    def start(self, image, box):
        return "person"

    def refine(self, image, state, predicted_center=None):
        cx, cy = predicted_center
        return type("R", (), {"box": (cx - 15.0, cy - 30.0, 30.0, 60.0), "similarity": 0.9,
                              "lost": False})()

    def appearance_similarity(self, image, state, box):
        return 0.9


@pytest.mark.parametrize("speed, still_speed, kept", [
    (0.0, 0.3, True),      # stands still, undetected for 2 s: kept
    (0.0, 0.0, False),     # no exemption: lost after max_undetected_time (0.5 s)
    (50.0, 0.3, False),    # walks at 50 px/s = 0.83 heights/s, undetected: lost
])
def test_a_person_standing_still_keeps_the_track_without_detections(speed, still_speed, kept):
    cfg = config(**{"lifecycle.still_speed": still_speed})
    trk = MultiObjectTracker(cfg, refiner=FollowRefiner())
    for i in range(25):                     # detected for 1 s
        trk.step(IMG, i * DT, [FrameDetection((100 + speed * i * DT, 100, 30, 60), 0.9)])
    (tid,) = [t.id for t in trk.tracks]
    for i in range(25, 75):                 # 2 s without a detection
        r = trk.step(IMG, i * DT, [])
    states = {t.id: t.state for t in r.tracks}
    assert states[tid] == ("confirmed" if kept else "lost")
