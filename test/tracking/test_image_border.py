"""The image border as an occluder (mk_tracker/tracking/image_border.py): the geometry with
hand-computed values, and hand-started tracks of a synthetic person entering at the left
edge and leaving at the right edge (``manual_track.border_person_aspect``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mk_tracker.boxes import clip_box, iou
from mk_tracker.tracking.image_border import (border_side, clip_to_image, complete_models,
                                              inside_fractions, overlaps_image,
                                              support_offsets, whole_person_box)
from mk_tracker.tracking.multi_kernel import MultiKernelConfig, MultiKernelTracker
from mk_tracker.tracking.multi_object_tracker import MultiObjectTracker
from mk_tracker.tracking.tracker_config import MultiObjectTrackerConfig
from mk_tracker.parameters import updated

W, H = 320, 240


# -- geometry ----------------------------------------------------------------------------------

def test_border_side():
    assert border_side((0, 10, 20, 100), W, 2.0) == "left"
    assert border_side((1.5, 10, 20, 100), W, 2.0) == "left"
    assert border_side((3, 10, 20, 100), W, 2.0) == ""
    assert border_side((300, 10, 20, 100), W, 2.0) == "right"      # x + w = 320
    assert border_side((0, 10, 320, 100), W, 2.0) == ""            # spans the image


def test_whole_person_box_extends_a_sliver_past_its_border():
    # left: 20 px of a 100 px high person, aspect 0.4 -> 40 px wide, inner edge at x = 20
    assert whole_person_box((0, 50, 20, 100), W, H, 0.4, 2.0) == \
        pytest.approx((-20.0, 50.0, 40.0, 100.0))
    # a box reaching outside is clipped first: (-5, 50, 25, 100) is (0, 50, 20, 100)
    assert whole_person_box((-5, 50, 25, 100), W, H, 0.4, 2.0) == \
        pytest.approx((-20.0, 50.0, 40.0, 100.0))
    # right: inner edge at x = 300 kept, 40 px wide
    assert whole_person_box((300, 50, 20, 100), W, H, 0.4, 2.0) == \
        pytest.approx((300.0, 50.0, 40.0, 100.0))
    # not a sliver: as wide as a person, or not at a border, or off
    assert whole_person_box((0, 50, 40, 100), W, H, 0.4, 2.0) is None
    assert whole_person_box((100, 50, 20, 100), W, H, 0.4, 2.0) is None
    assert whole_person_box((0, 50, 20, 100), W, H, 0.0, 2.0) is None


def test_inside_fractions_of_kernels_cut_by_the_border():
    centres = np.array([[0.0, 100.0], [100.0, 100.0], [-50.0, 100.0], [W, 100.0]])
    axes = np.full((4, 2), 20.0)
    f = inside_fractions(centres, axes, W, H)
    # half, all, none, half of each disc lies in the image
    assert f == pytest.approx([0.5, 1.0, 0.0, 0.5], abs=0.03)


def test_support_offsets_point_into_the_image_by_the_half_disc_centroid():
    lo, hi = np.array([0.0, 0.0]), np.array([float(W), float(H)])
    a = 30.0
    off = support_offsets(np.array([[0.0, 100.0], [100.0, 100.0], [W, 100.0]]),
                          np.full((3, 2), a), lo, hi)
    half_disc = 4.0 * a / (3.0 * math.pi)          # 12.73 px: centroid of a half disc
    assert off[0] == pytest.approx([half_disc, 0.0], abs=0.5)
    assert off[1] == pytest.approx([0.0, 0.0], abs=1e-9)
    assert off[2] == pytest.approx([-half_disc, 0.0], abs=0.5)


def test_complete_models_mixes_by_the_newly_seen_share():
    models = np.array([[1.0, 0.0], [1.0, 0.0], [1.0, 0.0]])
    seen = np.array([0.5, 0.5, 0.5])
    cand = np.array([[0.0, 1.0], [0.0, 1.0], [0.0, 1.0]])
    # kernel 0: in view 0.5 -> 1.0, seen: (0.5 q + 0.5 p) / 1.0; kernel 1: below the gate;
    # kernel 2: hardly more in view (0.51, gain below 0.02)
    n = complete_models(models, seen, cand, np.array([0.6, 0.2, 0.6]),
                        np.array([1.0, 1.0, 0.51]), gate=0.3)
    assert n == 1
    assert models[0] == pytest.approx([0.5, 0.5])
    assert models[1] == pytest.approx([1.0, 0.0]) and models[2] == pytest.approx([1.0, 0.0])
    assert seen == pytest.approx([1.0, 0.5, 0.5])


def test_clip_to_image_and_overlap():
    assert clip_to_image((-20, 50, 40, 100), W, H) == pytest.approx((0.0, 50.0, 20.0, 100.0))
    assert clip_to_image((-50, 50, 40, 100), W, H) == pytest.approx((-50.0, 50.0, 40.0, 100.0))
    assert overlaps_image((-20, 50, 40, 100), W, H)
    assert not overlaps_image((-40, 50, 40, 100), W, H)


def test_start_outside_lays_kernels_on_the_whole_box():
    img = _frame(-20.0)
    trk = MultiKernelTracker(MultiKernelConfig(num_kernels=2))
    st = trk.start(img, (-20.0, 70.0, 40.0, 100.0), outside=True)
    assert st.box == pytest.approx((-20.0, 70.0, 40.0, 100.0))
    assert st.seen == pytest.approx([0.5, 0.5], abs=0.03)
    clipped = trk.start(img, (-20.0, 70.0, 40.0, 100.0))        # the default: in-image part
    assert clipped.box == pytest.approx((0.0, 70.0, 20.0, 100.0))
    assert clipped.seen is None


# -- a synthetic person at the edges -----------------------------------------------------------

PERSON_W, PERSON_H, TOP = 40, 100, 70


def _frame(x: float, seed: int = 0) -> np.ndarray:
    """A 320 x 240 street: grey textured background, a person 40 x 100 px (red coat over
    blue trousers) whose left edge is at ``x`` (may be outside the image)."""
    rng = np.random.default_rng(seed)
    img = rng.integers(90, 140, (H, W, 3)).astype(np.uint8)
    x0, x1 = int(round(x)), int(round(x)) + PERSON_W
    a, b = max(x0, 0), min(x1, W)
    if b > a:
        img[TOP:TOP + 55, a:b] = (30, 30, 200)           # BGR red coat
        img[TOP + 55:TOP + PERSON_H, a:b] = (160, 60, 20)  # blue trousers
        noise = rng.integers(-15, 16, (PERSON_H, b - a, 3))
        img[TOP:TOP + PERSON_H, a:b] = np.clip(
            img[TOP:TOP + PERSON_H, a:b].astype(int) + noise, 0, 255).astype(np.uint8)
    return img


def _truth(x: float):
    """The annotated box: the person's part inside the image, None when out of it."""
    return clip_box((x, TOP, PERSON_W, PERSON_H), W, H)


