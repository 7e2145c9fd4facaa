"""The contrast of a search's peak to a ring of displaced copies of its kernel layout, as the
failure test of hand-started tracks (:mod:`mk_tracker.tracking.peak_contrast`,
``failure_test`` contrast; issue #16 item 3).

Oracles are computed by hand: ring positions from cos / sin, contrasts ``1 - exp(-dJ)`` of
given costs, and the verdicts on drawn frames (the two-colour 20 x 40 target of
``test_redetection``: red upper half, blue lower half, on grey noise) whose similarity level
and surroundings are set by construction.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from mk_tracker.tracking.multi_kernel import (MultiKernelConfig, MultiKernelTracker,
                                              visibility_similarity)
from mk_tracker.tracking.multi_object_tracker import (MultiObjectTracker,
                                                      MultiObjectTrackerConfig)
from mk_tracker.tracking.peak_contrast import kernel_contrasts, ring_offsets
from mk_tracker.tracking.track import TrackState

from test_redetection import TH, TW, _frame


def _faded(x, y, keep, seed=1):
    """The target at ``(x, y)`` with only ``keep`` of its pixels in its own colours, the rest
    green (a colour neither the model nor the grey background has): a low similarity level
    at a peak that is still distinct from the grey around it."""
    img = _frame([(x, y)], seed=seed)
    mask = np.random.default_rng(5).random((TH, TW)) >= keep
    img[y:y + TH, x:x + TW][mask] = (40, 200, 40)
    return img


def _weighted(res):
    return visibility_similarity(res.kernel_similarities, None, "weighted")


# -- by hand -----------------------------------------------------------------------------------

def test_ring_positions_are_the_box_size_times_cos_and_sin_every_45_degrees():
    r = math.sqrt(0.5)
    expected = [(20, 0), (20 * r, 40 * r), (0, 40), (-20 * r, 40 * r), (-20, 0),
                (-20 * r, -40 * r), (0, -40), (20 * r, -40 * r)]
    assert ring_offsets(20.0, 40.0, 1.0) == pytest.approx(np.array(expected), abs=1e-9)
    assert ring_offsets(20.0, 40.0, 0.5)[2] == pytest.approx([0.0, 20.0], abs=1e-9)
    with pytest.raises(ValueError):
        ring_offsets(20.0, 40.0, 0.0)


def test_contrast_is_one_minus_the_best_ring_similarity_over_the_peaks():
    box = np.array([3.0, 2.0])            # rho 0.050, 0.135
    ring = np.array([[7.0, 2.5],          # kernel 0: nearest ring cost 5 -> 1 - e^-2
                     [5.0, 9.0],          # kernel 1: nearest 2.5 -> 1 - e^-0.5
                     [np.inf, 4.0]])      # a copy without pixels is no competitor
    assert kernel_contrasts(box, ring) == pytest.approx([1 - math.exp(-2.0),
                                                         1 - math.exp(-0.5)])
    # a neighbour as similar as the peak, or more, gives 0
    assert kernel_contrasts(box, np.array([[3.0, 1.0]])) == pytest.approx([0.0, 0.0])
    # a kernel without pixels at the box has no contrast; with every copy empty, 1
    assert kernel_contrasts(np.array([np.inf, 2.0]),
                            np.array([[4.0, np.inf]])) == pytest.approx([0.0, 1.0])


# -- the verdict of a search -------------------------------------------------------------------

def test_a_distinct_peak_at_a_low_level_is_seen_by_the_contrast_only():
    # 10% of the target's pixels in its colours: exp(-J) ~0.13 at the peak, below the
    # failure level 0.25; the grey around it scores far lower, so the peak is distinct
    for test, seen in (("level", False), ("contrast", True)):
        tracker = MultiKernelTracker(MultiKernelConfig(failure_test=test,
                                                       recovery_similarity=0.25))
        state = tracker.start(_frame([(100, 60)]), (100.0, 60.0, TW, TH))
        res = tracker.refine(_faded(102, 61, 0.1), state)
        x, y, w, h = res.box
        # the search found the target either way; only the verdict differs
        assert (x + w / 2, y + h / 2) == pytest.approx((112.0, 81.0), abs=2.0)
        if seen:
            assert _weighted(res) > 0.9 and state.failed_frames == 0
        else:
            assert _weighted(res) < 0.25 and state.failed_frames == 1


@pytest.mark.parametrize("frame", [
    # a twin one box width to the right: the ring copy at 0 degrees lands on it
    _frame([(100, 60), (120, 60)], seed=1),
    # a flat neighbourhood: the target's colours run 3 box widths along x
    _frame([(80, 60), (100, 60), (120, 60)], seed=1),
], ids=["twin", "flat"])
def test_a_peak_shared_with_a_neighbour_is_not_seen_by_the_contrast(frame):
    for test, seen in (("level", True), ("contrast", False)):
        tracker = MultiKernelTracker(MultiKernelConfig(failure_test=test,
                                                       recovery_similarity=0.25))
        state = tracker.start(_frame([(100, 60)]), (100.0, 60.0, TW, TH))
        res = tracker.refine(frame, state, predicted_center=(110.0, 80.0))
        if seen:
            assert _weighted(res) > 0.9 and state.failed_frames == 0
        else:
            assert _weighted(res) < 0.1 and state.failed_frames == 1


def test_the_re_search_is_confirmed_by_the_contrast():
    # the faded target reappears 4 box widths away, beyond Algorithm 1's basin; the
    # re-search scans 2 box sizes around the start box and finds it; at its level 0.13 the
    # level test rejects it, the contrast confirms it
    for test, found in (("level", False), ("contrast", True)):
        tracker = MultiKernelTracker(MultiKernelConfig(failure_test=test,
                                                       recovery_similarity=0.25,
                                                       recovery_margin=4.0))
        state = tracker.start(_frame([(100, 60)]), (100.0, 60.0, TW, TH))
        res = tracker.refine(_faded(180, 61, 0.1), state)
        x, y, w, h = res.box
        assert (abs(x + w / 2 - 190.0) < 3.0) == found
        assert state.failed_frames == (0 if found else 1)


def test_a_hand_started_track_in_plain_view_at_a_low_level_stays_confirmed():
    base = MultiObjectTrackerConfig()
    states = {}
    for test in ("level", "contrast"):
        cfg = replace(base, manual_track=replace(base.manual_track, failure_test=test))
        tracker = MultiObjectTracker(cfg)
        first = _frame([(100, 60)])
        tid = tracker.start_track(first, 0.0, (100.0, 60.0, TW, TH))
        tracker.step(first, 0.0)
        out = []
        for i in range(1, 6):
            res = tracker.step(_faded(100 + i, 60, 0.1, seed=i), i / 25.0)
            out.append(next(t for t in res.tracks if t.id == tid).state)
        states[test] = out
    # (the reported state is the TrackState's value)
    assert states["level"] == [TrackState.OCCLUDED.value] * 5
    assert states["contrast"] == [TrackState.CONFIRMED.value] * 5


def test_the_options_are_validated():
    with pytest.raises(ValueError):
        MultiKernelTracker(MultiKernelConfig(failure_test="psr"))
    with pytest.raises(ValueError):
        MultiKernelTracker(MultiKernelConfig(contrast_ring_distance=0.0))
