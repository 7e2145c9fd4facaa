"""People who stand still from the start (``detector.still_people``, issue #19): a warm
person-sized region that never moves is reported once it has stayed in place for
``min_time``; the kernel covariance detector alone never sees it."""

import numpy as np

from mk_tracker.boxes import iou
from mk_tracker.detection.still_people import StillPeopleConfig
from mk_tracker.detection.thermal_detector import ThermalDetector, ThermalDetectorConfig

W, H = 160, 80
STILL = (130.0, 40.0, 8.0, 30.0)        # a person who never moves
SQUARE = (60.0, 50.0, 20.0, 20.0)       # a warm object that is not person-shaped
FPS = 10.0


def _scene(n: int = 90, walker: bool = True) -> list[np.ndarray]:
    """Background 40; a walker (10x30 px, level 200) moving right at 1 px a frame in rows
    10-39; the still person (level 150) and the warm square (level 150) in every frame."""
    out = []
    for k in range(n):
        f = np.full((H, W), 40, np.uint8)
        f[40:70, 130:138] = 150
        f[50:70, 60:80] = 150
        if walker:
            f[10:40, 5 + k:15 + k] = 200
        out.append(f)
    return out


def _run(enabled: bool, walker: bool = True, **kw) -> list[list]:
    det = ThermalDetector(ThermalDetectorConfig(
        still_people=StillPeopleConfig(enabled=enabled, **kw)))
    return [det.process(f, k / FPS) for k, f in enumerate(_scene(walker=walker))]


def _hits(frames: list[list], box) -> list[int]:
    return [k for k, found in enumerate(frames)
            if any(iou(d.box, box) >= 0.5 for d in found)]


def test_without_the_rule_the_still_person_is_never_detected():
    frames = _run(False)
    assert _hits(frames, STILL) == []
    assert any(frames)                   # the walker is


def test_the_still_person_is_reported_after_min_time_and_the_square_never():
    frames = _run(True, min_time=2.0)
    hits = _hits(frames, STILL)
    assert hits, "the still person is never reported"
    first = hits[0]
    # found at the start-up pass (frame 5): reported only once it stayed 2 s in place
    assert first / FPS >= 5 / FPS + 2.0
    assert hits == list(range(first, len(frames)))      # then in every frame
    assert _hits(frames, SQUARE) == []
    still = [d for d in frames[-1] if iou(d.box, STILL) >= 0.5]
    assert len(still) == 1 and 0.0 < still[0].score <= 1.0


def test_a_longer_min_time_reports_later():
    early = _hits(_run(True, min_time=2.0), STILL)[0]
    late = _hits(_run(True, min_time=4.0), STILL)
    assert late and late[0] > early


def test_nothing_is_reported_before_a_person_was_detected():
    # no walker: no person learnt, so size and warmth have no reference
    frames = _run(True, walker=False, min_time=0.0)
    assert all(not found for found in frames)


def test_a_person_too_small_for_the_learnt_size_is_not_reported():
    frames = _run(True, min_time=0.0, min_height_ratio=1.5)
    assert _hits(frames, STILL) == []
