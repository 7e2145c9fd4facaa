"""The search additions of the multiple-kernel tracker (issue #16): a start box reaching outside
the image, the coarse-to-fine start (``multi_start_radius``) and the failure re-search with the
colour back-projection (``recovery_similarity``), alone and inside a hand-started track.

Every oracle is a position computed by hand from the drawn scene: a two-colour target
(red upper half, blue lower half) on a grey, low-saturation noise background.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mk_tracker.tracking.manual_track import ManualTrackConfig, manual_track_multi_kernel
from mk_tracker.tracking.multi_kernel import MultiKernelConfig, MultiKernelTracker
from mk_tracker.tracking.multi_object_tracker import MultiObjectTracker, MultiObjectTrackerConfig
from mk_tracker.tracking.redetection import back_projection_peaks, grid_start

W, H = 320, 160
TW, TH = 20, 40          # target size


def _frame(positions, seed=0):
    """Grey noise background, and a 20x40 target (red top half, blue bottom half) with its
    top-left corner at each of ``positions``."""
    rng = np.random.default_rng(seed)
    grey = rng.integers(90, 140, size=(H, W, 1))
    img = np.repeat(grey, 3, axis=2).astype(np.uint8)
    for x, y in positions:
        img[y:y + TH // 2, x:x + TW] = (30, 30, 220)          # BGR red
        img[y + TH // 2:y + TH, x:x + TW] = (220, 60, 30)     # BGR blue
    return img


def _centre(res):
    x, y, w, h = res.box
    return np.array([x + w / 2.0, y + h / 2.0])


# -- start from a box reaching outside the image ---------------------------------------------

def test_a_box_reaching_outside_the_image_starts_on_its_visible_part():
    img = _frame([(0, 60)])
    tracker = MultiKernelTracker(MultiKernelConfig(num_kernels=6))
    # 40 px wide box, 30 px of it left of the image: the 6-kernel layout's left column
    # (x in [-30, -8]) would have no pixel at all
    state = tracker.start(img, (-30.0, 60.0, 40.0, 40.0))
    assert state.box == pytest.approx((0.0, 60.0, 10.0, 40.0))      # the clipped box
    assert np.all(state.models.sum(axis=1) > 0.99)                   # every kernel has a model


def test_a_box_entirely_outside_is_still_refused():
    from mk_tracker.tracking.multi_kernel import TrackingInputError
    with pytest.raises(TrackingInputError, match="entirely outside"):
        MultiKernelTracker().start(_frame([(0, 60)]), (-50.0, 60.0, 40.0, 40.0))


# -- coarse-to-fine start --------------------------------------------------------------------

def _jump(cfg, dx, dy=0):
    tracker = MultiKernelTracker(cfg)
    state = tracker.start(_frame([(100, 60)]), (100.0, 60.0, TW, TH))
    res = tracker.refine(_frame([(100 + dx, 60 + dy)], seed=1), state)
    return res


def test_a_target_beyond_the_kernels_reach_is_found_by_the_grid_start():
    # moved 30 px = 1.5 box widths: the 2 kernels (20 px wide) at the old place see none
    # of it; the 3x3 grid of radius 1.5 w has a point exactly on it -> centre (140, 80)
    res = _jump(MultiKernelConfig(multi_start_radius=1.5), 30)
    assert not res.lost
    assert _centre(res) == pytest.approx((140.0, 80.0), abs=1.5)
    assert res.similarity > 0.8


def test_without_the_grid_start_the_same_jump_is_missed():
    res = _jump(MultiKernelConfig(multi_start_radius=0.0), 30)
    assert res.lost or abs(_centre(res)[0] - 140.0) > 10.0


def test_the_grid_start_also_covers_vertical_motion():
    # 30 px down = 1.5 w (the grid spacing is in box widths on both axes)
    res = _jump(MultiKernelConfig(multi_start_radius=1.5), 0, 30)
    assert _centre(res) == pytest.approx((110.0, 110.0), abs=1.5)


def test_the_grid_start_keeps_the_prediction_when_the_target_is_there():
    tracker = MultiKernelTracker(MultiKernelConfig(multi_start_radius=1.5))
    state = tracker.start(_frame([(100, 60)]), (100.0, 60.0, TW, TH))
    search_img = _frame([(100, 60)], seed=1)
    region = (0, 0, W, H)
    search = tracker._search_region(search_img, region, 1)
    assert grid_start(tracker, search, state.centres, state, TW)[0] is None
    # a second copy of the target 1.5 w to the right scores the same: the tie keeps the
    # prediction (the first grid point examined)
    search2 = tracker._search_region(_frame([(100, 60), (130, 60)], seed=1), region, 1)
    assert grid_start(tracker, search2, state.centres, state, TW)[0] is None


# -- failure re-search -----------------------------------------------------------------------

def test_a_lost_target_far_away_is_found_by_the_back_projection_scan():
    # 150 px = 7.5 box widths away: beyond the grid, within a scan of 8 box sizes
    cfg = MultiKernelConfig(recovery_similarity=0.4, recovery_margin=8.0)
    res = _jump(cfg, 150)
    assert not res.lost
    assert _centre(res) == pytest.approx((260.0, 80.0), abs=1.5)


def test_without_the_re_search_the_far_target_is_not_found():
    res = _jump(MultiKernelConfig(recovery_similarity=0.0), 150)
    assert res.lost or abs(_centre(res)[0] - 260.0) > 10.0


def test_the_re_search_does_not_run_while_the_target_is_seen():
    tracker = MultiKernelTracker(MultiKernelConfig(recovery_similarity=0.4,
                                                   recovery_margin=8.0))
    state = tracker.start(_frame([(100, 60)]), (100.0, 60.0, TW, TH))
    calls = []
    original = tracker._recover
    tracker._recover = lambda *a: calls.append(a) or original(*a)
    tracker.refine(_frame([(103, 60), (250, 60)], seed=1), state)
    assert calls == []


def test_scan_peaks_are_ordered_and_a_box_apart():
    tracker = MultiKernelTracker(MultiKernelConfig(recovery_candidates=2,
                                                   recovery_scan_cells=10,
                                                   recovery_margin=6.0))
    state = tracker.start(_frame([(100, 60)]), (100.0, 60.0, TW, TH))
    img = _frame([(40, 60), (240, 60)], seed=2)
    img[60:100, 250:260] = 120              # the right copy is half covered (grey)
    # scan region: the box grown by 6 box sizes, x in [30, 290), y clipped to [0, 160)
    starts, _ = back_projection_peaks(tracker, img, state, (150.0, 60.0, TW, TH), 6.0)
    assert len(starts) == 2
    # stride ceil(20 / 10) = 2 px: the full copy's centre (50, 80) first, then the half
    # copy's visible half around (245, 80)
    assert starts[0] == pytest.approx((50.0, 80.0), abs=2.0)
    assert starts[1][0] == pytest.approx(245.0, abs=6.0)


def test_manual_track_settings_reach_the_multi_kernel_config():
    cfg = dataclasses.replace(MultiObjectTrackerConfig(), manual_track=ManualTrackConfig(
        multi_start_radius=0.75, recovery_similarity=0.3))
    mk = manual_track_multi_kernel(cfg)
    assert (mk.multi_start_radius, mk.recovery_similarity) == (0.75, 0.3)
    # tracks born from detections keep both off
    assert (cfg.multi_kernel.multi_start_radius, cfg.multi_kernel.recovery_similarity) == \
        (0.0, 0.0)


# -- inside a hand-started track (Kalman + multiple kernels, Sec. IV-D) ----------------------

def _follow(manual, step=22, frames=12, fps=7.0):
    """A target walking ``step`` px per frame to the right at ``fps``; returns the centre
    errors of a hand-started track."""
    cfg = dataclasses.replace(MultiObjectTrackerConfig(), manual_track=manual)
    tracker = MultiObjectTracker(cfg)
    tid = tracker.start_track(_frame([(20, 60)]), 0.0, (20.0, 60.0, TW, TH))
    errors = []
    for i in range(1, frames):
        x = 20 + step * i
        res = tracker.step(_frame([(x, 60)], seed=i), i / fps)
        box = next(t.box for t in res.tracks if t.id == tid)
        errors.append(abs(box[0] + box[2] / 2.0 - (x + TW / 2.0)))
    return np.array(errors)


def test_a_hand_started_track_follows_22_px_per_frame_at_7_fps():
    # 22 px per frame (1.1 box widths, 154 px/s) from a standing start: the kernels at the
    # prediction do not touch the target in the first frame, the grid start (0.5 w = 10 px
    # on each side) does; then the filter has learnt the velocity
    errors = _follow(ManualTrackConfig(num_kernels=2, multi_start_radius=0.5))
    assert errors.max() < 6.0


def test_without_the_grid_start_the_hand_started_track_falls_behind():
    errors = _follow(ManualTrackConfig(num_kernels=2, multi_start_radius=0.0,
                                       recovery_similarity=0.0))
    assert errors.max() > 10.0


def test_search_region_margin_and_extra_pixels():
    from mk_tracker.tracking.multi_kernel import _region
    # box x 10..20, y 10..30; margin 0.5 -> 5 px in x, 10 px in y; plus 5 px on every side
    assert _region((10.0, 10.0, 10.0, 20.0), 0.5, 100, 100, extra_px=5.0) == (0, 0, 30, 45)
    assert _region((10.0, 10.0, 10.0, 20.0), 0.5, 100, 100) == (5, 0, 25, 40)


def test_a_gated_grid_start_runs_only_when_the_first_search_fails(monkeypatch):
    import mk_tracker.tracking.multi_kernel as mk
    cfg = MultiKernelConfig(multi_start_radius=1.5, multi_start_similarity=0.4)
    calls = []
    for dx, expect_call in ((2, False), (30, True)):
        tracker = MultiKernelTracker(cfg)
        state = tracker.start(_frame([(100, 60)]), (100.0, 60.0, TW, TH))
        monkeypatch.setattr(mk, "grid_start",
                            lambda *a, _o=grid_start, _dx=dx: calls.append(_dx) or _o(*a))
        res = tracker.refine(_frame([(100 + dx, 60)], seed=1), state)
        assert (dx in calls) is expect_call
        # either way the target is found: centre (110 + dx, 80)
        assert _centre(res) == pytest.approx((110.0 + dx, 80.0), abs=1.5)
