"""Failure detection against the track's own history and re-detection
(:mod:`mk_tracker.tracking.redetection`, issue #16 item 3).

Oracles are computed by hand: Bhattacharyya coefficients of small histograms, reference
blends, window sizes in box widths, and positions of targets drawn on a grey background
(the two-colour 20 x 40 target of ``test_multi_kernel_search``: red upper half, blue lower
half).
"""

from __future__ import annotations

import numpy as np
import pytest

from mk_tracker.tracking.multi_kernel import MultiKernelConfig, MultiKernelTracker
from mk_tracker.tracking.redetection import (back_projection_peaks, kernel_bhattacharyya,
                                             relative_similarities, scan_margin,
                                             update_reference)

W, H = 320, 160
TW, TH = 20, 40


def _frame(targets, seed=0, colours=((30, 30, 220), (220, 60, 30))):
    """Grey noise; a 20 x 40 two-colour object (upper, lower BGR colour) with its top-left
    corner at each ``(x, y)`` of ``targets``."""
    rng = np.random.default_rng(seed)
    grey = rng.integers(90, 140, size=(H, W, 1))
    img = np.repeat(grey, 3, axis=2).astype(np.uint8)
    for x, y in targets:
        img[y:y + TH // 2, x:x + TW] = colours[0]
        img[y + TH // 2:y + TH, x:x + TW] = colours[1]
    return img


def _centre(res):
    x, y, w, h = res.box
    return np.array([x + w / 2.0, y + h / 2.0])


# -- the similarity and its learnt reference ---------------------------------------------------

def test_bhattacharyya_coefficient_by_hand():
    p = np.array([[0.5, 0.5, 0.0], [0.25, 0.25, 0.5]])
    q = np.array([[0.5, 0.0, 0.5], [0.25, 0.25, 0.5]])
    # sqrt(0.25) = 0.5 (one shared bin); identical rows -> 1
    assert kernel_bhattacharyya(p, q) == pytest.approx([0.5, 1.0])
    assert kernel_bhattacharyya(np.zeros((1, 3)), q[:1]) == pytest.approx([0.0])


class _State:
    """The fields of a TargetState these functions read."""

    def __init__(self, models, reference=None, reference_var=None):
        self.models = np.asarray(models, dtype=np.float64)
        self.reference = reference
        self.reference_var = reference_var

    @property
    def num_kernels(self):
        return self.models.shape[0]


def test_the_similarity_is_1_at_the_learnt_mean_and_0_at_k_spreads_below():
    models = [[0.5, 0.0, 0.5], [0.5, 0.0, 0.5]]
    state = _State(models, reference=np.array([0.6, 0.5]), reference_var=np.array([0.01, 0.0]))
    p = np.array([[0.5, 0.5, 0.0], [0.5, 0.0, 0.5]])      # B = 0.5 and 1.0
    # kernel 0: sd 0.1, k 2: 1 - (0.6 - 0.5) / 0.2 = 0.5; kernel 1: B above its mean -> 1
    assert relative_similarities(state, p, sigmas=2.0, spread_floor=0.05) == \
        pytest.approx([0.5, 1.0])
    # kernel 0 at 1 - 0.1 / (4 * 0.1) with k = 4
    assert relative_similarities(state, p, sigmas=4.0, spread_floor=0.05)[0] == \
        pytest.approx(0.75)
    # nothing learnt yet: mean 1, spread = the floor 0.05: 1 - 0.5 / 0.1 < 0 -> 0
    assert relative_similarities(_State(models), p, sigmas=2.0, spread_floor=0.05) == \
        pytest.approx([0.0, 1.0])
    # two copies of the layout, rows ordered layout by layout; the second copy's rows are
    # swapped: B = 1.0 (above 0.6) and 0.5 (at the mean 0.5) -> 1 and 1
    both = relative_similarities(state, np.vstack([p, p[::-1]]), n_layouts=2, sigmas=2.0,
                                 spread_floor=0.05)
    assert both == pytest.approx([0.5, 1.0, 1.0, 1.0])


def test_mean_and_spread_are_learnt_only_for_kernels_that_are_seen():
    state = _State([[0.5, 0.0, 0.5], [0.5, 0.0, 0.5]])
    p = np.array([[0.5, 0.5, 0.0], [0.0, 1.0, 0.0]])      # B = 0.5 and 0
    update_reference(state, p, relative=np.array([0.5, 0.0]), level=0.3, rate=0.5)
    # kernel 0: d = 0.5 - 1 = -0.5: mean 1 - 0.25 = 0.75, variance 0.5 * (0 + 0.5 * 0.25)
    # kernel 1 is below the level: unchanged (mean 1, variance 0)
    assert state.reference == pytest.approx([0.75, 1.0])
    assert state.reference_var == pytest.approx([0.0625, 0.0])
    update_reference(state, p, relative=np.array([0.5, 0.0]), level=0.3, rate=0.0)
    assert state.reference == pytest.approx([0.75, 1.0])   # rate 0: never learnt


def test_the_scan_window_grows_with_the_frames_of_the_failure():
    tracker = MultiKernelTracker(MultiKernelConfig(recovery_margin=2.0, recovery_growth=0.5))
    state = tracker.start(_frame([(100, 60)]), (100.0, 60.0, TW, TH))
    assert scan_margin(tracker, state) == pytest.approx(2.0)
    state.failed_frames = 4
    assert scan_margin(tracker, state) == pytest.approx(2.0 + 0.5 * 4)


# -- failure detection inside refine ----------------------------------------------------------

@pytest.mark.parametrize("measure, seen", [
    # the same pixels as the model: B = 1 = the start mean -> 1
    ("bhattacharyya", 1.0),
    # -J of the same pixels is the smoothing's cost log(1 / (1 - eps)) = 0.01005 (eps 0.01;
    # eps / m = 2e-5 is negligible), against the start mean 0 and spread 0.5, k 4:
    # 1 - 0.01005 / 2
    ("kl", 1.0 - 0.01005 / 2.0),
])
def test_a_seen_target_scores_one_and_a_covered_one_fails(measure, seen):
    cfg = MultiKernelConfig(similarity_reference_rate=0.1, recovery_similarity=0.5,
                            recovery_margin=1.0, learnt_measure=measure, failure_sigmas=4.0,
                            similarity_spread_prior=0.5)
    tracker = MultiKernelTracker(cfg)
    state = tracker.start(_frame([(100, 60)]), (100.0, 60.0, TW, TH))
    res = tracker.refine(_frame([(100, 60)], seed=1), state)
    assert res.kernel_similarities == pytest.approx([seen, seen], abs=1e-4)
    assert state.failed_frames == 0
    # the target is gone (grey only, and nothing of its colours within the scan)
    tracker.refine(_frame([], seed=2), state)
    assert state.failed_frames == 1
    tracker.refine(_frame([], seed=3), state)
    assert state.failed_frames == 2


# -- re-detection -------------------------------------------------------------------------------

def test_a_target_beyond_the_basin_is_found_once_the_window_has_grown_to_it():
    # start box x in [100, 120); the target reappears at x in [250, 270).  Window edge on
    # the right: 120 + 20 * m for m = 2 + 2 k box sizes after k failed frames: 160, 200,
    # 240 (target outside), then 280 >= 270 (inside) -> found on the 4th search.
    cfg = MultiKernelConfig(recovery_similarity=0.4, recovery_margin=2.0, recovery_growth=2.0,
                            similarity_reference_rate=0.1)
    tracker = MultiKernelTracker(cfg)
    state = tracker.start(_frame([(100, 60)]), (100.0, 60.0, TW, TH))
    start = (110.0, 80.0)
    for k in range(3):
        res = tracker.refine(_frame([(250, 60)], seed=10 + k), state, predicted_center=start)
        assert res.lost or abs(_centre(res)[0] - 260.0) > 10.0, k
        assert state.failed_frames == k + 1
    res = tracker.refine(_frame([(250, 60)], seed=20), state, predicted_center=start)
    assert not res.lost
    assert _centre(res) == pytest.approx((260.0, 80.0), abs=1.5)
    assert state.failed_frames == 0


def test_without_growth_the_same_target_stays_lost():
    cfg = MultiKernelConfig(recovery_similarity=0.4, recovery_margin=2.0, recovery_growth=0.0,
                            similarity_reference_rate=0.1)
    tracker = MultiKernelTracker(cfg)
    state = tracker.start(_frame([(100, 60)]), (100.0, 60.0, TW, TH))
    for k in range(5):
        res = tracker.refine(_frame([(250, 60)], seed=10 + k), state,
                             predicted_center=(110.0, 80.0))
        assert res.lost or abs(_centre(res)[0] - 260.0) > 10.0


def test_an_object_of_other_colours_is_not_taken():
    # a green-over-yellow object 60 px right of the start, inside the scan window: its
    # colours have no mass in the target's model, so its back-projection is 0 and no
    # candidate lies on it; the result is not moved onto it
    cfg = MultiKernelConfig(recovery_similarity=0.4, recovery_margin=4.0,
                            similarity_reference_rate=0.1)
    tracker = MultiKernelTracker(cfg)
    state = tracker.start(_frame([(100, 60)]), (100.0, 60.0, TW, TH))
    other = _frame([(160, 60)], seed=5, colours=((40, 200, 40), (40, 220, 220)))
    peaks, _ = back_projection_peaks(tracker, other, state, (100.0, 60.0, TW, TH), 4.0)
    assert all(abs(p[0] - 170.0) > TW for p in peaks)
    res = tracker.refine(other, state)
    assert res.lost or abs(_centre(res)[0] - 170.0) > TW
    assert state.failed_frames == 1


def test_of_two_objects_the_one_with_the_target_colours_is_taken():
    # the wrong-coloured object is nearer (40 px) than the target copy (120 px)
    cfg = MultiKernelConfig(recovery_similarity=0.4, recovery_margin=7.0,
                            similarity_reference_rate=0.1)
    tracker = MultiKernelTracker(cfg)
    state = tracker.start(_frame([(100, 60)]), (100.0, 60.0, TW, TH))
    img = _frame([(220, 60)], seed=6)
    img[60:100, 140:160] = (40, 200, 40)
    res = tracker.refine(img, state)
    assert _centre(res) == pytest.approx((230.0, 80.0), abs=1.5)


def test_the_level_can_be_learnt_on_the_kl_cost():
    from mk_tracker.tracking.redetection import kernel_values
    models = [[0.5, 0.0, 0.5], [0.5, 0.0, 0.5]]
    p = np.array([[0.5, 0.5, 0.0], [0.5, 0.0, 0.5]])
    costs = np.array([0.5, 3.0])
    # nothing learnt: the mean of -J is 0 (the model's own cost), the spread the prior 0.5;
    # k = 2: 1 - 0.5 / 1.0 = 0.5 and 1 - 3 / 1 < 0 -> 0
    s = relative_similarities(_State(models), p, sigmas=2.0, spread_floor=0.05,
                              spread_prior=0.5, costs=costs, measure="kl")
    assert s == pytest.approx([0.5, 0.0])
    # a kernel without pixels (infinite cost) scores 0, and is not learnt
    state = _State(models)
    s = relative_similarities(state, p, sigmas=2.0, spread_prior=0.5,
                              costs=np.array([0.0, np.inf]), measure="kl")
    assert s == pytest.approx([1.0, 0.0])
    update_reference(state, p, relative=np.array([1.0, 1.0]), level=0.3, rate=0.5,
                     spread_prior=0.5, costs=np.array([0.2, np.inf]), measure="kl")
    # kernel 0: d = -0.2: mean -0.1, variance 0.5 * (0.25 + 0.5 * 0.04) = 0.135
    assert state.reference == pytest.approx([-0.1, 0.0])
    assert state.reference_var == pytest.approx([0.135, 0.25])
    with pytest.raises(ValueError, match="costs"):
        kernel_values(p, np.asarray(models), None, "kl")
