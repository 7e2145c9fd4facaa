"""The scale step of the multiple-kernel tracker (eqs. (9)-(11), tracking/scale_estimation.py).

The acceptance rules and the three-scale test are checked with a stand-in kernel evaluation
whose costs are set by hand, so every expected scale below is computed by hand; the grey and
approaching-person cases run the real tracker.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from mk_tracker.parameters import ParameterError, updated, validate_config
from mk_tracker.synthetic.presets import approach_scene
from mk_tracker.tracking.multi_kernel import MultiKernelConfig, MultiKernelTracker
from mk_tracker.tracking.multi_object_tracker import (FrameDetection, MultiObjectTracker,
                                                      MultiObjectTrackerConfig)
from mk_tracker.tracking.scale_estimation import (ScaleEstimationConfig, fit_height,
                                                  scale_step)


def _state():
    """Two kernels, centroid (100, 100), at scale 1."""
    return SimpleNamespace(scale=1.0, center=np.array([100.0, 100.0]),
                           centres=np.array([[100.0, 80.0], [100.0, 120.0]]),
                           base_half_axes=np.array([[10.0, 20.0], [10.0, 20.0]]),
                           models=np.zeros((2, 4)))


def _evaluation(costs, ratios=(1e-5, 1e-5)):
    return SimpleNamespace(costs=np.asarray(costs, float),
                           scale_ratios=np.asarray(ratios, float))


def _evaluator(cost_of_scale):
    """A kernel evaluation whose per-kernel cost depends only on the kernels' scale (their
    half-axes over the base ones)."""
    def evaluate(search, axes, centres, models):
        s = float(axes[0, 1]) / 20.0
        c = cost_of_scale(s)
        return SimpleNamespace(costs=np.array([c, c]))
    return evaluate


def _config(**scale):
    return MultiKernelConfig(scale=ScaleEstimationConfig(**scale))


WEIGHTS = np.ones(2)


def test_gradient_step_on_a_tie_is_kept_by_not_higher_and_refused_by_lower():
    # r = (1e-5 + 1e-5) / 2 = 1e-5; beta r = 0.09, clipped to max_scale_change 0.05
    flat = _evaluator(lambda s: 0.5)                     # a bigger kernel matches as well
    state = _state()
    rec = scale_step(flat, None, state, WEIGHTS, _evaluation([0.5, 0.5]), _config(), 0.9)
    assert rec.reason == "kept" and state.scale == pytest.approx(1.05)
    assert rec.old_cost == pytest.approx(1.0) and rec.new_cost == pytest.approx(1.0)
    # the centres move away from the centroid with the scale: 100 -+ 20 * 1.05
    assert state.centres[:, 1] == pytest.approx([79.0, 121.0])
    state = _state()
    rec = scale_step(flat, None, state, WEIGHTS, _evaluation([0.5, 0.5]),
                     _config(acceptance="lower"), 0.9)
    assert rec.reason == "not_lower" and state.scale == 1.0
    assert state.centres[:, 1] == pytest.approx([80.0, 120.0])


def test_lower_acceptance_needs_the_margin():
    # cost 0.5 per kernel at scale 1, 0.497 at 1.05: 0.6 % lower
    ev = _evaluation([0.5, 0.5])
    cheaper = _evaluator(lambda s: 0.5 if s == 1.0 else 0.497)
    state = _state()
    rec = scale_step(cheaper, None, state, WEIGHTS, ev,
                     _config(acceptance="lower", min_relative_gain=0.01), 0.9)
    assert rec.reason == "not_lower" and state.scale == 1.0
    state = _state()
    rec = scale_step(cheaper, None, state, WEIGHTS, ev,
                     _config(acceptance="lower", min_relative_gain=0.005), 0.9)
    assert rec.reason == "kept" and state.scale == pytest.approx(1.05)


def test_three_scale_takes_the_best_of_three_smoothed_by_gamma():
    # cost per kernel (s - 1.2)^2 + 0.1: 0.14 at s = 1, 0.1625 at 0.95, 0.1225 at 1.05,
    # so s* = 1.05 and s = 1 + 0.5 (1.05 - 1) = 1.025
    bowl = _evaluator(lambda s: (s - 1.2) ** 2 + 0.1)
    state = _state()
    ev = _evaluation([0.14, 0.14], ratios=(-1e-5, -1e-5))   # (10) would shrink: ignored
    rec = scale_step(bowl, None, state, WEIGHTS, ev,
                     _config(method="three_scale", delta=0.05, gamma=0.5), 0.9)
    assert rec.reason == "kept" and state.scale == pytest.approx(1.025)
    assert rec.new_cost == pytest.approx(2 * 0.1225)
    # at the bottom of the bowl neither neighbour is lower: the scale stays
    state = _state()
    rec = scale_step(_evaluator(lambda s: (s - 1.0) ** 2 + 0.1), None, state, WEIGHTS,
                     _evaluation([0.1, 0.1]), _config(method="three_scale"), 0.9)
    assert rec.reason == "not_lower" and state.scale == 1.0


def test_checked_refuses_a_gradient_step_the_three_scale_test_contradicts():
    # (10) says grow (r > 0) but the cost is lowest below the current scale
    shrink = _evaluator(lambda s: (s - 0.8) ** 2 + 0.1)
    state = _state()
    ev = _evaluation([0.14, 0.14])
    rec = scale_step(shrink, None, state, WEIGHTS, ev, _config(method="checked"), 0.9)
    assert rec.reason == "disagree" and state.scale == 1.0
    grow = _evaluator(lambda s: (s - 1.2) ** 2 + 0.1)
    state = _state()
    rec = scale_step(grow, None, state, WEIGHTS, ev, _config(method="checked"), 0.9)
    assert rec.reason == "kept" and state.scale == pytest.approx(1.05)


def test_scale_settings_are_declared_and_validated():
    cfg = updated(MultiObjectTrackerConfig(), {"multi_kernel.scale.method": "three_scale",
                                               "max_refined_size_ratio": 1.5})
    assert cfg.multi_kernel.scale.method == "three_scale"
    with pytest.raises(ParameterError):
        validate_config(MultiKernelConfig(scale=ScaleEstimationConfig(method="bogus")))
    with pytest.raises(ParameterError):
        updated(MultiObjectTrackerConfig(), {"multi_kernel.scale.gamma": 2.0})


def _two_tone(size=(400, 400), bg=60, box=(180, 100, 60, 150)):
    """A grey 'person': bright upper half (200), dimmer lower half (130), on a dark wall."""
    im = np.full(size + (3,), bg, np.uint8)
    x, y, w, h = box
    im[y:y + h // 2, x:x + w] = 200
    im[y + h // 2:y + h, x:x + w] = 130
    return im


@pytest.mark.parametrize("scale", [dict(), dict(acceptance="lower"),
                                   dict(method="three_scale"), dict(method="checked")])
def test_grey_target_that_stands_still_keeps_its_size(scale):
    image = _two_tone()
    tracker = MultiKernelTracker(MultiKernelConfig(scale=ScaleEstimationConfig(**scale)))
    state = tracker.start(image, (180, 100, 60, 150))
    for _ in range(30):
        res = tracker.refine(image, state)
    assert not res.lost
    assert 0.95 <= state.scale <= 1.05
    assert abs(res.box[3] - 150.0) <= 0.05 * 150.0


@pytest.mark.parametrize("scale", [dict(), dict(acceptance="lower", min_relative_gain=0.01),
                                   dict(method="three_scale")])
def test_approaching_person_is_followed(scale):
    scene = approach_scene(frames=100)
    frames, truth = [], []
    for i in range(len(scene)):
        f = scene.frame(i)
        frames.append(f.rgb)
        truth.append(f.object(1).box_rgb)
    growth = truth[-1][3] / truth[0][3]
    assert growth > 2.5                               # the person triples in height
    tracker = MultiKernelTracker(MultiKernelConfig(num_kernels=2,
                                                   scale=ScaleEstimationConfig(**scale)))
    state = tracker.start(frames[0], truth[0])
    for frame in frames[1:]:
        tracker.refine(frame, state)
    # measured: the box reaches 2.3-2.4 x of the 3.07 x (0.75-0.78 of the growth) with every
    # method; without the scale update it would stay at 1
    assert state.scale > 0.65 * growth
    assert state.box[3] > 0.65 * truth[-1][3]


def test_fit_height_rescales_about_the_centroid_within_the_scale_range():
    image = _two_tone()
    tracker = MultiKernelTracker(MultiKernelConfig(max_scale=1.8))
    state = tracker.start(image, (180, 100, 60, 150))
    h0, c0 = state.box[3], state.center.copy()
    assert not fit_height(state, 0.5 * h0, 2.0 * h0, 0.25, 1.8)       # inside: unchanged
    assert fit_height(state, 1.5 * h0, 3.0 * h0, 0.25, 1.8)
    assert state.box[3] == pytest.approx(1.5 * h0) and state.scale == pytest.approx(1.5)
    assert state.center == pytest.approx(c0)
    assert fit_height(state, 4.0 * h0, 4.0 * h0, 0.25, 1.8)           # capped by max_scale
    assert state.scale == pytest.approx(1.8)


def _person_frame(box):
    im = np.full((480, 640, 3), 40, np.uint8)
    x, y, w, h = (int(round(v)) for v in box)
    im[y:y + h // 2, x:x + w] = (40, 40, 220)
    im[y + h // 2:y + h, x:x + w] = (200, 80, 20)
    return im


def _tracked(config, frames=6):
    trk = MultiObjectTracker(config)
    box = (300.0, 150.0, 40.0, 100.0)
    for i in range(frames):
        trk.step(_person_frame(box), i / 25.0, [FrameDetection(box, 0.9)])
    (t,) = [t for t in trk.tracks]
    assert t.target is not None and t.target.box[3] == pytest.approx(100.0, abs=1.0)
    return trk, t


@pytest.mark.parametrize("on", [False, True])
def test_a_detection_gives_the_kernels_its_size_only_when_asked(on):
    trk, t = _tracked(updated(MultiObjectTrackerConfig(),
                              {"refiner_size_from_detection": on}))
    big = (290.0, 120.0, 60.0, 150.0)
    # within appearance_update_interval: no refresh of the model, so only the option
    # changes the kernels' size
    trk.step(_person_frame(big), 6 / 25.0, [FrameDetection(big, 0.9)])
    expected = 150.0 if on else 100.0
    assert t.target.box[3] == pytest.approx(expected, abs=1.0)


def test_undetected_kernels_are_held_to_their_last_detected_size():
    trk, t = _tracked(updated(MultiObjectTrackerConfig(), {"max_refined_size_ratio": 1.5}))
    # the kernels have run away to 3 x the person (as on BU-TIV-lab's grey frames)
    fit_height(t.target, 300.0, 300.0, 0.25, 4.0)
    trk.step(_person_frame((300.0, 150.0, 40.0, 100.0)), 6 / 25.0, [])
    assert t.target.box[3] == pytest.approx(150.0, abs=1.0)
    assert t.refined_box is None or t.refined_box[3] == pytest.approx(150.0, abs=1.0)