def _run(xs, aspect: float):
    cfg = updated(MultiObjectTrackerConfig(), {"manual_track.border_person_aspect": aspect})
    tracker = MultiObjectTracker(cfg)
    tid = tracker.start_track(_frame(xs[0]), 0.0, _truth(xs[0]))
    tracker.step(_frame(xs[0]), 0.0)
    out = []
    for k, x in enumerate(xs[1:], start=1):
        res = tracker.step(_frame(x, seed=k), k / 25.0)
        mine = [t for t in res.tracks if t.id == tid]
        out.append(mine[0] if mine else None)
    return out


def test_person_entering_at_the_left_edge_is_followed_as_it_comes_into_view():
    # 16 px of the person visible in the first frame, then 3 px a frame to the right
    xs = [-24.0 + 3.0 * k for k in range(30)]
    got = _run(xs, 0.4)
    for k, t in enumerate(got, start=1):
        assert t is not None and t.state == "confirmed", (k, t)
        truth = _truth(xs[k])
        # the reported box is clipped to the image and grows with the visible part
        assert t.box[0] >= 0.0
        assert iou(t.box, truth) > 0.6, (k, t.box, truth)
    # once the person is in (k >= 8) the box is the person, within a few px
    last = got[-1].box
    assert last[0] == pytest.approx(xs[-1], abs=4.0)
    assert last[2] == pytest.approx(PERSON_W, abs=6.0)
    # and the reported width grew from the 16 px sliver
    assert got[0].box[2] < 26.0 < got[-1].box[2]
    # with the kernels laid out on the sliver only (the default) the box stays a sliver
    plain = _run(xs, 0.0)
    assert iou(plain[-1].box, _truth(xs[-1])) < 0.4


