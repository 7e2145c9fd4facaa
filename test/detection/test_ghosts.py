"""Ghost reset of the background detector (mk_tracker/detection/ghosts.py): the ground a
learnt person uncovers is background within a few frames, a walker is kept."""

from __future__ import annotations

import pytest

from mk_tracker.boxes import iou
from mk_tracker.detection.background_detector import BackgroundDetector

from test_background_detector import config, frame_with, run

STOOD = (20, 100, 24, 60)


def scene(k: int):
    """A person stands at STOOD in frames 0-9 (learnt by a model started on frame 0), then
    is gone; another walks 6 px per frame from frame 10 on."""
    if k < 10:
        return frame_with([STOOD])
    return frame_with([(100 + 6 * (k - 10), 120, 24, 60)])


@pytest.mark.parametrize("reset", ["model", "memory"])
def test_the_ground_a_learnt_person_uncovers_is_background_within_a_few_frames(reset):
    frames = [scene(k) for k in range(30)]
    plain = BackgroundDetector(config(bootstrap_frames=0, startup_frames=2))
    ghosty = BackgroundDetector(config(bootstrap_frames=0, startup_frames=2, ghost_time=0.2,
                                       ghost_reset=reset))
    for k, f in enumerate(frames):
        was, now = plain.process(f, k / 25.0, "bgr8"), ghosty.process(f, k / 25.0, "bgr8")
    walker = (100 + 6 * 19, 120, 24, 60)
    # without the reset the uncovered ground is still a box 20 frames later
    assert any(iou(d.box, STOOD) > 0.5 for d in was), [d.box for d in was]
    # with it (still 0.2 s = 5 frames): gone, the walker kept
    assert not any(iou(d.box, STOOD) > 0.1 for d in now), [d.box for d in now]
    assert any(iou(d.box, walker) > 0.7 for d in now), [d.box for d in now]
    assert ghosty.ghost_pixels > 0
