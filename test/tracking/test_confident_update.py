"""The model update in confident frames only (:mod:`mk_tracker.tracking.confident_update`,
``manual_track.model_update`` confident; issue #16 item 3) and the peak contrast it uses
(:mod:`mk_tracker.tracking.peak_contrast`).

Oracles are computed by hand: ring positions from cos / sin, contrasts ``1 - exp(-dJ)`` of
given costs, running means of given levels, and the verdicts on drawn frames (the two-colour
20 x 40 target of ``test_redetection``: red upper half, blue lower half, on grey noise) whose
colours and occluders are set by construction.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from mk_tracker.tracking.background_weighting import histogram_overlap
from mk_tracker.tracking.confident_update import confident_kernels, update_level_reference
from mk_tracker.tracking.multi_kernel import MultiKernelConfig, MultiKernelTracker
from mk_tracker.tracking.multi_object_tracker import (MultiObjectTracker,
                                                      MultiObjectTrackerConfig)
from mk_tracker.tracking.peak_contrast import kernel_contrasts, ring_offsets
from mk_tracker.tracking.track import TrackState

from test_redetection import TH, TW, _frame

#: colours the target's pixels turn into (upper, lower half): neither the model's nor the
#: grey background's
NEW_UPPER, NEW_LOWER = (40, 200, 40), (200, 40, 200)


def _drifted(t, seed, x=100, y=60):
    """The target with a share ``t`` of its pixels in the new colours; the same pixels keep
    their new colour as ``t`` grows (a slow change of appearance, as under a light change)."""
    img = _frame([(x, y)], seed=seed)
    turned = np.random.default_rng(7).random((TH, TW)) < t
    upper = np.zeros((TH, TW), dtype=bool)
    upper[:TH // 2] = True
    patch = img[y:y + TH, x:x + TW]
    patch[turned & upper] = NEW_UPPER
    patch[turned & ~upper] = NEW_LOWER
    return img


# -- by hand -----------------------------------------------------------------------------------

def test_ring_positions_are_the_box_size_times_cos_and_sin_every_45_degrees():
    r = math.sqrt(0.5)
    expected = [(20, 0), (20 * r, 40 * r), (0, 40), (-20 * r, 40 * r), (-20, 0),
                (-20 * r, -40 * r), (0, -40), (20 * r, -40 * r)]
    assert ring_offsets(20.0, 40.0, 1.0) == pytest.approx(np.array(expected), abs=1e-9)
    with pytest.raises(ValueError):
        ring_offsets(20.0, 40.0, 0.0)


def test_contrast_is_one_minus_the_best_ring_similarity_over_the_peaks():
    box = np.array([3.0, 2.0])
    ring = np.array([[7.0, 2.5],          # kernel 0: nearest ring cost 5 -> 1 - e^-2
                     [5.0, 9.0],          # kernel 1: nearest 2.5 -> 1 - e^-0.5
                     [np.inf, 4.0]])      # a copy without pixels is no competitor
    assert kernel_contrasts(box, ring) == pytest.approx([1 - math.exp(-2.0),
                                                         1 - math.exp(-0.5)])
    assert kernel_contrasts(box, np.array([[3.0, 1.0]])) == pytest.approx([0.0, 0.0])
    assert kernel_contrasts(np.array([np.inf, 2.0]),
                            np.array([[4.0, np.inf]])) == pytest.approx([0.0, 1.0])


def test_a_kernel_is_confident_when_it_and_the_frame_pass_both_tests():
    ref = np.array([0.8, 0.6])
    # both kernels distinct and within 0.7 of their means
    assert confident_kernels([0.6, 0.5], [0.9, 0.6], ref, 0.5, 0.7).tolist() == [True, True]
    # kernel 1 dropped below 0.7 * 0.6 = 0.42: only kernel 0 (the frame: mean 0.5 >= 0.49)
    assert confident_kernels([0.6, 0.4], [0.9, 0.6], ref, 0.5, 0.7).tolist() == [True, False]
    # kernel 1 not distinct (contrast 0.3), the frame's mean contrast 0.6 still is
    assert confident_kernels([0.6, 0.5], [0.9, 0.3], ref, 0.5, 0.7).tolist() == [True, False]
    # the frame's mean contrast (0.9 + 0) / 2 < 0.5: kernel 0 does not learn either
    assert confident_kernels([0.6, 0.5], [0.9, 0.0], ref, 0.5, 0.7).tolist() == [False, False]
    # the frame's mean level 0.45 < 0.7 * 0.7 = 0.49 although kernel 0 alone passes
    assert confident_kernels([0.57, 0.33], [0.9, 0.9], ref, 0.5, 0.7).tolist() == \
        [False, False]
    # no history: only the contrast and a positive level count; NaN is not confident
    assert confident_kernels([0.1, np.nan], [0.9, 0.9], None, 0.5, 0.7).tolist() == \
        [True, False]
    with pytest.raises(ValueError):
        confident_kernels([0.5, 0.5], [0.9], None, 0.5, 0.7)


def test_the_level_reference_is_the_plain_mean_of_every_frame():
    from types import SimpleNamespace
    state = SimpleNamespace(level_reference=None, level_frames=0)
    for v in (0.9, 0.6, 0.3):
        update_level_reference(state, np.array([v, 1.0]))
    assert state.level_reference == pytest.approx([0.6, 1.0])
    update_level_reference(state, np.array([0.2, np.nan]))
    # (0.9 + 0.6 + 0.3 + 0.2) / 4; a NaN level leaves its mean
    assert state.level_reference == pytest.approx([0.5, 1.0])
    assert state.level_frames == 4


# -- on drawn frames ---------------------------------------------------------------------------

def _hand_started_states(mode: str, frames: int = 150, final_share: float = 0.8):
    base = MultiObjectTrackerConfig()
    cfg = replace(base, manual_track=replace(base.manual_track, model_update=mode))
    tracker = MultiObjectTracker(cfg)
    first = _frame([(100, 60)])
    tid = tracker.start_track(first, 0.0, (100.0, 60.0, TW, TH))
    tracker.step(first, 0.0)
    states = []
    for i in range(1, frames + 1):
        res = tracker.step(_drifted(final_share * i / frames, seed=i), i / 25.0)
        states.append(next(t for t in res.tracks if t.id == tid).state)
    return states


def test_a_target_whose_colours_drift_slowly_stays_confirmed_only_with_the_update():
    # 80% of the target's pixels change colour over 150 frames (6 s at 25 fps)
    frozen = _hand_started_states("none")
    learning = _hand_started_states("confident")
    # both see it at first; the frozen models lose it as its colours leave them
    assert frozen[:10] == learning[:10] == [TrackState.CONFIRMED.value] * 10
    assert frozen[-20:] == [TrackState.OCCLUDED.value] * 20
    assert learning[-20:] == [TrackState.CONFIRMED.value] * 20


def _occluded(seed, covered):
    """The still target; with ``covered`` a green occluder over most of its lower half (a
    person in front, stepping in between two frames)."""
    img = _frame([(100, 60)], seed=seed)
    if covered:
        img[80:100, 96:113] = (40, 200, 40)
    return img


def test_an_occluder_stepping_in_front_does_not_enter_the_models():
    # 10 frames seen, 10 with 13 of the lower half's 20 columns hidden, 10 seen again; the
    # lower kernel's level drops from ~0.99 to ~0.5: above the paper's gate 0.3, so its gated
    # update at the same rate learns the green, but below 0.7 of its running mean, so the
    # confident update does not blend it (and its mean is not pulled down while hidden)
    overlaps = {}
    for name, cfg in (("confident", MultiKernelConfig(confident_update_rate=0.1,
                                                      scale_update=False)),
                      ("gated", MultiKernelConfig(model_update_rate=0.1, scale_update=False))):
        tracker = MultiKernelTracker(cfg)
        state = tracker.start(_frame([(100, 60)]), (100.0, 60.0, TW, TH))
        for i in range(10):
            tracker.refine(_occluded(i + 1, False), state)
        before = state.models.copy()
        for i in range(10, 20):
            tracker.refine(_occluded(i + 1, True), state)
        overlaps[name] = histogram_overlap(state.models[1], before[1])
        for i in range(20, 30):
            res = tracker.refine(_occluded(i + 1, False), state)
        x, y, w, h = res.box      # still on the target (within a quarter of its width)
        assert (x + w / 2, y + h / 2) == pytest.approx((110.0, 80.0), abs=5.0)
    assert overlaps["gated"] < 0.9
    assert overlaps["confident"] > 0.9999


def test_the_options_are_validated():
    with pytest.raises(ValueError):
        MultiKernelTracker(MultiKernelConfig(confident_update_rate=1.5))
    with pytest.raises(ValueError):
        MultiKernelTracker(MultiKernelConfig(contrast_ring_distance=0.0))
    base = MultiObjectTrackerConfig()
    with pytest.raises(ValueError):
        MultiObjectTracker(replace(base, manual_track=replace(base.manual_track,
                                                              model_update="always")))
