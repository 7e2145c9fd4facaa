"""Background-subtraction detector (issue #13): people on a static textured background,
groups split by the learnt person size, a person broken by an occluder joined, and the bad
inputs (global change, size change, time backwards, repeated stamp)."""

from __future__ import annotations

import numpy as np
import pytest

from mk_tracker.boxes import iou
from mk_tracker.detection.background_detector import (BackgroundDetector,
                                                      BackgroundDetectorConfig)
from mk_tracker.detection.person_size import PersonHeightModel
from mk_tracker.parameters import ParameterError

H, W = 240, 320
BACKGROUND = np.random.default_rng(7).integers(60, 120, size=(H, W, 3)).astype(np.uint8)


def frame_with(people, occluder=None) -> np.ndarray:
    """The static background with solid-colour people ``(x, y, w, h)`` drawn on it."""
    img = BACKGROUND.copy()
    for k, (x, y, w, h) in enumerate(people):
        img[y:y + h, x:x + w] = (230, 40 + 60 * k, 200 - 50 * k)
    if occluder is not None:
        x, y, w, h = occluder
        img[y:y + h, x:x + w] = BACKGROUND[y:y + h, x:x + w]   # hides the person there
    return img


def run(detector, frames, t0=0.0):
    out = None
    for k, f in enumerate(frames):
        out = detector.process(f, t0 + k / 25.0, encoding="bgr8")
    return out


def config(**kw) -> BackgroundDetectorConfig:
    # solid-colour test people: with OpenCV's background ratio 0.9 a still colour becomes
    # background after about 0.1 x history frames, so the history is long here
    # (and OpenCV's automatic rate learns fast in the first frames: a fixed slow rate)
    base = dict(min_person_height=40.0, startup_frames=5, history=1000, learning_rate=0.002)
    base.update(kw)
    return BackgroundDetectorConfig(**base)


def test_two_walkers_are_found_where_they_are():
    det = BackgroundDetector(config())
    frames = [BACKGROUND] * 20 + [frame_with([(40 + 2 * k, 100, 24, 60),
                                              (220 - 2 * k, 120, 24, 60)]) for k in range(10)]
    out = run(det, frames)
    truth = [(58, 100, 24, 60), (202, 120, 24, 60)]
    assert det.last_mode == "tracking" and len(out) == 2
    for t in truth:
        assert max(iou(t, d.box) for d in out) > 0.7, (t, [d.box for d in out])
    assert all(0.5 < d.score <= 1.0 for d in out)


def test_startup_frames_report_nothing():
    det = BackgroundDetector(config(startup_frames=8))
    for k in range(8):
        assert det.process(frame_with([(50, 50, 20, 60)]), k / 25.0, "bgr8") == []
        assert det.last_mode == "startup"


def test_a_group_is_split_once_person_sizes_are_learnt():
    det = BackgroundDetector(config())
    walk = [frame_with([(30 + 3 * k, 100, 24, 60), (150 + 3 * k, 60, 24, 60),
                        (240 - 2 * k, 140, 24, 60)]) for k in range(20)]
    run(det, [BACKGROUND] * 20 + walk)
    assert det.heights.samples >= 3 and det.heights.height_at(160) == pytest.approx(60, abs=3)
    # three people side by side, touching: one blob 72 px wide
    out = run(det, [frame_with([(100, 100, 24, 60), (124, 100, 24, 60),
                                (148, 100, 24, 60)])], t0=10.0)
    assert len(out) == 3, [d.box for d in out]
    for x in (100, 124, 148):
        assert max(iou((x, 100, 24, 60), d.box) for d in out) > 0.5


def test_a_person_behind_a_thin_horizontal_bar_is_one_box():
    det = BackgroundDetector(config())
    frames = [BACKGROUND] * 20 + [frame_with([(100 + k, 80, 24, 70)],
                                             occluder=(0, 110, W, 4)) for k in range(8)]
    out = run(det, frames)
    assert len(out) == 1 and iou(out[0].box, (107, 80, 24, 70)) > 0.7, [d.box for d in out]


