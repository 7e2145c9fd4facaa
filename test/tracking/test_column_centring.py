"""``manual_track.column_centring``: a 2 x 2 kernel layout re-centres the x of a hand-started
track's search result (:func:`mk_tracker.tracking.manual_track.centre_by_columns`)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mk_tracker.tracking.manual_track import (CENTRING_KERNELS, centre_by_columns,
                                              column_centring_multi_kernel)
from mk_tracker.tracking.multi_kernel import MultiKernelTracker
from mk_tracker.tracking.multi_object_tracker import (MultiObjectTracker,
                                                      MultiObjectTrackerConfig)
from mk_tracker.tracking.search_region import compiled_kernels

#: the person: a 40 x 120 box at x 200, y 100, left half red, right half green (BGR)
TRUTH = np.array([200.0, 100.0, 40.0, 120.0])


def _image() -> np.ndarray:
    img = np.full((300, 400, 3), 128, np.uint8)
    img[100:220, 200:220] = (0, 0, 200)
    img[100:220, 220:240] = (0, 200, 0)
    return img


def _config(centring: float) -> MultiObjectTrackerConfig:
    c = MultiObjectTrackerConfig()
    return dataclasses.replace(c, manual_track=dataclasses.replace(
        c.manual_track, column_centring=centring, background_weighting="none"))


def _refiner(backend: str = "auto") -> MultiKernelTracker:
    return MultiKernelTracker(column_centring_multi_kernel(_config(0.25)), backend=backend)


def test_the_centring_layout_is_2_by_2_without_scale_step_or_extra_searches():
    cfg = column_centring_multi_kernel(_config(0.25))
    assert (cfg.num_kernels, cfg.scale_update) == (4, False)
    assert (cfg.multi_start_radius, cfg.recovery_similarity) == (0.0, 0.0)
    assert CENTRING_KERNELS == 4


def test_a_box_behind_the_person_is_moved_onto_it_in_x_only():
    img = _image()
    ref = _refiner()
    target = ref.start(img, tuple(TRUTH))
    behind = TRUTH + np.array([-6.0, 3.0, 0.0, 0.0])     # 0.15 widths behind, 3 px low
    out = centre_by_columns(ref, img, target, 1.0, behind, 0.25, 0.2)
    # the red | green edge is at x 220: the 2 x 2 layout puts its column split there
    assert out[0] == pytest.approx(200.0, abs=1.0)
    assert out[1] == behind[1]                        # y, w, h are the search's
    assert np.array_equal(out[2:], behind[2:])


def test_a_move_beyond_the_bound_is_not_taken():
    img = _image()
    ref = _refiner()
    target = ref.start(img, tuple(TRUTH))
    behind = TRUTH + np.array([-6.0, 0.0, 0.0, 0.0])
    # 6 px = 0.15 widths > 0.05 widths: the box comes back unchanged
    out = centre_by_columns(ref, img, target, 1.0, behind, 0.05, 0.2)
    assert np.array_equal(out, behind)


def test_a_result_whose_columns_do_not_both_see_the_target_is_not_taken():
    img = _image()
    ref = _refiner()
    target = ref.start(img, tuple(TRUTH))
    on_background = np.array([300.0, 100.0, 40.0, 120.0])   # uniform grey, 60 px away
    out = centre_by_columns(ref, img, target, 1.0, on_background, 1.0, 0.2)
    assert np.array_equal(out, on_background)


@pytest.mark.skipif(compiled_kernels() is None, reason="numba not installed")
def test_numpy_and_compiled_kernels_centre_alike():
    img = _image()
    behind = TRUTH + np.array([-6.0, 0.0, 0.0, 0.0])
    outs = []
    for backend in ("numpy", "compiled"):
        ref = _refiner(backend)
        outs.append(centre_by_columns(ref, img, ref.start(img, tuple(TRUTH)), 1.0, behind,
                                      0.25, 0.2))
    np.testing.assert_allclose(outs[0], outs[1], atol=1e-6)


def test_the_tracker_keeps_a_centring_target_only_when_on():
    img = _image()
    off = MultiObjectTracker(_config(0.0))
    tid = off.start_track(img, 0.0, tuple(TRUTH))
    assert off.column_refiner is None
    assert next(t for t in off.tracks if t.id == tid).column_target is None
    on = MultiObjectTracker(_config(0.25))
    tid = on.start_track(img, 0.0, tuple(TRUTH))
    t = next(t for t in on.tracks if t.id == tid)
    assert t.column_target is not None and t.column_target.num_kernels == 4
    # a frame later the person stands where it was: the reported box stays on it
    on.step(img, 0.0)
    res = on.step(img, 0.04)
    box = next(o.box for o in res.tracks if o.id == tid)
    assert box[0] == pytest.approx(200.0, abs=1.5)
