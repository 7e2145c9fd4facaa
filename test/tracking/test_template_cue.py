"""The template (spatial-structure) cue of tracks started by hand
(:mod:`mk_tracker.tracking.template_cue`, ``manual_track.template_cue``).

The images are smoothed random textures, so a template has one clear correlation peak; the
shifts are applied with ``np.roll`` / slicing, so the expected offsets are known by
construction, not computed by the code under test.
"""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import cv2
import numpy as np
import pytest

from mk_tracker.tracking.manual_track import (ManualTrackConfig, centre_by_template,
                                              manual_track_template)
from mk_tracker.tracking.multi_object_tracker import MultiObjectTracker, MultiObjectTrackerConfig
from mk_tracker.tracking.template_cue import (match_template, start_template, template_shift,
                                              update_template)

BOX = (100.0, 60.0, 40.0, 100.0)         # x, y, w, h: a 40 x 100 px person
WIDTH, FRACTION, RADIUS = 24, 0.7, 0.3


def texture(seed: int, shape=(240, 320)) -> np.ndarray:
    rng = np.random.default_rng(seed)
    img = (rng.random(shape + (3,)) * 255).astype(np.uint8)
    return cv2.GaussianBlur(img, (7, 7), 2.0)


def shifted(img: np.ndarray, dx: int, dy: int) -> np.ndarray:
    """The image content moved by (dx, dy) px (right, down)."""
    return np.roll(img, (dy, dx), axis=(0, 1))


# -- the cue itself ----------------------------------------------------------------------------

@pytest.mark.parametrize("dx,dy", [(7, -4), (-9, 5), (3, 0), (0, -10)])
def test_finds_a_known_shift(dx, dy):
    img = texture(1)
    model = start_template(img, BOX, WIDTH, FRACTION)
    assert model is not None and model.template.shape[1] == WIDTH
    m = match_template(model, shifted(img, dx, dy), BOX, RADIUS)
    assert m is not None
    # the resampling (24 template px for 28 image px) and the sub-pixel parabola: within 1 px
    assert m.dx == pytest.approx(dx, abs=1.0)
    assert m.dy == pytest.approx(dy, abs=1.0)
    assert m.peak > 0.9 and m.at_box < m.peak - 0.2
    # the shift the measurement gets: the whole offset at weight 1, half at 0.5
    assert template_shift(m, BOX, 0.5, 0.05, 1.0) == pytest.approx((m.dx, m.dy))
    assert template_shift(m, BOX, 0.5, 0.05, 0.5) == pytest.approx((m.dx / 2, m.dy / 2))


def test_follows_the_box_scale():
    # the person seen 1.5 times larger: the template is resampled to the box's width
    img = texture(2)
    model = start_template(img, BOX, WIDTH, FRACTION)
    big = cv2.resize(img, None, fx=1.5, fy=1.5, interpolation=cv2.INTER_LINEAR)
    x, y, w, h = (1.5 * v for v in BOX)
    m = match_template(model, shifted(big, 6, -5), (x, y, w, h), RADIUS)
    assert m.dx == pytest.approx(6, abs=1.5) and m.dy == pytest.approx(-5, abs=1.5)
    assert m.peak > 0.8


def test_a_shift_beyond_the_window_is_not_found():
    img = texture(3)
    model = start_template(img, BOX, WIDTH, FRACTION)
    # 0.3 box widths = 12 px of reach: a 30 px move is outside the window
    m = match_template(model, shifted(img, 30, 0), BOX, RADIUS)
    assert abs(m.dx) <= RADIUS * BOX[2] + 0.5
    assert m.peak < 0.5
    assert template_shift(m, BOX, 0.5, 0.05, 1.0) == (0.0, 0.0)
    # a 13 px move: the correlation still rises at the window's rim (12 px), no peak inside
    m = match_template(model, shifted(img, 13, 0), BOX, RADIUS)
    assert not m.inside and m.dx > 10
    assert template_shift(m, BOX, -1.0, 0.0, 1.0) == (0.0, 0.0)
    # 9 px: inside
    m = match_template(model, shifted(img, 9, 0), BOX, RADIUS)
    assert m.inside and template_shift(m, BOX, 0.5, 0.05, 1.0)[0] == pytest.approx(9, abs=1.0)


