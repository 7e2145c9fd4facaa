"""Distractor-aware kernel models (:mod:`mk_tracker.tracking.distractor_model`, Possegger,
Mauthner & Bischof 2015) and their use in the multiple-kernel tracker.

Oracles are worked out by hand in the comments; the tracker tests use a drawn scene with a
look-alike standing right next to the target (one box width away, where the distractor grid
looks) and one far away (where it does not).
"""

from __future__ import annotations

import numpy as np
import pytest

from mk_tracker.tracking.background_weighting import (BackgroundModel, background_model,
                                                      reweighted)
from mk_tracker.tracking.distractor_model import (blend_distractors, distractor_offsets,
                                                  distractor_sum, distractor_weights)
from mk_tracker.tracking.multi_kernel import MultiKernelConfig, MultiKernelTracker


# -- the pieces, by hand -----------------------------------------------------------------------

def test_offsets_are_the_grid_without_its_centre():
    off = distractor_offsets(20.0, 1.5)                  # spacing 30 px
    assert off.shape == (8, 2)
    assert not np.any(np.all(off == 0.0, axis=1))
    assert set(map(tuple, off)) == {(x, y) for x in (-30.0, 0.0, 30.0)
                                    for y in (-30.0, 0.0, 30.0)} - {(0.0, 0.0)}


def test_distractor_sum_keeps_the_layouts_at_the_level():
    # 3 layouts of 2 kernels over 3 bins; mean similarities 0.6, 0.2, 0.45
    p = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0],
                  [0.0, 0.0, 1.0], [0.0, 0.0, 1.0],
                  [0.5, 0.5, 0.0], [0.0, 0.5, 0.5]])
    sims = np.array([0.7, 0.5, 0.2, 0.2, 0.4, 0.5])
    total, n = distractor_sum(p, sims, 2, 0.45)
    # layouts 0 and 2 count: kernel 0 (1, 0, 0) + (0.5, 0.5, 0), kernel 1 (0, 1, 0) + (0, .5, .5)
    assert n == 2
    assert total == pytest.approx(np.array([[1.5, 0.5, 0.0], [0.0, 1.5, 0.5]]))
    total, n = distractor_sum(p, sims, 2, 0.9)
    assert n == 0 and total == pytest.approx(np.zeros((2, 3)))
    # a layout scoring 0 (no pixels) never counts, even at level 0
    assert distractor_sum(p, np.zeros(6), 2, 0.0)[1] == 0


def test_blend_is_dat_linear_interpolation():
    obs = np.array([[2.0, 0.0]])
    d = blend_distractors(None, obs, 0.1)                 # from nothing: 0.1 * obs
    assert d == pytest.approx(np.array([[0.2, 0.0]]))
    d = blend_distractors(d, np.zeros((1, 2)), 0.1)       # none seen: decays by 0.9
    assert d == pytest.approx(np.array([[0.18, 0.0]]))


def test_weights_are_object_versus_distractor_likelihoods():
    q = np.array([[0.5, 0.5, 0.0, 0.0]])
    d = np.array([[0.5, 0.0, 0.3, 0.0]])
    # 0.5 / (0.5 + 0.5), 0.5 / 0.5, 0 / 0.3, and 1 where neither has the colour
    assert distractor_weights(q, d) == pytest.approx(np.array([[0.5, 1.0, 0.0, 1.0]]))
    assert distractor_weights(q, None) == pytest.approx(np.ones((1, 4)))


def test_reweighted_combines_ring_and_distractor_weights():
    plain = np.array([[0.5, 0.5, 0.0], [0.0, 0.5, 0.5]])
    bg, q = background_model(plain, np.zeros(3), 0.0, 0.01)   # no ring: q' = q
    assert q == pytest.approx(plain)
    bg.distractors = np.array([[0.5, 0.0, 0.0], [0.0, 0.0, 0.0]])
    q = reweighted(bg, 0.0, 0.01)
    # kernel 0: r = (1/2, 1): (0.25, 0.5) / 0.75; kernel 1 unchanged
    assert q[0] == pytest.approx([1 / 3, 2 / 3, 0.0])
    assert q[1] == pytest.approx([0.0, 0.5, 0.5])
    # the offset J0 of the re-weighted kernel grows, the other's stays the smoothing's
    assert bg.offsets[0] > bg.offsets[1] + 0.05
    # with a ring too the weights multiply; a ring of two equally frequent colours gives
    # v = (1, 1, 1) (o* / o_u = 1, bin 0 absent: 1), so the result is the same
    bg2 = BackgroundModel(plain.copy(), np.array([0.0, 0.5, 0.5]), np.ones(3), np.zeros(2))
    bg2.distractors = bg.distractors
    assert reweighted(bg2, 0.0, 0.01) == pytest.approx(q)
    bg2.histogram = np.array([0.0, 0.8, 0.2])               # v = (1, 1/4, 1)
    # kernel 0: v r q = (0.25, 0.125, 0) / 0.375; kernel 1: (0, 0.125, 0.5) / 0.625
    assert reweighted(bg2, 0.0, 0.01) == pytest.approx(np.array([[2 / 3, 1 / 3, 0.0],
                                                                  [0.0, 0.2, 0.8]]))