def test_lights_on_restarts_the_model_and_is_counted():
    det = BackgroundDetector(config())
    run(det, [BACKGROUND] * 20)
    bright = np.clip(BACKGROUND.astype(int) + 100, 0, 255).astype(np.uint8)
    assert det.process(bright, 5.0, "bgr8") == []
    assert det.last_mode == "global_change" and det.global_changes == 1
    assert "restarted" in det.last_event
    # the new background is the bright scene: a person on it is found after start-up
    out = run(det, [bright] * 10 + [np.where(frame_with([(60, 60, 24, 60)]) == BACKGROUND,
                                             bright, frame_with([(60, 60, 24, 60)]))],
              t0=6.0)
    assert len(out) == 1 and iou(out[0].box, (60, 60, 24, 60)) > 0.7


def test_size_change_and_time_backwards_restart_repeated_stamp_is_skipped():
    det = BackgroundDetector(config())
    run(det, [BACKGROUND] * 10)
    restarts = det.restarts
    assert det.process(BACKGROUND, 9 / 25.0, "bgr8") == []   # the last frame's stamp
    assert det.last_mode == "out_of_order" and det.restarts == restarts
    det.process(BACKGROUND[:120, :160], 1.0, "bgr8")
    assert det.restarts == restarts + 1 and "differs" in det.last_event
    det.process(BACKGROUND[:120, :160], 0.5, "bgr8")
    assert det.restarts == restarts + 2 and "backwards" in det.last_event
    assert det.last_mode == "startup"


def test_grey_and_16_bit_frames_are_taken():
    det = BackgroundDetector(config())
    grey = BACKGROUND[:, :, 0].astype(np.uint16) * 100
    person = grey.copy()
    person[100:160, 50:74] = 30000
    out = run(det, [grey] * 20 + [person] * 3)
    assert len(out) == 1 and iou(out[0].box, (50, 100, 24, 60)) > 0.7


def test_person_height_model_fits_a_line_with_forgetting():
    model = PersonHeightModel(memory=1e9)
    assert model.height_at(100) is None
    for y, h in ((100, 40), (200, 80), (300, 120)):     # h = 0.4 y
        model.add(y, h)
    assert model.height_at(250) == pytest.approx(100.0)
    flat = PersonHeightModel(memory=1e9)
    for _ in range(3):
        flat.add(150, 50)
    assert flat.height_at(400) == pytest.approx(50.0)   # one row only: the mean height
    short = PersonHeightModel(memory=4.0)               # weights x0.75 each sample
    for h in (10, 10, 10, 10, 90):
        short.add(100, h)
    weights = [0.75 ** k for k in range(5)]            # newest first: 90, then the 10s
    expected = (90 * weights[0] + 10 * sum(weights[1:])) / sum(weights)
    assert short.height_at(100) == pytest.approx(expected)      # 36.2, not the plain 26


def test_bad_parameters_are_refused():
    with pytest.raises((ParameterError, ValueError)):
        BackgroundDetector(BackgroundDetectorConfig(model="vibe"))
    with pytest.raises((ParameterError, ValueError)):
        BackgroundDetector(BackgroundDetectorConfig(max_foreground_fraction=0.0))


def test_bootstrap_removes_people_present_from_the_first_frame():
    # a person walks 8 px per frame from the first frame on: over 9 frames each pixel of
    # the path is covered 3 times (24 px wide), so the per-pixel median is the background
    walk = [frame_with([(20 + 8 * k, 100, 24, 60)]) for k in range(12)]
    det = BackgroundDetector(config(bootstrap_frames=9, startup_frames=0))
    for k in range(8):
        assert det.process(walk[k], k / 25.0, "bgr8") == [] and det.last_mode == "startup"
    out = det.process(walk[8], 8 / 25.0, "bgr8")          # the 9th frame is measured
    assert det.last_mode == "tracking" and len(out) == 1, [d.box for d in out]
    assert iou(out[0].box, (84, 100, 24, 60)) > 0.7
    out = run(det, walk[9:], t0=9 / 25.0)
    assert len(out) == 1 and iou(out[0].box, (108, 100, 24, 60)) > 0.7
    # without the bootstrap the first frame is the background: the person's first place
    # (x 20..44) is reported as a ghost
    plain = BackgroundDetector(config(bootstrap_frames=0, startup_frames=8))
    out = run(plain, walk[:9])
    assert any(iou(d.box, (20, 100, 24, 60)) > 0.5 for d in out), [d.box for d in out]


