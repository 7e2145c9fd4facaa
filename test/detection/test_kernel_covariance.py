"""The fast kernel covariance (3.5) against a naive reference, and the exact block skipping."""

import math

import numpy as np
import pytest

from mk_tracker.detection.kernel_covariance import (KernelCovarianceError, active_pixels,
                                          block_kernel_covariance, frame_blocks,
                                          pixel_kernel_variance, range_for_variance,
                                          variance_bound_from_range)
from mk_tracker.detection.sparse_factorization import sparse_factorize, zero_factor_threshold


def naive_kernel_covariance(block, sigma2):
    """(3.5) written out term by term: block is (F, p)."""
    n_frames, p = block.shape
    out = np.zeros((p, p))
    for i in range(p):
        for j in range(p):
            first = 0.0
            for t in range(n_frames):
                first += math.exp(-(block[t, i] - block[t, j]) ** 2 / (2 * sigma2))
            second = 0.0
            for t in range(n_frames):
                for u in range(n_frames):
                    second += math.exp(-(block[t, i] - block[u, j]) ** 2 / (2 * sigma2))
            out[i, j] = first / n_frames - second / n_frames ** 2
    return out


@pytest.mark.parametrize("n_frames,p,sigma2", [(2, 4, 0.01), (5, 9, 0.01), (4, 16, 0.1),
                                               (7, 6, 0.5)])