# -- in the tracker -------------------------------------------------------------------------

W, H = 320, 200
BOX = (120, 60, 30, 80)


def _scene(seed: int = 0, passer_x: int | None = 150) -> np.ndarray:
    """Grey noise; a person at x 120 (red top with a green band, blue legs) and a look-alike
    at ``passer_x`` (red top without the band, blue legs), both 30 x 80 px from y = 60."""
    rng = np.random.default_rng(seed)
    img = np.repeat(rng.integers(90, 140, size=(H, W, 1)), 3, axis=2).astype(np.uint8)
    img[60:100, 120:150] = (30, 30, 220)              # red top (BGR)
    img[62:65, 120:150] = (40, 200, 40)               # a thin green band: hers alone
    img[100:140, 120:150] = (200, 60, 30)             # blue legs
    if passer_x is not None:
        img[60:100, passer_x:passer_x + 30] = (30, 30, 220)
        img[100:140, passer_x:passer_x + 30] = (200, 60, 30)
    return img


def _tracker(rate: float, weighting: str = "none") -> MultiKernelTracker:
    return MultiKernelTracker(MultiKernelConfig(distractor_rate=rate,
                                                background_weighting=weighting),
                              backend="numpy")


def test_off_by_default_keeps_the_plain_models():
    tracker = MultiKernelTracker(MultiKernelConfig(), backend="numpy")
    state = tracker.start(_scene(), BOX)
    assert state.background is None
    tracker.refine(_scene(), state, state.center)
    assert state.background is None


def test_a_look_alike_beside_the_target_is_learnt_and_counts_less():
    img = _scene()
    tracker = _tracker(0.1)
    state = tracker.start(img, BOX)
    bg = state.background
    assert bg is not None and not bg.ring and bg.distractors is None
    passer = (150, 60, 30, 80)
    before = tracker.appearance_similarity(img, state, passer)
    for _ in range(10):
        res = tracker.refine(img, state, state.center)
        assert not res.lost
    assert abs(res.center[0] - 135.0) < 3.0                  # still on her
    d = bg.distractors
    red, green = int(np.argmax(bg.plain[0])), None
    # the look-alike's red top entered the upper kernel's distractor histogram; her green
    # band (absent from the look-alike) did not
    top = bg.plain[0]
    green = int(np.argsort(top)[-2])
    assert d[0, red] > 0.1
    assert d[0, green] == pytest.approx(0.0)
    # so the weighted upper model shifts its mass towards the green band
    assert state.models[0, green] / state.models[0, red] > top[green] / top[red]
    assert state.models.sum(axis=1) == pytest.approx([1.0, 1.0])
    # and the look-alike scores lower against the target (the corrected similarity)
    after = tracker.appearance_similarity(img, state, passer)
    assert after < before - 0.02                             # [0.948 -> 0.913]
    # while the target itself keeps the corrected similarity of its first box
    assert tracker.appearance_similarity(img, state, BOX) == pytest.approx(1.0, abs=0.02)
    # the ring is not used: no ring weighting appears
    assert bg.weights == pytest.approx(np.ones_like(bg.weights))
    assert bg.updates == 0


def test_a_far_look_alike_is_not_a_distractor_and_a_gone_one_is_forgotten():
    tracker = _tracker(0.1, "cbwh")
    state = tracker.start(_scene(passer_x=260), BOX)
    tracker.refine(_scene(passer_x=260), state, state.center)
    assert state.background.distractors == pytest.approx(np.zeros_like(state.models))
    state = tracker.start(_scene(), BOX)
    tracker.refine(_scene(), state, state.center)
    learnt = float(state.background.distractors.sum())
    assert learnt > 0.0
    for _ in range(3):                                       # the look-alike has gone
        tracker.refine(_scene(passer_x=None), state, state.center)
    assert float(state.background.distractors.sum()) == pytest.approx(learnt * 0.9 ** 3)


def test_tracks_started_by_hand_take_their_own_rate():
    from dataclasses import replace
    from mk_tracker.tracking.manual_track import manual_track_multi_kernel
    from mk_tracker.tracking.multi_object_tracker import MultiObjectTrackerConfig
    cfg = MultiObjectTrackerConfig()
    assert manual_track_multi_kernel(cfg).distractor_rate == 0.0       # off by default
    cfg = replace(cfg, manual_track=replace(cfg.manual_track, distractor_rate=0.1))
    assert manual_track_multi_kernel(cfg).distractor_rate == 0.1
    assert cfg.multi_kernel.distractor_rate == 0.0                     # detections' tracks
