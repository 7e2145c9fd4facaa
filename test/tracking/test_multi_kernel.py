"""Mathematics and API of the projected-gradient multiple-kernel tracker (Chu 2013)."""

import numpy as np
import pytest

from mk_tracker.tracking.kernel_histograms import quantize
from mk_tracker.tracking.kernel_layouts import kernel_layout
from mk_tracker.tracking.multi_kernel import (MultiKernelConfig, MultiKernelTracker, TrackingInputError,
                                     adaptive_weights, evaluate_kernel,
                                     mean_shift_baseline_config, paper_config)
from mk_tracker.tracking.projected_gradient import (constraint_jacobian, constraint_projector,
                                                    constraint_thresholds, constraint_values,
                                                    kernel_pairs, pair_distances,
                                                    projected_gradient_step)
from mk_tracker.parameters import ParameterError


def _random_problem(rng, n_kernels, perturb=3.0):
    centres0 = rng.uniform(0, 100, size=(n_kernels, 2))
    pairs = kernel_pairs(n_kernels)
    lx, ly = pair_distances(centres0, pairs)
    centres = centres0 + rng.normal(0, perturb, size=centres0.shape)
    return centres, pairs, lx, ly


@pytest.mark.parametrize("n_kernels", [2, 4, 5, 6])
def test_step_components_are_orthogonal_and_dx_a_keeps_constraints(n_kernels):
    rng = np.random.default_rng(n_kernels)
    for _ in range(20):
        x, pairs, lx, ly = _random_problem(rng, n_kernels)
        jac = constraint_jacobian(x, pairs, lx, ly)
        c = constraint_values(x, pairs, lx, ly)
        jx = rng.normal(size=2 * n_kernels)
        w = adaptive_weights(rng.uniform(0.1, 1, n_kernels))
        dx_a, dx_b = projected_gradient_step(jx, jac, c, w)
        scale = np.linalg.norm(dx_a) * np.linalg.norm(dx_b) + 1e-12
        assert abs(dx_a @ dx_b) / scale < 1e-9                    # (B.1)
        assert np.max(np.abs(jac.T @ dx_a)) < 1e-9 * (1 + np.linalg.norm(jx))   # (B.3)
        assert (w.repeat(2) * jx) @ dx_a <= 1e-12                  # (B.2): descent direction
        assert np.all(np.isfinite(dx_a)) and np.all(np.isfinite(dx_b))


def test_dx_b_solves_the_linearised_constraints_when_full_rank():
    rng = np.random.default_rng(7)
    for _ in range(20):
        x, pairs, lx, ly = _random_problem(rng, 2)
        jac = constraint_jacobian(x, pairs, lx, ly)
        c = constraint_values(x, pairs, lx, ly)
        _, dx_b = projected_gradient_step(np.zeros(4), jac, c)
        assert np.allclose(jac.T @ dx_b, -c, atol=1e-9)            # (B.4)


@pytest.mark.parametrize("n_kernels", [2, 4, 6])
def test_repeated_dx_b_drives_the_constraints_to_zero(n_kernels):
    rng = np.random.default_rng(11)
    x, pairs, lx, ly = _random_problem(rng, n_kernels, perturb=4.0)
    start = np.max(np.abs(constraint_values(x, pairs, lx, ly)))
    for _ in range(30):
        jac = constraint_jacobian(x, pairs, lx, ly)
        c = constraint_values(x, pairs, lx, ly)
        _, dx_b = projected_gradient_step(np.zeros(2 * n_kernels), jac, c)
        x = x + dx_b.reshape(-1, 2)
    assert start > 0.01
    assert np.max(np.abs(constraint_values(x, pairs, lx, ly))) < 1e-6 * start