def test_bootstrap_restarts_after_a_global_change():
    det = BackgroundDetector(config(bootstrap_frames=5, startup_frames=0))
    run(det, [BACKGROUND] * 8)
    bright = np.clip(BACKGROUND.astype(int) + 100, 0, 255).astype(np.uint8)
    assert det.process(bright, 1.0, "bgr8") == [] and det.last_mode == "global_change"
    for k in range(3):                                     # frames 2..4 of the new buffer
        assert det.process(bright, 1.1 + k / 25.0, "bgr8") == []
        assert det.last_mode == "startup"
    person = np.where(frame_with([(60, 60, 24, 60)]) == BACKGROUND, bright,
                      frame_with([(60, 60, 24, 60)]))
    det.process(bright, 1.5, "bgr8")                       # the 5th: model seeded
    out = run(det, [person], t0=2.0)
    assert len(out) == 1 and iou(out[0].box, (60, 60, 24, 60)) > 0.7


@pytest.mark.parametrize("method", ["ratio", "model"])
def test_a_cast_shadow_is_not_a_detection(method):
    # a person and, beside it, a shadow: the background darkened to 0.6 (colour kept)
    def scene(k):
        img = frame_with([(60 + 2 * k, 100, 24, 60)])
        x = 150 + 2 * k
        img[120:160, x:x + 40] = (img[120:160, x:x + 40] * 0.6).astype(np.uint8)
        return img
    frames = [BACKGROUND] * 20 + [scene(k) for k in range(6)]
    # the size filter is off (the patch is shorter than the person): the shadow test decides
    det = BackgroundDetector(config(shadow_method=method, shadow_threshold=0.5,
                                    shadow_min_ratio=0.5, shadow_max_ratio=0.95,
                                    min_height_ratio=0.0))
    out = run(det, frames)
    assert len(out) == 1 and iou(out[0].box, (70, 100, 24, 60)) > 0.7, [d.box for d in out]
    # with no shadow test the darkened patch (x 160..200, y 120..160) is foreground too
    # (reported as one box or cut in two: it is wider than one person of the learnt size)
    out = run(BackgroundDetector(config(shadow_method="none", min_height_ratio=0.0)), frames)
    inside = [d.box for d in out if d.box[0] >= 155 and d.box[0] + d.box[2] <= 205
              and d.box[1] >= 115 and d.box[1] + d.box[3] <= 165]
    assert inside and sum(w * h for _x, _y, w, h in inside) > 0.8 * 40 * 40, \
        [d.box for d in out]


@pytest.mark.parametrize("ratio, boxes", [(0.0, 2), (0.8, 1)])
def test_a_blob_much_shorter_than_the_learnt_person_is_dropped(ratio, boxes):
    det = BackgroundDetector(config(min_height_ratio=ratio))
    walk = [frame_with([(30 + 3 * k, 100, 24, 60), (150 + 3 * k, 60, 24, 60),
                        (240 - 2 * k, 140, 24, 60)]) for k in range(20)]
    run(det, [BACKGROUND] * 20 + walk)
    assert det.heights.height_at(160) == pytest.approx(60, abs=3)
    # a person (60 px) and a 16 x 24 blob with its bottom on the same row: 24 < 0.8 x 60
    out = run(det, [frame_with([(60, 100, 24, 60), (200, 136, 16, 24)])], t0=10.0)
    assert len(out) == boxes, [d.box for d in out]
    assert max(iou((60, 100, 24, 60), d.box) for d in out) > 0.7
    if boxes == 2:
        assert max(iou((200, 136, 16, 24), d.box) for d in out) > 0.7


def test_column_trim_drops_a_stride_leg_from_the_box():
    # a 24 x 60 person with a 10 px tall leg stretched 10 px to the right at the bottom:
    # the leg's columns hold 10 foreground pixels, the body's 60 (10 / 60 = 0.17)
    def walker(k):
        img = frame_with([(60 + 2 * k, 100, 24, 60)])
        img[150:160, 84 + 2 * k:94 + 2 * k] = (230, 40, 200)
        return img
    frames = [BACKGROUND] * 20 + [walker(k) for k in range(6)]
    wide = run(BackgroundDetector(config(column_trim=0.0)), frames)
    trimmed = run(BackgroundDetector(config(column_trim=0.2)), frames)
    assert len(wide) == 1 and iou(wide[0].box, (70, 100, 34, 60)) > 0.85, wide[0].box
    assert len(trimmed) == 1 and iou(trimmed[0].box, (70, 100, 24, 60)) > 0.85, \
        trimmed[0].box
