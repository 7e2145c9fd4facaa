"""The grey template test of a still track (``lifecycle.still_template``,
mk_tracker/tracking/still_template.py): a person who stopped is still where they were last
detected while the pixels there correlate with those of that detection's frame."""

from __future__ import annotations

import numpy as np
import pytest

from mk_tracker.parameters import updated
from mk_tracker.tracking.multi_object_tracker import (FrameDetection, MultiObjectTracker,
                                                      MultiObjectTrackerConfig)
from mk_tracker.tracking.still_template import (CENTRAL_WIDTH, grey_template,
                                                template_correlation, template_window)

DT = 1.0 / 25.0
BOX = (100.0, 100.0, 30.0, 60.0)


def textured(seed: int, shape=(480, 640, 3)) -> np.ndarray:
    """Smooth random texture (a person's clothes, or a background), 8 bits."""
    rng = np.random.default_rng(seed)
    small = rng.integers(0, 256, (shape[0] // 4, shape[1] // 4, 3), dtype=np.uint8)
    return np.repeat(np.repeat(small, 4, axis=0), 4, axis=1)[:shape[0], :shape[1]]


def with_person(background: np.ndarray, person: np.ndarray, box=BOX) -> np.ndarray:
    x, y, w, h = (int(v) for v in box)
    out = background.copy()
    out[y:y + h, x:x + w] = person[y:y + h, x:x + w]
    return out


# -- the pure functions ------------------------------------------------------------------

def test_the_window_is_the_central_part_of_the_box_clipped_to_the_image():
    x0, y0, x1, y1 = template_window((100, 50, 50, 80), 640, 480)
    assert (y0, y1) == (50, 130)
    assert x1 - x0 == round(50 * CENTRAL_WIDTH)
    assert (x0, x1) == (110, 140)                                     # 10 px off each side
    assert template_window((620, 460, 40, 40), 640, 480) == (628, 460, 640, 480)
    assert template_window((10, 10, 4, 40), 640, 480) is None         # 2 px wide: too small
    assert template_window((10, 10, float("nan"), 40), 640, 480) is None
    assert template_window((700, 10, 40, 40), 640, 480) is None       # outside


def test_the_same_pixels_in_another_light_correlate_and_background_does_not():
    image = textured(1)
    template = grey_template(image, BOX)
    assert template_correlation(image, template) == pytest.approx(1.0, abs=1e-4)
    dimmer = np.clip(image.astype(np.float32) * 0.6 + 20.0, 0, 255).astype(np.uint8)
    assert template_correlation(dimmer, template) > 0.98             # gain and offset
    assert template_correlation(textured(2), template) < 0.3          # another texture
    flat = np.full_like(image, 90)
    assert template_correlation(flat, template) == 0.0                # nothing to correlate
    grey = image[..., 1].copy()                                      # single channel works
    assert template_correlation(grey, grey_template(grey, BOX)) == pytest.approx(1.0, abs=1e-4)


# -- in the tracker ----------------------------------------------------------------------

class UnseenAfterDetections:
    """Fake refiner that follows the prediction with similarity 0.9 while detections come,
    then calls the target unseen (0.3, below occlusion_similarity): small people in a
    changing light, where the colour model no longer matches."""

    def __init__(self):
        self.fading = False

    def start(self, image, box):
        return "person"

    def refine(self, image, state, predicted_center=None):
        cx, cy = predicted_center
        return type("R", (), {"box": (cx - 12.0, cy - 33.0, 30.0, 60.0),
                              "similarity": 0.3 if self.fading else 0.9, "lost": False})()

    def appearance_similarity(self, image, state, box):
        return 0.9


@pytest.mark.parametrize("threshold, stays, speed, kept", [
    (0.0, True, 0.0, False),      # off: the colour model decides, and loses the person
    (0.8, True, 0.0, True),       # on: the pixels have not changed, the person stands there
    (0.8, False, 0.0, False),     # on, but the person left: background uncovered
    (0.8, True, 50.0, False),     # a walker (0.83 heights/s) is not a still track
])
def test_a_still_person_undetected_for_two_seconds(threshold, stays, speed, kept):
    background, person = textured(10), textured(11)
    trk = MultiObjectTracker(updated(MultiObjectTrackerConfig(),
                                     {"lifecycle.still_template": threshold}),
                             refiner=(refiner := UnseenAfterDetections()))
    for i in range(25):                                 # detected for 1 s
        box = (BOX[0] + speed * i * DT, *BOX[1:])
        trk.step(with_person(background, person, box), i * DT, [FrameDetection(box, 0.9)])
    (tid,) = [t.id for t in trk.tracks]
    last = (BOX[0] + speed * 24 * DT, *BOX[1:])
    refiner.fading = True
    for i in range(25, 75):                             # 2 s, no detection, light fading
        frame = with_person(background, person, last) if stays else background
        gain = 1.0 - 0.3 * (i - 25) / 50.0
        frame = (frame.astype(np.float32) * gain).astype(np.uint8)
        r = trk.step(frame, i * DT, [])
    state = {t.id: t.state for t in r.tracks}.get(tid)
    assert (state == "confirmed") is kept
    if kept:
        # measured at the last detected box, not where the search drifted (3 px right)
        (box,) = [t.box for t in r.tracks if t.id == tid]
        assert box[0] == pytest.approx(BOX[0], abs=0.5)


def test_no_template_is_kept_when_the_test_is_off():
    trk = MultiObjectTracker(MultiObjectTrackerConfig(), refiner=UnseenAfterDetections())
    image = textured(3)
    for i in range(5):
        trk.step(image, i * DT, [FrameDetection(BOX, 0.9)])
    assert all(t.detected_template is None for t in trk.tracks)