def test_moving_along_dx_a_changes_constraints_only_to_second_order():
    rng = np.random.default_rng(5)
    x, pairs, lx, ly = _random_problem(rng, 4, perturb=0.0)
    jac = constraint_jacobian(x, pairs, lx, ly)
    dx_a, _ = projected_gradient_step(rng.normal(size=8), jac, np.zeros(12))
    d = dx_a / np.linalg.norm(dx_a)
    changes = [np.max(np.abs(constraint_values(x + t * d.reshape(4, 2), pairs, lx, ly)))
               for t in (0.1, 0.2)]
    assert changes[1] == pytest.approx(4 * changes[0], rel=1e-3)   # quadratic in t
    # without the projection the change is first order and much larger
    raw, _ = projected_gradient_step(rng.normal(size=8), jac, np.zeros(12),
                                     use_projected_gradient=False)
    assert np.max(np.abs(jac.T @ raw)) > 1e-3


def test_rank_deficient_four_kernels_give_a_rank_six_projector():
    centres, _ = kernel_layout((10, 10, 40, 100), 4)
    pairs = kernel_pairs(4)
    lx, ly = pair_distances(centres, pairs)
    jac = constraint_jacobian(centres, pairs, lx, ly)
    assert jac.shape == (8, 12)
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.inv(jac.T @ jac)       # the paper's formula cannot be used as written
    proj, dx_b = constraint_projector(jac, constraint_values(centres, pairs, lx, ly))
    assert np.allclose(proj, proj.T) and np.allclose(proj @ proj, proj)
    assert np.trace(proj) == pytest.approx(6.0)   # x- and y-differences: 3 + 3
    assert np.allclose(dx_b, 0)


def test_stacked_kernels_with_zero_x_gradient_do_not_blow_up():
    centres, _ = kernel_layout((10, 10, 40, 100), 2)      # one above the other: L_x = 0
    pairs = kernel_pairs(2)
    lx, ly = pair_distances(centres, pairs)
    assert lx[0] == 0
    jac = constraint_jacobian(centres, pairs, lx, ly)
    assert np.all(jac[:, 0] == 0)                         # x-constraint gradient is zero
    jx = np.array([1.0, 2.0, -3.0, 0.5])
    dx_a, dx_b = projected_gradient_step(jx, jac, constraint_values(centres, pairs, lx, ly))
    assert np.all(np.isfinite(dx_a)) and np.allclose(dx_b, 0)
    # y-difference is kept, x moves freely: dy_1 == dy_2
    assert dx_a[1] == pytest.approx(dx_a[3])
    assert dx_a[0] == pytest.approx(-1.0) and dx_a[2] == pytest.approx(3.0)
    # a tiny x-offset: Newton on (x1-x2)^2 halves it, no jump
    x = centres + np.array([[1e-7, 0], [0, 0]])
    _, dx_b = projected_gradient_step(np.zeros(4), constraint_jacobian(x, pairs, lx, ly),
                                      constraint_values(x, pairs, lx, ly))
    assert np.max(np.abs(dx_b)) < 1e-6


def test_without_constraints_the_step_is_independent_mean_shift():
    jx = np.array([0.5, -2.0])
    dx_a, dx_b = projected_gradient_step(jx, np.zeros((2, 0)), np.zeros(0), alpha=1.0)
    assert np.allclose(dx_a, -jx) and np.allclose(dx_b, 0)      # eq. (6)


def test_constraint_thresholds_are_size_dependent():
    eps = constraint_thresholds(np.array([0.0, 50.0]), np.array([10.0, 100.0]), 1.0)
    assert eps[0] == pytest.approx(1.0)          # L = 0: (1^2)/1
    assert eps[2] == pytest.approx(101 / 2501)   # L = 50
    assert eps[3] < eps[1]


def test_adaptive_weights_sum_to_n_and_follow_similarity():
    w = adaptive_weights(np.array([0.9, 0.3, 0.6]))
    assert w.sum() == pytest.approx(3.0)
    assert w[0] / w[1] == pytest.approx(3.0)
    assert np.allclose(adaptive_weights(np.zeros(4)), 1.0)


def _smooth_scene(shift=(0, 0)):
    yy, xx = np.mgrid[0:240, 0:320].astype(np.float64)
    img = np.empty((240, 320, 3), np.uint8)
    img[..., 0] = 100 + 60 * np.sin(xx / 23.0)
    img[..., 1] = 110 + 60 * np.cos(yy / 19.0)
    img[..., 2] = 90
    x0, y0 = 140 + shift[0], 70 + shift[1]
    img[y0:y0 + 50, x0:x0 + 40] = (40, 40, 210)
    img[y0 + 50:y0 + 100, x0:x0 + 40] = (200, 90, 30)
    return img


