"""The thermal detector keeps its windows' durations on a slower camera
(``detector.counts_fps``: window_frames, startup_frames, reconfigure_period and
group_recheck_frames are counted at 25 fps)."""

from __future__ import annotations

import numpy as np
import pytest

from mk_tracker.boxes import iou_matrix
from mk_tracker.detection.thermal_detector import ThermalDetector
from mk_tracker.detection.thermal_detector_config import ThermalDetectorConfig
from mk_tracker.synthetic.presets import crowd_scene


def _run(scene, config: ThermalDetectorConfig, step: int):
    """(recall at IoU 0.5 of the people at least half visible from frame 60, full-frame
    passes, every frame's boxes) of the detector fed every ``step``-th frame."""
    det = ThermalDetector(config)
    matched = people = 0
    boxes_seen = []
    for i in range(0, len(scene), step):
        frame = scene.frame(i)
        found = det.process(frame.thermal, frame.stamp)
        boxes = np.array([d.box for d in found], dtype=float).reshape(-1, 4)
        boxes_seen.append(boxes)
        if i < 60:
            continue
        truth = np.array([o.box_thermal for o in frame.objects if o.visible_fraction > 0.5],
                         dtype=float).reshape(-1, 4)
        people += len(truth)
        if len(truth) and len(boxes):
            matched += int((iou_matrix(truth, boxes).max(axis=1) >= 0.5).sum())
    return matched / max(people, 1), det.full_passes, boxes_seen


@pytest.mark.parametrize("seed", [303, 7])
def test_a_third_of_the_rate_keeps_people_apart(seed):
    """At 8.3 Hz four frames span half a second: the swept support of a walker joins its
    neighbours.  Counted in seconds the window is two frames and a full pass comes every
    8 frames (one second), as at 25 fps."""
    scene = crowd_scene(3, seed=seed, width=320, height=240, frames=240)
    recall_frames, passes_frames, _ = _run(scene, ThermalDetectorConfig(counts_fps=0.0), 3)
    recall_seconds, passes_seconds, _ = _run(scene, ThermalDetectorConfig(), 3)
    assert recall_frames < 0.5 and recall_seconds > 0.8
    # 80 frames: a full pass at start-up, then every 25 frames / every 8
    assert passes_frames == 3 and passes_seconds == 10


def test_the_reference_rate_and_faster_streams_are_unchanged():
    scene = crowd_scene(3, seed=303, width=320, height=240, frames=80)
    a = _run(scene, ThermalDetectorConfig(counts_fps=0.0), 1)     # 25 fps, the reference
    b = _run(scene, ThermalDetectorConfig(), 1)
    assert a[:2] == b[:2]
    assert all(np.array_equal(x, y) for x, y in zip(a[2], b[2]))
    faster = ThermalDetector(ThermalDetectorConfig(counts_fps=12.5))   # 25 fps is faster
    plain = ThermalDetector(ThermalDetectorConfig(counts_fps=0.0))
    for i in range(len(scene)):
        frame = scene.frame(i)
        got = faster.process(frame.thermal, frame.stamp)
        want = plain.process(frame.thermal, frame.stamp)
        assert [d.box for d in got] == [d.box for d in want]
    assert faster.full_passes == plain.full_passes