def test_ignored_when_the_peak_is_low():
    # another texture in the window (the person hidden or gone): no peak reaches 0.5
    model = start_template(texture(4), BOX, WIDTH, FRACTION)
    m = match_template(model, texture(5), BOX, RADIUS)
    assert m is not None and m.peak < 0.5
    assert template_shift(m, BOX, 0.5, 0.05, 1.0) == (0.0, 0.0)
    # the same match is used once the level is below its peak
    assert template_shift(m, BOX, m.peak - 0.01, 0.0, 1.0) == pytest.approx((m.dx, m.dy))


def test_ignored_when_the_box_is_already_at_the_peak():
    # nothing moved: the peak is the box itself, so the gain over the box is 0
    img = texture(6)
    model = start_template(img, BOX, WIDTH, FRACTION)
    m = match_template(model, img, BOX, RADIUS)
    # (the window is resampled on a grid 0.3 template px off the template's: peak ~0.98)
    assert m.peak > 0.95 and m.peak - m.at_box < 0.05
    assert abs(m.dx) < 0.5 and abs(m.dy) < 0.5
    assert template_shift(m, BOX, 0.5, 0.05, 1.0) == (0.0, 0.0)


def test_a_window_cut_by_the_image_border():
    img = texture(7)
    box = (4.0, 60.0, 40.0, 100.0)     # the window reaches 10 px past the left border
    model = start_template(img, box, WIDTH, FRACTION)
    moved = img.copy()
    moved[:, 5:] = img[:, :-5]         # the content moves 5 px right
    m = match_template(model, moved, box, RADIUS)
    assert m is not None and m.dx == pytest.approx(5, abs=1.0) and m.peak > 0.9 and m.inside
    # at the top-left corner the window holds no full template: no match, no error
    corner = (-30.0, -80.0, 40.0, 100.0)
    assert match_template(model, img, corner, RADIUS) is None
    assert template_shift(None, corner, 0.5, 0.05, 1.0) == (0.0, 0.0)
    # a first box partly outside the image has no template
    assert start_template(img, (-10.0, 60.0, 40.0, 100.0), WIDTH, FRACTION) is None
    # a box whose own position is outside the window (cut away): its correlation is
    # unknown (NaN) and the cue does not act
    left = (-14.0, 60.0, 40.0, 100.0)
    m = match_template(model, img, left, RADIUS)
    assert m is None or (np.isnan(m.at_box) and
                         template_shift(m, left, 0.5, 0.05, 1.0) == (0.0, 0.0))


def test_constant_and_nan_patches_do_not_raise():
    flat = np.full((240, 320, 3), 90, np.uint8)
    assert start_template(flat, BOX, WIDTH, FRACTION) is None
    model = start_template(texture(8), BOX, WIDTH, FRACTION)
    m = match_template(model, flat, BOX, RADIUS)       # OpenCV cannot normalise a flat window
    assert m is not None and np.isfinite(m.peak)
    assert template_shift(m, BOX, 0.5, 0.05, 1.0) == (0.0, 0.0)
    nan = texture(8).astype(np.float64)
    nan[100, 120, 1] = np.nan
    assert start_template(nan, BOX, WIDTH, FRACTION) is None
    assert match_template(model, nan, BOX, RADIUS) is None
    for bad in [(np.nan, 60.0, 40.0, 100.0), (100.0, 60.0, 0.0, 100.0), (1.0, 2.0, 3.0)]:
        assert match_template(model, texture(8), bad, RADIUS) is None
    assert start_template(texture(8), (100.0, 60.0, np.inf, 100.0), WIDTH, FRACTION) is None
    # a grey (2-D) image works like a BGR one
    grey = cv2.cvtColor(texture(8), cv2.COLOR_BGR2GRAY)
    g = match_template(model, shifted(grey, 4, 0), BOX, RADIUS)
    assert g.dx == pytest.approx(4, abs=1.0)