def test_cost_does_not_increase_along_a_small_dx_a():
    cfg = MultiKernelConfig()
    tracker = MultiKernelTracker(cfg)
    state = tracker.start(_smooth_scene(), (140, 70, 40, 100))
    img = _smooth_scene((5, 3))
    bins = quantize(img, "hsv", cfg.bins)
    axes = state.half_axes

    def evaluate(x):
        return [evaluate_kernel(bins, (0, 0), x[i], axes[i], state.models[i]) for i in range(2)]

    x = state.centres
    ev = evaluate(x)
    w = adaptive_weights(np.array([e.similarity for e in ev]))
    j0 = float(np.sum(w * [e.cost for e in ev]))
    jx = -np.concatenate([e.mean_shift for e in ev])
    jac = constraint_jacobian(x, state.pairs, state.base_lx, state.base_ly)
    dx_a, _ = projected_gradient_step(jx, jac, constraint_values(x, state.pairs, state.base_lx,
                                                                 state.base_ly), w)
    for t in (0.25, 0.5):
        j1 = float(np.sum(w * [e.cost for e in evaluate(x + t * dx_a.reshape(2, 2))]))
        assert j1 < j0


# ---- tracker API ------------------------------------------------------------------------

def test_refine_follows_a_moving_target_and_reports_kernels():
    tracker = MultiKernelTracker(MultiKernelConfig(num_kernels=2, scale_update=False))
    state = tracker.start(_smooth_scene(), (140, 70, 40, 100))
    for k in range(1, 6):
        res = tracker.refine(_smooth_scene((3 * k, k)), state)
        assert not res.lost and res.reason == ""
    assert np.hypot(res.center[0] - (160 + 15), res.center[1] - (120 + 5)) < 3.0
    assert res.kernel_centres.shape == (2, 2) and res.kernel_axes.shape == (2, 2)
    assert res.weights.sum() == pytest.approx(2.0)
    assert 0.5 < res.similarity <= 1.0 and len(res.kernel_similarities) == 2
    assert np.allclose(state.centres, res.kernel_centres)   # state mutated on success


def test_predicted_center_initialises_the_search():
    tracker = MultiKernelTracker(MultiKernelConfig(scale_update=False))
    state = tracker.start(_smooth_scene(), (140, 70, 40, 100))
    img = _smooth_scene((40, 0))                   # a jump too large for the search region
    res = tracker.refine(img, state.copy(), predicted_center=(198, 120))
    assert np.hypot(res.center[0] - 200, res.center[1] - 120) < 3.0
    blind = tracker.refine(img, state.copy())
    assert np.hypot(blind.center[0] - 200, blind.center[1] - 120) > 10.0


def test_search_reads_no_pixel_outside_its_region():
    tracker = MultiKernelTracker(MultiKernelConfig(search_margin=0.3))
    clean = _smooth_scene((4, 2)).astype(np.float32)
    poisoned = clean.copy()
    # the search region is the box (140,70,40,100) grown by 30 %: x in [128,192), y in [40,200)
    poisoned[:, :127] = np.nan
    poisoned[:, 193:] = np.nan
    poisoned[:39] = np.nan
    poisoned[201:] = np.nan
    s1 = tracker.start(_smooth_scene(), (140, 70, 40, 100))
    s2 = s1.copy()
    a = tracker.refine(clean, s1)
    b = tracker.refine(poisoned, s2)
    assert not b.lost
    assert np.allclose(a.kernel_centres, b.kernel_centres)


