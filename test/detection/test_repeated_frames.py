"""A frozen thermal camera (shutter / flat-field correction, or a driver repeating its last
frame) is skipped by the kernel-covariance detector: its objects and window survive."""

from __future__ import annotations

import numpy as np

from mk_tracker.detection.thermal_detector import ThermalDetector
from mk_tracker.detection.thermal_detector_config import ThermalDetectorConfig
from mk_tracker.frame_processing import skipped_reason
from mk_tracker.synthetic.presets import crowd_scene

FREEZE = range(40, 50)        # 0.4 s at 25 fps, about an uncooled core's correction


def _run(freeze: bool):
    scene = crowd_scene(4, seed=7, width=320, height=240, frames=70)
    det = ThermalDetector(ThermalDetectorConfig())
    held = None
    counts, modes, reasons = {}, {}, {}
    ids_before = None
    for i in range(len(scene)):
        frame = scene.frame(i)
        image = frame.thermal
        if freeze and i in FREEZE:
            held = image if held is None else held
            image = held
        if i == FREEZE.start:
            ids_before = {k for k, _ in det.tracks}
        counts[i] = len(det.process(image, frame.stamp))
        modes[i] = det.last_mode
        reasons[i] = skipped_reason(det)
    return det, counts, modes, reasons, ids_before


def test_a_frozen_camera_is_skipped_and_the_objects_survive():
    det, counts, modes, reasons, ids_before = _run(True)
    held_again = list(FREEZE)[1:]               # the first frozen frame is a new frame
    assert all(modes[i] == "repeated_frame" and counts[i] == 0 for i in held_again)
    assert "identical to the previous frame" in reasons[held_again[0]]
    assert det.repeated_frames == len(held_again) == det.skipped_frames
    # detection resumes at the first new frame, by the objects followed before the freeze
    # (counted in frames the window would have been empty until the next full pass)
    after = FREEZE.stop
    assert modes[after] == "tracking" and counts[after] >= 3
    assert len(ids_before) >= 3 and ids_before <= {k for k, _ in det.tracks}


def test_without_a_freeze_no_frame_is_skipped():
    det, counts, modes, _, _ = _run(False)
    assert det.repeated_frames == 0 and det.skipped_frames == 0
    assert all(m != "repeated_frame" for m in modes.values())


def test_identical_float_frames_with_missing_pixels_are_repeats():
    det = ThermalDetector(ThermalDetectorConfig())
    frame = np.full((60, 80), 300.0, dtype=np.float32)
    frame[:5, :5] = np.nan
    det.process(frame, 0.0, "32FC1")
    det.process(frame.copy(), 0.04, "32FC1")
    assert det.last_mode == "repeated_frame"
    changed = frame.copy()
    changed[30, 40] += 1.0
    det.process(changed, 0.08, "32FC1")
    assert det.last_mode != "repeated_frame"
