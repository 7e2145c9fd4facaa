"""The back-projection extent step of the scale (tracking/scale_estimation.py:
back_projection_extent, extent_step; MultiKernelConfig.extent_scale_rate).

The extent's moments are checked on hand-made bin grids, so every expected centroid and
size is counted by hand; the tracker cases use a synthetic person of known height.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from mk_tracker.tracking.manual_track import manual_track_multi_kernel
from mk_tracker.tracking.multi_kernel import MultiKernelConfig, MultiKernelTracker
from mk_tracker.tracking.multi_object_tracker import MultiObjectTrackerConfig
from mk_tracker.tracking.scale_estimation import (Extent, back_projection_extent,
                                                  extent_step)

#: bin 0 = background colour (all of the ring), bin 1 = the person's colour, bin 2 = a
#: colour absent from the ring that the target holds only a trace of
Q = np.array([0.2, 0.79, 0.01])
O = np.array([1.0, 0.0, 0.0])


def _grid(stride: int = 1) -> np.ndarray:
    """30 x 20 samples of bin 0; a rectangle of bin 1 on image pixels x 5..14, y 4..23."""
    bins = np.zeros((30, 20), dtype=np.int32)
    xs = np.arange(20) * stride
    ys = np.arange(30) * stride
    bins[np.ix_((ys >= 4) & (ys <= 23), (xs >= 5) & (xs <= 14))] = 1
    return bins


def test_extent_of_a_rectangle_counted_by_hand():
    # 10 x 20 samples at pixel centres x 5.5..14.5, y 4.5..23.5: centroid (10, 14); a run
    # of n samples 1 px apart has variance (n^2 - 1) / 12, so sqrt(12 var + 1) = n
    e = back_projection_extent(_grid(), (0, 0), 1, (5.0, 4.0, 10.0, 20.0), Q, O, 0.25)
    assert e.cx == pytest.approx(10.0) and e.cy == pytest.approx(14.0)
    assert e.width == pytest.approx(10.0) and e.height == pytest.approx(20.0)
    assert e.fraction == pytest.approx(1.0)                   # 200 of the box's 200 samples


def test_extent_with_a_stride():
    # stride 2: bin 1 on samples x 6, 8, .., 14 (5) and y 4, 6, .., 22 (10); centres +0.5:
    # x mean 10.5, y mean 13.5; variance 4 (n^2 - 1) / 12: sqrt(12 var + 4) = 2 n
    e = back_projection_extent(_grid(2), (0, 0), 2, (5.0, 4.0, 10.0, 20.0), Q, O, 0.25)
    assert e.cx == pytest.approx(10.5) and e.cy == pytest.approx(13.5)
    assert e.width == pytest.approx(10.0) and e.height == pytest.approx(20.0)
    # the box holds samples x 6..14 (5) by y 4..22 (10): all 50 are the person's
    assert e.fraction == pytest.approx(1.0)


def test_only_the_window_and_only_target_colours_count():
    bins = _grid()
    bins[0:2, 16:20] = 1       # the person's colour 2 px past the window's reach (x 15..17.5)
    bins[24:28, 5:15] = 2      # below the person, inside the window: a colour absent from
    #                            the ring but only a trace of the target (0.01 * 3 bins < 1)
    e = back_projection_extent(bins, (0, 0), 1, (5.0, 4.0, 10.0, 20.0), Q, O, 0.1)
    # window x in [4, 16), y in [2, 26): the blob at x 16..19 is out, the rectangle is all in
    assert e.width == pytest.approx(10.0) and e.height == pytest.approx(20.0)
    # with a margin reaching it, the blob's 8 samples (x 16.5..19.5, y 0.5, 1.5) join
    wide = back_projection_extent(bins, (0, 0), 1, (5.0, 4.0, 10.0, 20.0), Q, O, 0.5)
    assert wide.cy == pytest.approx((200 * 14.0 + 4 * 0.5 + 4 * 1.5) / 208)
    # a colour as frequent in the ring as on the target is not the target's
    assert back_projection_extent(bins, (0, 0), 1, (5.0, 4.0, 10.0, 20.0),
                                  np.array([0.5, 0.0, 0.5]), np.array([0.5, 0.0, 0.5]),
                                  0.25) is None


def _state(height: float = 40.0):
    return SimpleNamespace(scale=1.0, center=np.array([100.0, 100.0]),
                           box=(90.0, 100.0 - height / 2, 20.0, height),
                           centres=np.array([[100.0, 80.0], [100.0, 120.0]]))


CFG = MultiKernelConfig()          # max_scale_change 0.05, scale range [0.25, 4]


def test_extent_step_moves_the_scale_part_of_the_way():
    # extent 50 px over a 40 px box: goal scale 1.25; rate 0.1 -> 1 + 0.1 * 0.25 = 1.025
    state = _state()
    assert extent_step(state, Extent(100.0, 100.0, 20.0, 50.0, 0.8), 0.1, 0.3, CFG)
    assert state.scale == pytest.approx(1.025)
    # centres rescaled about the centroid: 20 px * 1.025 = 20.5 px from it
    assert state.centres == pytest.approx(np.array([[100.0, 79.5], [100.0, 120.5]]))
    # rate 0.4 would give 1.1: bounded by max_scale_change to 1.05
    state = _state()
    assert extent_step(state, Extent(100.0, 100.0, 20.0, 50.0, 0.8), 0.4, 0.3, CFG)
    assert state.scale == pytest.approx(1.05)


def test_extent_step_refuses_too_few_samples_and_outliers():
    e = Extent(100.0, 100.0, 20.0, 50.0, 0.2)
    state = _state()
    assert not extent_step(state, e, 0.1, 0.3, CFG)                   # 0.2 of the box < 0.3
    assert not extent_step(state, Extent(100.0, 100.0, 20.0, 50.0, 0.8), 0.1, 0.3, CFG,
                           max_ratio=1.2)                             # 50 / 40 = 1.25 > 1.2
    assert not extent_step(state, Extent(100.0, 100.0, 20.0, 30.0, 0.8), 0.1, 0.3, CFG,
                           max_ratio=1.2)                             # 40 / 30 = 1.33 > 1.2
    assert not extent_step(state, None, 0.1, 0.3, CFG)
    assert not extent_step(state, Extent(100.0, 100.0, 20.0, 50.0, 0.8), 0.0, 0.3, CFG)
    assert state.scale == 1.0
    assert state.centres == pytest.approx(np.array([[100.0, 80.0], [100.0, 120.0]]))


# -- in the tracker -------------------------------------------------------------------------

W, H = 320, 220


def _scene(seed: int) -> np.ndarray:
    """Grey noise; a person 30 x 80 px at x 120, y 60 (red top 40 px, blue legs 40 px)."""
    rng = np.random.default_rng(seed)
    img = np.repeat(rng.integers(90, 140, size=(H, W, 1)), 3, axis=2).astype(np.uint8)
    img[60:100, 120:150] = (30, 30, 220)
    img[100:140, 120:150] = (200, 60, 30)
    return img


def _run(rate: float, backend: str = "numpy", frames: int = 30):
    """Started on a box 20 px too tall (background above the head: 30 x 100 from y 40)."""
    cfg = MultiKernelConfig(background_weighting="cbwh", extent_scale_rate=rate,
                            extent_max_ratio=1.5)
    tracker = MultiKernelTracker(cfg, backend=backend)
    state = tracker.start(_scene(0), (120, 40, 30, 100))
    boxes = [tracker.refine(_scene(k), state, state.center).box for k in range(1, frames)]
    return state, np.array(boxes)


def test_a_box_started_too_tall_shrinks_to_the_person():
    grown, _ = _run(0.2)
    plain, _ = _run(0.0)
    # the person is 80 px tall (y 60..139); without the extent the box keeps most of its
    # 100 px
    assert grown.box[3] == pytest.approx(80.0, abs=4.0)
    assert plain.box[3] > 90.0


def test_backends_agree_with_the_extent_step():
    a, boxes_a = _run(0.2, "numpy", 12)
    b, boxes_b = _run(0.2, "compiled", 12)
    assert a.scale == pytest.approx(b.scale, abs=1e-9)
    assert boxes_a == pytest.approx(boxes_b, abs=1e-6)
    assert a.scale < 0.95                                  # it did act in these frames


def test_manual_track_setting_reaches_the_kernels():
    config = MultiObjectTrackerConfig()
    assert manual_track_multi_kernel(config).extent_scale_rate == 0.0
    from dataclasses import replace
    on = replace(config, manual_track=replace(config.manual_track, extent_scale_rate=0.05))
    assert manual_track_multi_kernel(on).extent_scale_rate == 0.05
    # tracks born from detections keep theirs
    assert on.multi_kernel.extent_scale_rate == 0.0