def test_models_and_scale_change_only_above_the_gate():
    cfg = MultiKernelConfig(lost_similarity=0.0, model_update_rate=0.5)
    tracker = MultiKernelTracker(cfg)
    state = tracker.start(_smooth_scene(), (140, 70, 40, 100))
    models, scale = state.models.copy(), state.scale
    other = _smooth_scene()
    other[60:180, 120:200] = (0, 255, 0)           # the target painted over in green
    res = tracker.refine(other, state)
    assert res.similarity < cfg.similarity_gate and not res.lost
    assert np.array_equal(state.models, models) and state.scale == scale
    tracker.refine(_smooth_scene((1, 0)), state)
    assert not np.array_equal(state.models, models)


def test_lost_states_have_reasons_and_leave_the_state_alone():
    tracker = MultiKernelTracker()
    state = tracker.start(_smooth_scene(), (140, 70, 40, 100))
    before = state.centres.copy()
    res = tracker.refine(_smooth_scene(), state, predicted_center=(5000, 5000))
    assert res.lost and res.reason == "outside_image"
    nan_img = _smooth_scene().astype(np.float64)
    nan_img[100, 150] = np.nan
    res = tracker.refine(nan_img, state)
    assert res.lost and res.reason == "nan_pixels"
    gone = _smooth_scene()
    gone[:, :] = (0, 255, 0)
    gone[0, 0] = (0, 0, 0)
    res = tracker.refine(gone, state)
    assert res.lost and res.reason == "low_similarity" and res.similarity < 0.1
    assert np.array_equal(state.centres, before) and state.lost


@pytest.mark.parametrize("box", [(0, 0, 0, 10), (10, 10, 5, -2), (np.nan, 1, 2, 3), (),
                                 (1000, 1000, 20, 20), (-100, -100, 50, 50)])
def test_bad_boxes_raise_tracking_input_error(box):
    with pytest.raises(TrackingInputError):
        MultiKernelTracker().start(_smooth_scene(), box)


@pytest.mark.parametrize("backend", ["auto", "numpy"])
def test_a_box_clipped_to_a_sliver_raises_tracking_input_error(backend):
    # found by the property test's dev profile: (0, 16 - 2e-15, 16, 16) on a 16x16 image is
    # 1.8e-15 px high inside it, its kernels' half-axes are 0; the compiled backend raised
    # ZeroDivisionError instead of the documented "kernel with no pixel" error
    image = np.random.default_rng(0).integers(0, 256, (16, 16, 3), dtype=np.uint8)
    with pytest.raises(TrackingInputError, match="no pixel"):
        MultiKernelTracker(backend=backend).start(image, (0.0, 15.999999999999998, 16.0, 16.0))


def test_bad_images_and_uniform_targets_raise_tracking_input_error():
    tracker = MultiKernelTracker()
    with pytest.raises(TrackingInputError, match="uniform"):
        tracker.start(np.full((100, 100, 3), 77, np.uint8), (20, 20, 30, 60))
    nan_img = _smooth_scene().astype(np.float32)
    nan_img[80, 150] = np.nan
    with pytest.raises(TrackingInputError, match="NaN"):
        tracker.start(nan_img, (140, 70, 40, 100))
    with pytest.raises(TrackingInputError):
        tracker.start(np.zeros((100, 100), np.uint8), (20, 20, 30, 60))
    state = tracker.start(_smooth_scene(), (140, 70, 40, 100))
    with pytest.raises(TrackingInputError):
        tracker.refine(_smooth_scene(), state, predicted_center=(np.nan, 3))


def test_appearance_similarity_separates_target_from_background():
    tracker = MultiKernelTracker()
    img = _smooth_scene()
    state = tracker.start(img, (140, 70, 40, 100))
    assert tracker.appearance_similarity(img, state, (140, 70, 40, 100)) > 0.95
    assert tracker.appearance_similarity(img, state, (20, 60, 40, 100)) < 0.2
    assert tracker.appearance_similarity(img, state, (900, 900, 40, 100)) == 0.0
    with pytest.raises(TrackingInputError):
        tracker.appearance_similarity(img, state, (0, 0, 0, 0))


