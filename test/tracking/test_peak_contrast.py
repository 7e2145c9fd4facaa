"""The contrast of a search's peak to a ring of displaced copies of its kernel layout
(:mod:`mk_tracker.tracking.peak_contrast`, used by ``benchmarks/diagnose_single_target.py
--separation``; issue #16 item 3).

Oracles are computed by hand: ring positions from cos / sin, contrasts ``1 - exp(-dJ)`` of
given costs, and the ring of a drawn frame (the two-colour 20 x 40 target of
``test_redetection`` on grey noise, a twin one box width to its right).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from mk_tracker.tracking.multi_kernel import MultiKernelConfig, MultiKernelTracker
from mk_tracker.tracking.peak_contrast import kernel_contrasts, peak_contrasts, ring_offsets

from test_redetection import TH, TW, _frame


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


def test_a_distinct_target_has_a_high_contrast_and_a_twin_beside_it_none():
    tracker = MultiKernelTracker(MultiKernelConfig())
    state = tracker.start(_frame([(100, 60)]), (100.0, 60.0, TW, TH))
    alone = _frame([(100, 60)], seed=1)
    twin = _frame([(100, 60), (120, 60)], seed=1)      # the 0-degree ring copy lands on it
    contrasts = {}
    for name, img in (("alone", alone), ("twin", twin)):
        res = tracker.refine(img, state.copy())
        ev = tracker._evaluate(tracker._search_region(img, (0, 0, img.shape[1], img.shape[0]),
                                                      tracker._stride(state.half_axes)),
                               state.half_axes, res.kernel_centres, state.models)
        contrasts[name] = peak_contrasts(tracker, img, state, res.kernel_centres, ev.costs, 1.0)
    assert np.all(contrasts["alone"] > 0.9)
    assert np.all(contrasts["twin"] < 0.1)


def test_the_trackers_peak_contrast_is_high_on_the_target_and_zero_where_it_left():
    """:meth:`MultiKernelTracker.peak_contrast` (the still-track test of the multi-object
    tracker): the mean kernel contrast of a refinement result; 0 for a lost result."""
    tracker = MultiKernelTracker(MultiKernelConfig())
    state = tracker.start(_frame([(100, 60)]), (100.0, 60.0, TW, TH))
    here = _frame([(100, 60)], seed=1)
    res = tracker.refine(here, state.copy())
    assert tracker.peak_contrast(here, state, res) > 0.9
    gone = _frame([], seed=1)                          # the person left: grey noise only
    res_gone = tracker.refine(gone, state.copy())
    assert tracker.peak_contrast(gone, state, res_gone) < 0.5
    res_gone.lost = True
    assert tracker.peak_contrast(gone, state, res_gone) == 0.0