def test_the_update_stays_anchored_to_the_first_template():
    img = texture(9)
    model = start_template(img, BOX, WIDTH, FRACTION)
    first = model.template.copy()
    other = texture(10)
    for _ in range(200):               # a patch of something else, over and over
        update_template(model, other, BOX, 0.1)
    def ncc(a, b):
        a, b = a - a.mean(), b - b.mean()
        return float((a * b).sum() / np.sqrt((a * a).sum() * (b * b).sum()))
    # (1-a)^2 T + ... converges to a fixed point with the first template's share
    # a / (1 - (1-a)^2) = 0.1 / 0.19 > 0.5: still closer to the first view than the other
    assert ncc(model.template, first) > 0.5
    model_other = start_template(other, BOX, WIDTH, FRACTION).template
    assert ncc(model.template, first) > ncc(model.template, model_other)
    # rate 0 leaves it alone; an unreadable patch too
    before = model.template.copy()
    update_template(model, other, BOX, 0.0)
    update_template(model, np.full_like(other, 7), BOX, 0.5)
    assert np.array_equal(model.template, before)


# -- in the tracker ----------------------------------------------------------------------------

def test_centre_by_template_moves_only_the_position():
    m = replace(ManualTrackConfig(), template_cue=True)
    img = texture(11)
    model = manual_track_template(m, img, BOX)
    # x only (the default): the window reaches 0.1 box widths = 4 px in y, enough for 3 px
    out = centre_by_template(m, model, shifted(img, -6, 3), np.array(BOX))
    assert out[0] == pytest.approx(BOX[0] - 6, abs=1.0)
    assert out[1] == BOX[1]
    assert tuple(out[2:]) == BOX[2:]                  # the scale stays the kernels'
    # with template_vertical the peak's y moves the box too
    mv = replace(m, template_vertical=True, template_radius_y=0.3)
    out = centre_by_template(mv, model, shifted(img, -6, 9), np.array(BOX))
    assert out[0] == pytest.approx(BOX[0] - 6, abs=1.0)
    assert out[1] == pytest.approx(BOX[1] + 9, abs=1.0)
    assert manual_track_template(ManualTrackConfig(), img, BOX) is None     # off


class BehindRefiner:
    """A refiner whose measurement is the true box ``lag`` px behind a walker moving right
    (the 2-kernel colour optimum behind the person, docs/failure_analysis.md)."""

    def __init__(self, truth: list, lag: float):
        self.truth, self.lag, self.frame = truth, lag, 0

    def start(self, image, box):
        return SimpleNamespace(box=tuple(box))

    def refine(self, image, state, predicted_center=None):
        self.frame += 1
        x, y, w, h = self.truth[self.frame]
        return SimpleNamespace(box=(x - self.lag, y, w, h), similarity=0.9, lost=False)

    def appearance_similarity(self, image, state, box):
        return 0.9


def walker(n: int, speed: int):
    """A textured person walking right over a textured background, and its true boxes."""
    back, person = texture(12, (240, 400)), texture(13, (100, 40))
    frames, truth = [], []
    for i in range(n):
        x = 60 + speed * i
        img = back.copy()
        img[60:160, x:x + 40] = person
        frames.append(img)
        truth.append((float(x), 60.0, 40.0, 100.0))
    return frames, truth


def run(frames, truth, cue: bool) -> float:
    cfg = MultiObjectTrackerConfig()
    cfg = replace(cfg, manual_track=replace(cfg.manual_track, template_cue=cue))
    trk = MultiObjectTracker(cfg, manual_refiner=BehindRefiner(truth, lag=8.0))
    tid = trk.start_track(frames[0], 0.0, truth[0])
    errs = []
    for i in range(1, len(frames)):
        out = {o.id: o.box for o in trk.step(frames[i], i / 25.0).tracks}
        x = out[tid][0] + out[tid][2] / 2.0
        errs.append(abs(x - (truth[i][0] + truth[i][2] / 2.0)))
    return float(np.mean(errs[10:]))


def test_the_cue_removes_a_measurement_behind_the_walker():
    frames, truth = walker(40, 4)
    without, with_cue = run(frames, truth, False), run(frames, truth, True)
    # measured in this run: without the cue the box follows the biased measurement
    assert without > 4.0
    assert with_cue < 0.25 * without