def test_config_is_validated_and_baseline_is_single_kernel():
    with pytest.raises(ParameterError):
        MultiKernelTracker(MultiKernelConfig(num_kernels=3))
    with pytest.raises(ParameterError):
        MultiKernelTracker(MultiKernelConfig(similarity_gate=1.5))
    base = mean_shift_baseline_config()
    assert base.num_kernels == 1 and base.pixel_weighting == "bhattacharyya"
    assert MultiKernelConfig().max_iterations == 5 and MultiKernelConfig().beta == 9e3
    assert paper_config().epsilon_j_factor == 0.7


# ---- the fast paths agree with their references -------------------------------------------

def _scaled_svd_reference(jac, values, tol=1e-6):
    """The projector and dx_B written out from numpy's pinv, independently of the module."""
    norms = np.linalg.norm(jac, axis=0)
    keep = norms > 1e-12 * max(norms.max(), 1.0)
    a = jac[:, keep] / norms[keep]
    b = values[keep] / norms[keep]
    pinv_t = np.linalg.pinv(a.T, rcond=tol)
    return a @ np.linalg.pinv(a, rcond=tol), -pinv_t @ b


@pytest.mark.parametrize("n_kernels", [2, 3, 4, 6])
def test_cached_projector_factors_equal_a_fresh_pseudo_inverse(n_kernels):
    rng = np.random.default_rng(20 + n_kernels)
    for trial in range(40):
        x, pairs, lx, ly = _random_problem(rng, n_kernels)
        if trial % 4 == 0:
            x[:, 0] = x[0, 0]                       # all stacked: zero x-gradients
        if trial % 4 == 1:
            x[1] = x[0]                             # two kernels on top of each other
        jac = constraint_jacobian(x, pairs, lx, ly)
        c = constraint_values(x, pairs, lx, ly)
        for _ in range(2):                          # the second call hits the cache
            proj, dx_b = constraint_projector(jac, c)
            ref_proj, ref_dx_b = _scaled_svd_reference(jac, c)
            assert np.allclose(proj, ref_proj, atol=1e-12)
            assert np.allclose(dx_b, ref_dx_b, atol=1e-10 * (1 + np.abs(ref_dx_b).max()))


def test_projector_of_a_general_matrix_is_not_taken_from_the_cache():
    rng = np.random.default_rng(3)
    for _ in range(10):
        jac = rng.normal(size=(6, 4))
        jac[:, 1] *= 1e-3
        c = rng.normal(size=4)
        proj, dx_b = constraint_projector(jac, c)
        ref_proj, ref_dx_b = _scaled_svd_reference(jac, c)
        assert np.allclose(proj, ref_proj, atol=1e-10) and np.allclose(dx_b, ref_dx_b)


def test_constraint_values_and_jacobian_follow_their_formulas():
    centres = np.array([[10.0, 20.0], [13.0, 60.0], [4.0, 41.0]])
    pairs = kernel_pairs(3)
    lx, ly = np.array([2.0, 5.0, 9.0]), np.array([30.0, 20.0, 19.0])
    c = constraint_values(centres, pairs, lx, ly)
    jac = constraint_jacobian(centres, pairs, lx, ly)
    # pair (0, 2): dx = 6, dy = -21
    assert c[2] == pytest.approx((36 - 25) / 26) and c[3] == pytest.approx((441 - 400) / 401)
    assert jac[0, 2] == pytest.approx(12 / 26) and jac[4, 2] == pytest.approx(-12 / 26)
    assert jac[1, 3] == pytest.approx(-42 / 401) and jac[5, 3] == pytest.approx(42 / 401)
    assert np.count_nonzero(jac) == 12


def _tracks(backend, n_kernels, frames):
    tracker = MultiKernelTracker(MultiKernelConfig(num_kernels=n_kernels), backend=backend)
    state = tracker.start(_smooth_scene(), (140, 70, 40, 100))
    out = []
    for k in range(1, frames + 1):
        res = tracker.refine(_smooth_scene((3 * k, k)), state)
        out.append(np.r_[res.box, res.similarity, res.cost, state.scale, res.iterations])
    return np.array(out), tracker.appearance_similarity(_smooth_scene((3 * frames, frames)),
                                                        state, (150, 75, 40, 100))


@pytest.mark.skipif(__import__("mk_tracker.tracking.search_region", fromlist=["x"]
                               ).compiled_kernels() is None, reason="numba not available")