def test_fast_equals_naive(n_frames, p, sigma2):
    rng = np.random.default_rng(n_frames * 100 + p)
    blocks = rng.random((3, n_frames, p))
    blocks[1, :, : p // 2] = 0.3            # some constant pixels
    blocks[2] = (rng.random((n_frames, p)) > 0.5) * 0.9   # binary object/background switching
    fast64 = block_kernel_covariance(blocks, sigma2, dtype=np.float64)
    fast32 = block_kernel_covariance(blocks, sigma2)
    for b in range(3):
        ref = naive_kernel_covariance(blocks[b], sigma2)
        np.testing.assert_allclose(fast64[b], ref, atol=1e-12)
        np.testing.assert_allclose(fast32[b], ref, atol=2e-6)


def test_constant_pixel_has_zero_row_and_column():
    rng = np.random.default_rng(1)
    block = rng.random((1, 6, 5))
    block[0, :, 2] = 0.7
    sigma = block_kernel_covariance(block, 0.01, dtype=np.float64)[0]
    np.testing.assert_allclose(sigma[2], 0.0, atol=1e-15)
    np.testing.assert_allclose(sigma[:, 2], 0.0, atol=1e-15)
    assert np.abs(sigma[0]).max() > 1e-3


def test_binary_switching_pixel_variance_by_hand():
    # pixel 0 is 1.0 in one frame of four and 0 otherwise; with sigma2 tiny the kernel between
    # 0 and 1 is ~0, so Sigma(0,0) = 1 - (1^2 + 3^2)/16 = 6/16
    block = np.zeros((1, 4, 2))
    block[0, 0, 0] = 1.0
    sigma = block_kernel_covariance(block, 1e-4, dtype=np.float64)[0]
    assert sigma[0, 0] == pytest.approx(6 / 16)
    assert sigma[1, 1] == pytest.approx(0.0)


def test_pixel_kernel_variance_is_the_diagonal_and_mask_restricts_it():
    rng = np.random.default_rng(2)
    window = rng.random((5, 3, 4)).astype(np.float32)
    var = pixel_kernel_variance(window, 0.05)
    flat = window.reshape(5, -1).astype(np.float64)
    ref = np.diag(naive_kernel_covariance(flat, 0.05))
    np.testing.assert_allclose(var.reshape(-1), ref, atol=2e-6)
    mask = np.zeros((3, 4), bool)
    mask[1, 2] = True
    masked = pixel_kernel_variance(window, 0.05, mask=mask)
    assert masked[1, 2] == pytest.approx(var[1, 2])
    assert np.count_nonzero(masked) == 1


def test_range_bound_is_an_upper_bound_and_inverts():
    rng = np.random.default_rng(3)
    window = rng.normal(0.5, 0.03, (6, 20, 20)).astype(np.float32)
    var = pixel_kernel_variance(window, 0.01)
    bound = variance_bound_from_range(window.max(0) - window.min(0), 0.01)
    assert np.all(var <= bound + 1e-6)
    r = range_for_variance(0.2, 0.01)
    assert float(variance_bound_from_range(np.array([r]), 0.01)[0]) == pytest.approx(0.2)


def test_active_pixels_match_the_exact_diagonal():
    rng = np.random.default_rng(4)
    window = rng.normal(0.1, 0.02, (5, 12, 12)).astype(np.float32)
    window[2:, 3:6, 3:6] = 0.95           # an object arriving
    window[:, 9, 9] = [0.1, 0.6, 0.1, 0.6, 0.1]
    threshold = 0.2
    act = active_pixels(window, 0.01, threshold)
    exact = pixel_kernel_variance(window, 0.01) > threshold
    np.testing.assert_array_equal(act, exact)
    assert act[4, 4] and act[9, 9] and not act[0, 0]


def test_block_below_the_threshold_factors_to_exactly_zero():
    """The skip rule: every diagonal entry <= T(lambda) -> Algorithm 1 returns M = 0."""
    lam = 0.15
    t = zero_factor_threshold(lam)
    rng = np.random.default_rng(5)
    a = rng.normal(size=(16, 16))
    sigma = a @ a.T
    d = np.sqrt(np.diag(sigma))
    sigma = sigma / np.outer(d, d) * (t * 0.999)      # all diagonals just below T
    res = sparse_factorize(sigma, lam, backend="numpy")
    assert np.all(res.factors == 0)
    assert res.cycles[0] == 1
    sigma_above = sigma / 0.999 * 1.01
    res2 = sparse_factorize(sigma_above, lam, backend="numpy")
    assert np.any(res2.factors != 0)


def test_frame_blocks_layout():
    window = np.arange(2 * 4 * 6).reshape(2, 4, 6)
    blocks, (nby, nbx) = frame_blocks(window, 2)
    assert (nby, nbx) == (2, 3)
    # block (by=1, bx=2) covers rows 2-3, columns 4-5 of each frame, row-major
    np.testing.assert_array_equal(blocks[1 * 3 + 2, 1], [40, 41, 46, 47])
    with pytest.raises(KernelCovarianceError):
        frame_blocks(np.zeros((2, 5, 6)), 2)


def test_bad_inputs_raise_our_error():
    with pytest.raises(KernelCovarianceError):
        block_kernel_covariance(np.full((1, 3, 4), np.nan), 0.01)
    with pytest.raises(KernelCovarianceError):
        block_kernel_covariance(np.zeros((3, 4)), 0.01)
    with pytest.raises(KernelCovarianceError):
        block_kernel_covariance(np.zeros((1, 3, 4)), 0.0)
    with pytest.raises(KernelCovarianceError):
        active_pixels(np.zeros((3, 4)), 0.01, 0.1)


def test_level_table_path_equals_the_exponential_path():
    """Integer (mono8) windows: the table path gives (3.5) exactly, diagonal included."""
    from mk_tracker.detection.kernel_covariance import (block_kernel_covariance_levels,
                                              block_variance_levels, kernel_table)
    rng = np.random.default_rng(9)
    levels = rng.integers(0, 256, size=(4, 5, 9))
    levels[1, :, :3] = 17                       # constant pixels
    levels[2] = np.where(rng.random((5, 9)) > 0.5, 240, 20)
    table = kernel_table(255, 1 / 255, 0.01)
    fast = block_kernel_covariance_levels(levels, table)
    var = block_variance_levels(levels, table)
    for b in range(4):
        ref = naive_kernel_covariance(levels[b] / 255.0, 0.01)
        np.testing.assert_allclose(fast[b], ref, atol=1e-12)
        np.testing.assert_allclose(var[b], np.diag(ref), atol=1e-12)
    with pytest.raises(KernelCovarianceError):
        block_kernel_covariance_levels(levels, table[:100])


@pytest.mark.parametrize("n_frames, rho", [(4, 4), (6, 4), (2, 3), (5, 5), (3, 2), (4, 1)])
def test_vector_gather_covariance_equals_the_plain_python_loops(n_frames, rho):
    """The compiled (3.5) of a block of levels and its diagonal, whose look-ups are vector
    gathers (``_gather_add``, ``_gather_one_minus``: 8 lanes, then scalar for the rest of
    a row), equal bit for bit the same functions run as plain Python (one look-up and one
    addition at a time), also for rows not a multiple of 8 long and level differences of
    either sign."""
    from mk_tracker.detection import kernel_covariance as kc
    kernels = kc.compiled_level_kernels()
    if kernels is None:
        pytest.skip("numba not installed")
    rng = np.random.default_rng(n_frames * 10 + rho)
    p = rho * rho
    table = kc.kernel_table(300, 1.0 / 255.0, 0.01)
    same, cross = np.zeros((p, p)), np.zeros((p, p))
    for trial in range(4):
        x = rng.integers(0, 256, (n_frames, p)).astype(np.int32)
        if trial == 1:
            x[:, : p // 2] = x[0, : p // 2]            # pixels that do not change
        fast, slow = np.full((p, p), np.nan), np.full((p, p), np.nan)
        kernels["block_covariance"](x, table, same, cross, fast)
        kernels["block_covariance"].py_func(x, table, same.copy(), cross.copy(), slow)
        np.testing.assert_array_equal(fast, slow)
        assert np.array_equal(fast, fast.T)
        var_fast, var_slow = np.full(p, np.nan), np.full(p, np.nan)
        kernels["block_variance"](x, table, var_fast)
        kernels["block_variance"].py_func(x, table, var_slow)
        np.testing.assert_array_equal(var_fast, var_slow)
        np.testing.assert_allclose(var_fast, np.diag(fast), rtol=0, atol=1e-12)
    # and against the batch function on the same blocks
    blocks = rng.integers(0, 256, (3, n_frames, p)).astype(np.int32)
    batch = kc.block_kernel_covariance_levels(blocks, table)
    batch_var = kc.block_variance_levels(blocks, table)
    for b in range(3):
        one, var = np.empty((p, p)), np.empty(p)
        kernels["block_covariance"].py_func(blocks[b], table, same, cross, one)
        kernels["block_variance"].py_func(blocks[b], table, var)
        np.testing.assert_array_equal(batch[b], one)
        np.testing.assert_array_equal(batch_var[b], var)
