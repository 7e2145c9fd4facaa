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


# -- a still track that stops matching (lifecycle.still_needs_visible) ------------------------

from mk_tracker.tracking.track import LifecycleConfig, TrackState, next_state  # noqa: E402


def lifecycle(**changes) -> LifecycleConfig:
    return updated(LifecycleConfig(), changes)


@pytest.mark.parametrize("needs_visible, unseen, expected", [
    (True, 0.04, TrackState.LOST),        # a still track that misses one match: lost at once
    (False, 0.04, TrackState.OCCLUDED),   # coasts like any other
    (False, 1.2, TrackState.LOST),        # ... and is lost after max_coast_time (1 s)
])
def test_a_still_track_that_stops_matching(needs_visible, unseen, expected):
    cfg = lifecycle(still_needs_visible=needs_visible)
    assert next_state(TrackState.CONFIRMED, detected=False, visible=False, in_image=True,
                      hits=10, tentative_misses=30, unseen_time=unseen, lost_time=0.0,
                      config=cfg, undetected_time=2.0, still=True) is expected


class DippingRefiner(FollowRefiner):
    """FollowRefiner whose similarity drops to 0.3 (< occlusion_similarity 0.6) in one
    frame: a passer-by's shoulder, a flicker of the kernels."""

    def __init__(self, dip_call: int):
        self.calls, self.dip_call = 0, dip_call

    def refine(self, image, state, predicted_center=None):
        r = super().refine(image, state, predicted_center)
        self.calls += 1
        if self.calls == self.dip_call:
            r.similarity = 0.3
        return r


@pytest.mark.parametrize("needs_visible, kept", [(True, False), (False, True)])
def test_one_unmatched_frame_of_a_still_person(needs_visible, kept):
    # standing, detected for 1 s; undetected from frame 25; the refiner runs from then on
    # and misses once at frame 49 (its 25th call), 0.96 s after the last detection
    cfg = config(**{"lifecycle.still_needs_visible": needs_visible})
    trk = MultiObjectTracker(cfg, refiner=DippingRefiner(dip_call=25))
    for i in range(25):
        trk.step(IMG, i * DT, [FrameDetection((100, 100, 30, 60), 0.9)])
    (tid,) = [t.id for t in trk.tracks]
    for i in range(25, 75):
        r = trk.step(IMG, i * DT, [])
        if i == 49:
            assert {t.id: t.state for t in r.tracks}[tid] == ("occluded" if kept else "lost")
    assert {t.id: t.state for t in r.tracks}[tid] == ("confirmed" if kept else "lost")


@pytest.mark.parametrize("changes, jumps", [
    ({"recovery.still_max_age": 0.0}, True),
    ({"recovery.skip_still": True}, False),
    # capped at 0.5 s: spread 60 sqrt(0.05^2 + 0.15^2) = 9.5 px, d2 = 160 > 13.8
    ({"recovery.still_max_age": 0.5}, False),
])
def test_a_passer_by_near_a_still_track_in_the_recovery_round(changes, jumps):
    # standing at (100, 100) 30 x 60, detected for 1 s, then seen only by the kernels for
    # 2 s; then a detection 120 px (2 box heights) to the right.  Its distance from the last
    # detection, 2 s old: spread 60 sqrt(0.05^2 + (0.3 * 2)^2) = 36.1 px, d2 = 11.0 < 13.8,
    # inside the recovery gate (the kernels' corrections keep it out of the Kalman gate)
    cfg = config(**changes)
    trk = MultiObjectTracker(cfg, refiner=FollowRefiner())
    for i in range(25):
        trk.step(IMG, i * DT, [FrameDetection((100, 100, 30, 60), 0.9)])
    (tid,) = [t.id for t in trk.tracks]
    for i in range(25, 75):
        trk.step(IMG, i * DT, [])
    r = trk.step(IMG, 75 * DT, [FrameDetection((220, 100, 30, 60), 0.9)])
    box = {t.id: t.box for t in r.tracks}[tid]
    assert (box[0] == pytest.approx(220.0)) is jumps
    assert (box[0] == pytest.approx(100.0, abs=1.0)) is not jumps
    assert len(r.tracks) == (1 if jumps else 2)     # else the passer-by starts a track


# -- a still track in another light (lifecycle.still_contrast) --------------------------------

class FadingRefiner(FollowRefiner):
    """FollowRefiner whose level falls to ``level`` (< occlusion_similarity 0.6) once the
    detections stop, while its peak stands out from its surroundings by ``contrast``."""

    def __init__(self, level: float, contrast: float):
        self.level, self.contrast, self.fading = level, contrast, False

    def refine(self, image, state, predicted_center=None):
        r = super().refine(image, state, predicted_center)
        if self.fading:
            r.similarity = self.level
        return r

    def peak_contrast(self, image, state, result):
        return self.contrast


@pytest.mark.parametrize("still_contrast, contrast, speed, kept", [
    (0.0, 0.9, 0.0, False),    # off: the level (0.5) alone decides
    (0.6, 0.9, 0.0, True),     # sqrt(0.5 x 0.9) = 0.67 >= 0.6: seen
    (0.6, 0.5, 0.0, False),    # sqrt(0.5 x 0.5) = 0.5: a flat neighbourhood, not seen
    (0.6, 0.9, 50.0, False),   # a walker (0.83 heights/s) is not a still track
])
def test_a_still_person_in_fading_light_is_judged_by_level_and_contrast(
        still_contrast, contrast, speed, kept):
    cfg = config(**{"lifecycle.still_contrast": still_contrast})
    refiner = FadingRefiner(level=0.5, contrast=contrast)
    trk = MultiObjectTracker(cfg, refiner=refiner)
    for i in range(25):                     # detected for 1 s at similarity 0.9
        trk.step(IMG, i * DT, [FrameDetection((100 + speed * i * DT, 100, 30, 60), 0.9)])
    (tid,) = [t.id for t in trk.tracks]
    refiner.fading = True
    for i in range(25, 75):                 # 2 s without a detection, level 0.5
        r = trk.step(IMG, i * DT, [])
    assert {t.id: t.state for t in r.tracks}[tid] == ("confirmed" if kept else "lost")