@pytest.mark.parametrize("n_kernels", [1, 2, 4])
def test_compiled_and_numpy_trackers_give_the_same_results(n_kernels):
    a, sim_a = _tracks("compiled", n_kernels, 4)
    b, sim_b = _tracks("numpy", n_kernels, 4)
    assert np.allclose(a, b, rtol=0, atol=1e-6)
    assert sim_a == pytest.approx(sim_b, abs=1e-9) and sim_a > 0.5


def test_unknown_backend_is_a_tracking_input_error():
    with pytest.raises(TrackingInputError, match="backend"):
        MultiKernelTracker(backend="opencl")


@pytest.mark.skipif(__import__("mk_tracker.tracking.projected_gradient",
                               fromlist=["x"])._compiled_step() is None,
                    reason="numba not available")
@pytest.mark.parametrize("n_kernels", [2, 3, 4, 5, 6])
def test_compiled_closed_form_step_equals_the_svd_step(n_kernels):
    from mk_tracker.tracking.projected_gradient import _compiled_step
    step = _compiled_step()
    rng = np.random.default_rng(30 + n_kernels)
    pairs = kernel_pairs(n_kernels)
    for trial in range(60):
        start = rng.uniform(0, 100, size=(n_kernels, 2))
        if trial % 5 == 0:
            start[:, 0] = start[0, 0]                # stacked: L_x = 0 for every pair
        if trial % 7 == 0:
            start[1] = start[0]                      # two kernels with the same centre
        lx, ly = pair_distances(start, pairs)
        x = start + rng.normal(0, 3, size=start.shape) * (trial % 3 != 0)
        if trial % 11 == 0:
            x[:, 1] = x[0, 1]                        # every y-gradient zero
        jx = rng.normal(size=2 * n_kernels)
        w = adaptive_weights(rng.uniform(0.1, 1, n_kernels))
        for use_pg in (True, False):
            jac = constraint_jacobian(x, pairs, lx, ly)
            c = constraint_values(x, pairs, lx, ly)
            ref_a, ref_b = projected_gradient_step(jx, jac, c, w, 0.7, use_pg)
            values = np.empty(2 * len(pairs))
            dx_a, dx_b = np.empty(2 * n_kernels), np.empty(2 * n_kernels)
            step(np.ascontiguousarray(x), pairs, lx, ly, jx, w, 0.7, use_pg, values, dx_a, dx_b)
            assert np.allclose(values, c, rtol=0, atol=1e-12)
            assert np.allclose(dx_a, ref_a, rtol=0, atol=1e-9)
            assert np.allclose(dx_b, ref_b, rtol=0, atol=1e-9 * (1 + np.abs(ref_b).max()))


@pytest.mark.skipif(__import__("mk_tracker.tracking.projected_gradient",
                               fromlist=["x"])._compiled_step() is None,
                    reason="numba not available")
def test_no_frame_compiles_code_read_only_or_padded_images_included():
    from mk_tracker.tracking.search_region import compiled_kernels
    from mk_tracker.tracking.projected_gradient import _compiled_step
    tracker = MultiKernelTracker(MultiKernelConfig(num_kernels=4), backend="compiled")
    dispatchers = [*compiled_kernels(), _compiled_step()]
    before = [len(d.signatures) for d in dispatchers]
    assert all(n >= 1 for n in before)               # compiled with the tracker
    img = _smooth_scene()
    wide = np.zeros((240, 336, 3), np.uint8)
    wide[:, :320] = img
    padded = wide[:, :320]                            # rows with a padded stride
    read_only = img.copy()
    read_only.setflags(write=False)                   # like a ROS message buffer
    results = []
    for image in (img, padded, read_only):
        state = tracker.start(image, (140, 70, 40, 100))
        results.append(tracker.refine(_smooth_scene((3, 1)), state).box)
        results.append(tracker.refine(image, state).box)
    assert [len(d.signatures) for d in dispatchers] == before
    assert results[0::2] == [results[0]] * 3 and results[1::2] == [results[1]] * 3
