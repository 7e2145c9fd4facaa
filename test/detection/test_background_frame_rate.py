"""The background detector's start-up counted in seconds (``counts_fps``, issue #13 at
6.25 fps): the bootstrap and start-up frames last the same seconds at 6.25 fps as at 25 fps,
and at 25 fps nothing changes."""

from __future__ import annotations

import numpy as np

from mk_tracker.detection.background_detector import (BackgroundDetector,
                                                      BackgroundDetectorConfig)

H, W = 240, 320
BACKGROUND = np.random.default_rng(11).integers(60, 120, size=(H, W, 3)).astype(np.uint8)


def with_person(x: int, y: int = 100, w: int = 24, h: int = 60) -> np.ndarray:
    img = BACKGROUND.copy()
    img[y:y + h, x:x + w] = (230, 90, 160)
    return img


def config(**kw) -> BackgroundDetectorConfig:
    base = dict(min_person_height=40.0, bootstrap_frames=0, min_height_ratio=0.0)
    base.update(kw)
    return BackgroundDetectorConfig(**base)


def first_report_time(cfg: BackgroundDetectorConfig, fps: float) -> float:
    """Stamp of the first frame the detector leaves its start-up (a walker in view)."""
    det = BackgroundDetector(cfg)
    for k in range(200):
        det.process(with_person(20 + (k * 50 // int(fps)) % 250), k / fps, encoding="bgr8")
        if det.last_mode == "tracking":
            return k / fps
    raise AssertionError("never left the start-up")


def test_startup_lasts_the_same_seconds_at_a_quarter_of_the_frame_rate():
    cfg = config(startup_frames=12, bootstrap_frames=4, counts_fps=25.0)
    at25, at6 = first_report_time(cfg, 25.0), first_report_time(cfg, 6.25)
    assert abs(at6 - at25) <= 1.0 / 6.25, (at25, at6)
    # per frame (the old behaviour) the start-up lasts four times as long in seconds
    per_frame = first_report_time(config(startup_frames=12, bootstrap_frames=4,
                                         counts_fps=0.0), 6.25)
    assert per_frame > 3.0 * at25 and per_frame > at6 + 1.0, (at25, per_frame)


def test_at_the_counting_frame_rate_the_boxes_are_unchanged():
    frames = [BACKGROUND] * 15 + [with_person(20 + 4 * k) for k in range(40)]
    runs = []
    for counts_fps in (0.0, 25.0):
        det = BackgroundDetector(config(counts_fps=counts_fps, bootstrap_frames=6,
                                        startup_frames=8, history=100))
        runs.append([[d.box for d in det.process(f, k / 25.0, encoding="bgr8")]
                     for k, f in enumerate(frames)])
    assert runs[0] == runs[1]
    assert sum(len(b) for b in runs[0]) >= 30          # the walker was found


def test_a_stamp_gap_does_not_break_the_detector():
    det = BackgroundDetector(config(counts_fps=25.0, startup_frames=4))
    stamps = [0.0, 0.04, 0.08, 5.0, 5.04, 5.08, 5.12, 5.16]
    for k, t in enumerate(stamps):
        det.process(with_person(20 + 10 * k), t, encoding="bgr8")
    assert det.last_mode == "tracking"


def test_stamps_too_close_for_a_camera_keep_the_start_up_bounded():
    # stamps a microsecond apart (a broken clock) would make the 10 start-up frames counted
    # at 25 fps 400 000 frames; the rate is capped at max_frame_rate (100 fps: 40 frames)
    det = BackgroundDetector(config(counts_fps=25.0, startup_frames=10, max_frame_rate=100.0))
    for k in range(60):
        det.process(with_person(20 + 3 * k), k * 1e-6, encoding="bgr8")
    assert det.last_mode == "tracking"