def test_person_leaving_at_the_right_edge_shrinks_then_ends():
    # fully in view at x = 260 (right edge 300), 4 px a frame out: gone from x = 320 (k = 15)
    xs = [260.0 + 4.0 * k for k in range(30)]
    got, plain = _run(xs, 0.4), _run(xs, 0.0)
    widths = []
    for k, t in enumerate(got, start=1):
        if _truth(xs[k]) is None:
            break
        assert t is not None, k
        assert t.box[0] >= 0.0 and t.box[0] + t.box[2] <= W + 1e-6     # clipped
        widths.append(t.box[2])
    # the reported box shrinks with the visible part (40 px -> under 20 px)
    assert widths[4] > 35.0 and widths[-1] < 20.0
    assert all(b <= a + 0.5 for a, b in zip(widths[5:], widths[6:]))
    # while the person goes out (k = 6..12: 36 -> 12 px visible) the clipped box matches
    # the annotation better than the whole-box report of the default
    on = [iou(got[k - 1].box, _truth(xs[k])) for k in range(6, 13)]
    off = [iou(plain[k - 1].box, _truth(xs[k])) for k in range(6, 13)]
    assert all(a >= b - 1e-9 for a, b in zip(on, off)) and np.mean(on) > np.mean(off) + 0.1
    # once the person is out the track is not confirmed, and it is lost once its box has
    # left the image (it never says "seen" at a stale place)
    out = got[15 - 1:]
    assert all(t is None or t.state != "confirmed" for t in out)
    assert any(t is None or t.state == "lost" for t in out)


def test_a_kernel_wholly_past_the_border_falls_back_to_the_visible_part():
    # 6 kernels (3 rows x 2 columns, Fig. 14b): a 10 px sliver of a 40 px person leaves the
    # outer column ([0, 0.55] of the width = 22 px) wholly outside the image, so that
    # kernel would have no model: the track starts on the visible part, as before
    cfg = updated(MultiObjectTrackerConfig(), {"manual_track.border_person_aspect": 0.4,
                                               "manual_track.num_kernels": 6})
    tracker = MultiObjectTracker(cfg)
    img = _frame(-30.0)
    tid = tracker.start_track(img, 0.0, (0.0, TOP, 10.0, PERSON_H))
    t = next(t for t in tracker.tracks if t.id == tid)
    assert t.box == pytest.approx((0.0, TOP, 10.0, PERSON_H))
    assert t.target.seen is None
    # with 2 full-width kernels the same sliver is laid out on the whole person
    cfg2 = updated(cfg, {"manual_track.num_kernels": 2})
    tracker2 = MultiObjectTracker(cfg2)
    tid2 = tracker2.start_track(img, 0.0, (0.0, TOP, 10.0, PERSON_H))
    t2 = next(t for t in tracker2.tracks if t.id == tid2)
    assert t2.box == pytest.approx((-30.0, TOP, 40.0, PERSON_H))
    # the visible 10 px are the last quarter of each 40 px wide kernel: the disc segment
    # beyond u = 0.5 of the half-axis, (acos(u) - u sqrt(1 - u^2)) / pi = 0.1955 of its area
    segment = (math.acos(0.5) - 0.5 * math.sqrt(0.75)) / math.pi
    assert t2.target.seen == pytest.approx([segment, segment], abs=0.01)
