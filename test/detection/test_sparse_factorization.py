"""Coordinate descent of (3.7): exact 1-D updates, monotone cost, support recovery."""

import numpy as np
import pytest

from mk_tracker.detection.sparse_factorization import (FactorizationError, coordinate_cost,
                                             coordinate_minimizer, factorization_cost,
                                             largest_real_root, sparse_factorize,
                                             zero_factor_threshold)
from mk_tracker.detection import sparse_factorization as sf


def dense_min(c1, c2, lam, lo=-6.0, hi=6.0, n=40001):
    grid = np.linspace(lo, hi, n)
    cost = grid ** 4 + c1 * grid ** 2 + c2 * grid + lam * np.abs(grid)
    return cost.min(), grid[np.argmin(cost)]


@pytest.mark.parametrize("scale", [0.01, 1.0, 3.0])
def test_coordinate_update_attains_the_minimum_of_3_9(scale):
    rng = np.random.default_rng(int(scale * 100))
    n = 150
    c1 = rng.normal(0, 2, n) * scale
    c2 = rng.normal(0, 2, n) * scale
    c2[:20] = 0.0                       # symmetric case: two minimisers or zero
    lam = 0.3 * scale
    h = coordinate_minimizer(c1, c2, lam)
    for i in range(n):
        best, _ = dense_min(c1[i], c2[i], lam, -4 * max(scale, 1), 4 * max(scale, 1))
        got = coordinate_cost(np.array(h[i]), c1[i], c2[i], lam)
        assert got <= best + 1e-9, (c1[i], c2[i], h[i])


def test_minimizer_candidates_by_hand():
    # c1 = -2, c2 = 0, lambda = 0: J = h^4 - 2h^2, minima at +-1; the positive one is chosen
    assert coordinate_minimizer(np.array([-2.0]), np.array([0.0]), 0.0)[0] == pytest.approx(1.0)
    # c1 = 0, c2 = -4, lambda = 0: J' = 4h^3 - 4 = 0 -> h = 1
    assert coordinate_minimizer(np.array([0.0]), np.array([-4.0]), 0.0)[0] == pytest.approx(1.0)
    # same with c2 = +4 -> h = -1
    assert coordinate_minimizer(np.array([0.0]), np.array([4.0]), 0.0)[0] == pytest.approx(-1.0)
    # lambda larger than |c2| with c1 >= 0: zero
    assert coordinate_minimizer(np.array([1.0]), np.array([-0.5]), 1.0)[0] == 0.0


def test_largest_real_root_against_numpy_roots():
    rng = np.random.default_rng(7)
    p = rng.normal(0, 3, 500)
    q = rng.normal(0, 3, 500)
    got = largest_real_root(p, q)
    for i in range(500):
        r = np.roots([1.0, 0.0, p[i], q[i]])
        real = r[np.abs(r.imag) < 1e-7].real
        assert got[i] == pytest.approx(real.max(), abs=1e-7)


def test_zero_factor_threshold_is_tight():
    lam = 0.2
    t = zero_factor_threshold(lam)
    below, _ = dense_min(-2 * (t - 1e-4), 0.0, lam, -2, 2)
    above, _ = dense_min(-2 * (t + 1e-3), 0.0, lam, -2, 2)
    assert below >= -1e-12
    assert above < 0


def _random_sigma(rng, n_blocks, p, rank):
    a = rng.normal(size=(n_blocks, p, rank)) / np.sqrt(p)
    return a @ a.transpose(0, 2, 1) + 0.01 * np.eye(p)


@pytest.mark.parametrize("columns", [1, 2, 3])
def test_cost_never_increases_over_cycles(columns):
    rng = np.random.default_rng(columns)
    sigma = _random_sigma(rng, 12, 10, 3)
    res = sparse_factorize(sigma, 0.05, columns=columns, max_cycles=15, tol=1e-9,
                           record_cost=True, backend="numpy")
    hist = res.cost_history
    for b in range(hist.shape[0]):
        h = hist[b][~np.isnan(hist[b])]
        assert len(h) >= 3
        assert np.all(np.diff(h) <= 1e-12 * (1 + np.abs(h[:-1])))
        assert h[-1] < h[0]             # the factorization does something


def test_converged_factor_is_coordinate_wise_optimal():
    rng = np.random.default_rng(11)
    sigma = _random_sigma(rng, 1, 8, 2)[0]
    lam = 0.02
    res = sparse_factorize(sigma, lam, max_cycles=200, tol=1e-12, backend="numpy")
    m = res.factors[0, :, 0]
    for j in range(8):
        others = np.delete(m, j)
        c1 = 2 * np.sum(others ** 2) - 2 * sigma[j, j]
        c2 = -4 * np.dot(np.delete(sigma[j], j), others)
        best, _ = dense_min(c1, c2, lam, -3, 3)
        assert coordinate_cost(np.array(m[j]), c1, c2, lam) <= best + 1e-8


def test_block_diagonal_support_is_recovered():
    # two correlated groups (pixels 0-3 and 6-9), the rest uncorrelated and quiet
    p = 12
    sigma = np.diag(np.full(p, 0.01))
    sigma[np.ix_(range(4), range(4))] = 0.4
    sigma[np.ix_(range(6, 10), range(6, 10))] = 0.3
    res = sparse_factorize(sigma, 0.1, columns=2, backend="numpy")
    support = res.support()[0]
    expected = np.zeros(p, bool)
    expected[:4] = expected[6:10] = True
    np.testing.assert_array_equal(support, expected)
    # each column holds one group
    cols = [set(np.flatnonzero(res.factors[0, :, r])) for r in range(2)]
    assert {frozenset(c) for c in cols} == {frozenset(range(4)), frozenset(range(6, 10))}


def test_factorization_cost_by_hand():
    sigma = np.array([[1.0, 0.5], [0.5, 2.0]])
    m = np.array([1.0, -1.0])
    # residual [[0, 1.5], [1.5, 1]] -> 1.5^2 * 2 + 1 = 5.5; plus lambda * 2
    assert factorization_cost(sigma, m, 0.25) == pytest.approx(5.5 + 0.5)


@pytest.mark.skipif(sf._compiled_kernel() is None, reason="numba not installed")
@pytest.mark.parametrize("columns", [1, 2])
def test_compiled_backend_equals_numpy_backend(columns):
    rng = np.random.default_rng(20 + columns)
    sigma = _random_sigma(rng, 30, 16, 3)
    a = sparse_factorize(sigma, 0.05, columns=columns, backend="numpy")
    b = sparse_factorize(sigma, 0.05, columns=columns, backend="compiled")
    np.testing.assert_allclose(a.factors, b.factors, atol=1e-10)
    np.testing.assert_array_equal(a.cycles, b.cycles)


@pytest.mark.skipif(sf._compiled_kernel() is None, reason="numba not installed")
@pytest.mark.parametrize("columns", [1, 2])
def test_compiled_backend_reads_sigma_like_the_reference_when_it_is_not_symmetric(columns):
    """The compiled coordinate descent keeps Sigma M from Sigma's columns; on a Sigma that is
    not symmetric (as float rounding can leave it) it must still use the entries the numpy
    reference uses, row j for coordinate j: an asymmetry of 1e-2 would show."""
    rng = np.random.default_rng(40 + columns)
    sigma = _random_sigma(rng, 20, 16, 3)
    sigma = sigma + 1e-2 * np.triu(rng.normal(size=sigma.shape), 1)
    assert np.abs(sigma - sigma.transpose(0, 2, 1)).max() > 1e-3
    a = sparse_factorize(sigma, 0.05, columns=columns, backend="numpy")
    b = sparse_factorize(sigma, 0.05, columns=columns, backend="compiled")
    transposed = sparse_factorize(sigma.transpose(0, 2, 1), 0.05, columns=columns,
                                  backend="numpy")
    assert np.abs(a.factors - transposed.factors).max() > 1e-6     # the asymmetry matters
    np.testing.assert_allclose(a.factors, b.factors, atol=1e-10)
    np.testing.assert_array_equal(a.cycles, b.cycles)


def test_bad_inputs_raise_our_error():
    with pytest.raises(FactorizationError):
        sparse_factorize(np.full((3, 3), np.nan), 0.1)
    with pytest.raises(FactorizationError):
        sparse_factorize(np.eye(3), -1.0)
    with pytest.raises(FactorizationError):
        sparse_factorize(np.zeros((2, 3)), 0.1)
    with pytest.raises(FactorizationError):
        sparse_factorize(np.eye(3), 0.1, backend="gpu")


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_a_single_bad_entry_in_sigma_is_refused(bad):
    sigma = np.eye(3)
    sigma[1, 2] = bad
    with pytest.raises(FactorizationError):
        sparse_factorize(sigma, 0.1, backend="numpy")
    batch = np.stack([np.eye(3), sigma])            # one bad block in a batch
    with pytest.raises(FactorizationError):
        sparse_factorize(batch, 0.1, backend="numpy")


@pytest.mark.parametrize("lam", [np.nan, np.inf, -1e-9])
def test_bad_lambda_is_refused(lam):
    with pytest.raises(FactorizationError):
        sparse_factorize(np.eye(2), lam, backend="numpy")


@pytest.mark.parametrize("kwargs", [dict(columns=0), dict(max_cycles=0), dict(tol=-1e-9),
                                    dict(tol=float("nan"))])
def test_bad_settings_are_refused(kwargs):
    with pytest.raises(FactorizationError):
        sparse_factorize(np.eye(2), 0.1, backend="numpy", **kwargs)


def test_compiled_backend_without_numba_is_refused(monkeypatch):
    monkeypatch.setattr(sf, "_compiled_kernel", lambda: None)
    with pytest.raises(FactorizationError):
        sparse_factorize(np.eye(2), 0.1, backend="compiled")
    # "auto" falls back to the numpy reference
    res = sparse_factorize(np.diag([4.0, 1.0]), 0.0, backend="auto")
    np.testing.assert_allclose(res.factors[0, :, 0], [2.0, 0.0])


# Two blocks traced by hand with lambda = 0 (the plain rank-R fit, no sparsity term).
# diag(4, 1), one column, from M = 0:
#   j = 0: c1 = 0 - 2*4 = -8, c2 = 0 -> h^4 - 8 h^2, minimisers +-2, the positive one kept
#   j = 1: c1 = 2*4 - 2*1 = 6, c2 = -4 * Sigma(1,0) * 2 = 0 -> h = 0
#   cycle 2 changes nothing: ||M^2 - M^1|| = 0 <= tol, so 2 cycles, converged.
# [[1, 1], [1, 1]] = v v^T, v = (1, 1):
#   j = 0: c1 = -2, c2 = 0 -> h^4 - 2 h^2 -> h = 1
#   j = 1: c1 = 2*1 - 2*1 = 0, c2 = -4 * 1 * 1 = -4 -> 4 h^3 = 4 -> h = 1
#   cycle 2 changes nothing: 2 cycles, factor (1, 1), cost 0.
HAND_BLOCKS = [(np.diag([4.0, 1.0]), [2.0, 0.0], 1.0),
               (np.ones((2, 2)), [1.0, 1.0], 0.0)]


@pytest.mark.parametrize("backend", ["numpy", "auto"])
@pytest.mark.parametrize("sigma, factor, cost", HAND_BLOCKS)
def test_lambda_zero_by_hand(backend, sigma, factor, cost):
    res = sparse_factorize(sigma, 0.0, tol=1e-9, max_cycles=10, backend=backend)
    np.testing.assert_allclose(res.factors[0, :, 0], factor, atol=1e-12)
    assert res.cycles.tolist() == [2]
    assert res.converged.tolist() == [True]
    assert factorization_cost(sigma, res.factors[0], 0.0) == pytest.approx(cost, abs=1e-12)


def test_cycle_cap_stops_without_convergence():
    # diag(4, 1) needs a second cycle to see that nothing changes: one cycle is not enough
    res = sparse_factorize(np.diag([4.0, 1.0]), 0.0, max_cycles=1, backend="numpy")
    np.testing.assert_allclose(res.factors[0, :, 0], [2.0, 0.0])
    assert res.cycles.tolist() == [1] and res.converged.tolist() == [False]


def test_blocks_of_a_batch_keep_their_own_cycle_counts():
    # block 0 converges after 2 cycles (traced above); block 1 needs more: a batch must
    # stop updating block 0 and still report block 1's own count
    rng = np.random.default_rng(5)
    hard = _random_sigma(rng, 1, 8, 3)[0]
    alone = sparse_factorize(hard, 0.0, max_cycles=30, tol=1e-9, backend="numpy")
    assert alone.cycles[0] > 2
    batch = sparse_factorize(np.stack([np.diag([4.0] + [1.0] * 7), hard]), 0.0,
                             max_cycles=30, tol=1e-9, backend="numpy")
    assert batch.cycles.tolist() == [2, alone.cycles[0]]
    np.testing.assert_allclose(batch.factors[0, :, 0], [2.0] + [0.0] * 7, atol=1e-12)
    np.testing.assert_allclose(batch.factors[1], alone.factors[0], atol=1e-12)


def test_two_columns_by_hand():
    # diag(4, 1), lambda 0, two columns: column 0 takes pixel 0 (h = 2 as above); column 1
    # at pixel 0 sees the residual 4 - 2^2 = 0, so stays 0; at pixel 1 column 0 sees
    # c1 = 2*4 - 2*1 = 6 -> 0, column 1 sees c1 = 0 - 2*1 = -2 -> h = 1.  M = [[2, 0], [0, 1]]
    # fits exactly; cycle 2 changes nothing.
    for backend in ("numpy", "auto"):
        res = sparse_factorize(np.diag([4.0, 1.0]), 0.0, columns=2, tol=1e-9, backend=backend)
        np.testing.assert_allclose(res.factors[0], [[2.0, 0.0], [0.0, 1.0]], atol=1e-12)
        assert res.cycles.tolist() == [2]


def _call_block(sigma, lam, n_cols, max_cycles, tol):
    """The fused per-block factoriser (compiled when numba is there, else plain Python)."""
    block = sf.compiled_block_factorizer() or sf._factorize_block
    p = sigma.shape[0]
    m = np.zeros((p, n_cols))
    cycles, converged = block(np.ascontiguousarray(sigma.T), m, np.zeros((n_cols, p)),
                              np.zeros(n_cols), np.zeros((n_cols, n_cols)), lam, n_cols,
                              max_cycles, tol)
    return m, int(cycles), bool(converged)


@pytest.mark.parametrize("lam,tol,max_cycles", [(0.05, 1e-6, 12), (0.2, 1e-2, 10),
                                                (0.02, 1e-9, 3)])
def test_lockstep_factorizer_equals_one_block_at_a_time(lam, tol, max_cycles):
    """The lock-step factoriser of the detector's block loop gives every block exactly the
    factor of the one-block loop (bit for bit), also when the blocks stop after different
    numbers of cycles or hit max_cycles, with fewer blocks than scratch slots; and the
    numpy reference's factor to 1e-9.  Both branches of the root are taken: a block's first
    step has ``c2 = 0`` and ``disc = lambda^2/64 - Sigma(0, 0)^3/27 <= 0`` (trigonometric)
    for these lambdas, later steps mostly ``disc > 0`` (Cardano)."""
    rng = np.random.default_rng(int(lam * 1000) + max_cycles)
    sigmas = np.concatenate([_random_sigma(rng, 7, 16, 1), 3.0 * _random_sigma(rng, 6, 16, 2),
                             0.2 * _random_sigma(rng, 6, 16, 3)])
    lockstep = sf.compiled_lockstep_factorizer() or sf._factorize_blocks_one_column
    slots = 24
    m = np.zeros((slots, 16))
    lockstep(np.ascontiguousarray(sigmas.transpose(0, 2, 1)), m, np.zeros((slots, 16)),
             sigmas.shape[0], lam, max_cycles, tol, np.zeros(slots), np.zeros(slots),
             np.zeros(slots, dtype=np.int64), np.zeros((5, slots)))
    cycles = set()
    for b in range(sigmas.shape[0]):
        one, c, _ = _call_block(sigmas[b], lam, 1, max_cycles, tol)
        cycles.add(c)
        np.testing.assert_array_equal(m[b], one[:, 0])
    assert len(cycles) > 1                      # blocks stopped at different cycles
    assert np.count_nonzero(m) > 10
    assert not m[sigmas.shape[0]:].any()         # slots beyond n untouched
    ref = sparse_factorize(sigmas, lam, columns=1, max_cycles=max_cycles, tol=tol,
                           backend="numpy")
    np.testing.assert_allclose(m[:sigmas.shape[0]], ref.factors[:, :, 0], atol=1e-9)


def test_cube_root_within_three_units_in_the_last_place_of_cbrt():
    """The inlined cube root of Cardano's branch (bit-pattern seed, three Halley steps)
    against the libm one over 600 orders of magnitude, both signs (outside 2^-600..2^600,
    where its steps would overflow, it is libm's); the special inputs (signed zeros,
    subnormals, infinities, NaN) are libm's."""
    rng = np.random.default_rng(11)
    w = np.exp(rng.uniform(-700.0, 700.0, 20000)) * rng.choice([-1.0, 1.0], 20000)
    w = np.concatenate([w, [1.0, -1.0, 8.0, -27.0, 0.001, 2.0 ** -1022, 1.7e308]])
    got = sf.cube_root(w)
    ref = np.cbrt(w)
    assert np.all(np.sign(got) == np.sign(w))
    assert np.max(np.abs(got - ref) / np.spacing(np.abs(ref))) <= 3.0
    assert np.mean(got == ref) > 0.3                 # often exactly libm's value
    np.testing.assert_allclose(sf.cube_root(np.array([8.0, -27.0, 0.001])), [2.0, -3.0, 0.1],
                               rtol=4e-16, atol=0)
    special = np.array([0.0, -0.0, 5e-324, -1e-310, np.inf, -np.inf, np.nan])
    out = sf.cube_root(special)
    np.testing.assert_array_equal(out, np.cbrt(special))
    np.testing.assert_array_equal(np.signbit(out), np.signbit(np.cbrt(special)))


def test_scalar_cube_root_equals_the_array_one_bit_for_bit():
    """The scalar cube root (compiled, and its Python source run as it is) gives the array
    version's bits in its own range, so the numpy reference and the compiled loops take the
    same roots; outside it both hand over to a cbrt (numba's libm call and numpy's may
    differ in the last place, as they did before)."""
    sf._compiled_kernel()
    rng = np.random.default_rng(12)
    w = np.concatenate([np.exp(rng.uniform(-60.0, 60.0, 3000)) * rng.choice([-1.0, 1.0], 3000),
                        [2.0 ** 600, -(2.0 ** -600)]])
    outside = np.array([0.0, -0.0, 5e-324, 1e300, -1e-200, np.inf, -np.inf])
    fns = [sf._cube_root]
    if hasattr(sf._cube_root, "py_func"):
        fns.append(sf._cube_root.py_func)
    for fn in fns:
        got = np.array([fn(float(v)) for v in w])
        np.testing.assert_array_equal(got.view(np.int64), sf.cube_root(w).view(np.int64))
        got = np.array([fn(float(v)) for v in outside])
        np.testing.assert_allclose(got, np.cbrt(outside), rtol=3e-16, atol=0)
        np.testing.assert_array_equal(np.signbit(got), np.signbit(outside))


def test_plain_lockstep_factorizer_equals_the_compiled_one():
    """The Python source of the lock-step loop (what numba compiles) run uncompiled gives
    the compiled result: the two cannot drift apart."""
    compiled = sf.compiled_lockstep_factorizer()
    if compiled is None:
        pytest.skip("numba not installed")
    rng = np.random.default_rng(7)
    sigmas = _random_sigma(rng, 5, 9, 2)
    outs = []
    for fn in (compiled, compiled.py_func):
        m = np.zeros((5, 9))
        fn(sigmas, m, np.zeros((5, 9)), 5, 0.03, 10, 1e-6, np.zeros(5), np.zeros(5),
           np.zeros(5, dtype=np.int64), np.zeros((5, 5)))
        outs.append(m)
    assert np.count_nonzero(outs[0]) > 5
    np.testing.assert_array_equal(outs[0], outs[1])


@pytest.mark.parametrize("n_cols", [1, 2])
def test_fused_block_factorizer_cycle_count_by_hand(n_cols):
    m, cycles, converged = _call_block(np.diag([4.0, 1.0]), 0.0, n_cols, 10, 1e-9)
    assert (cycles, converged) == (2, True)
    expected = [[2.0], [0.0]] if n_cols == 1 else [[2.0, 0.0], [0.0, 1.0]]
    np.testing.assert_allclose(m, expected, atol=1e-12)
    m, cycles, converged = _call_block(np.diag([4.0, 1.0]), 0.0, n_cols, 1, 1e-9)
    assert (cycles, converged) == (1, False)


@pytest.mark.parametrize("n_cols", [1, 2, 3])
def test_fused_block_factorizer_matches_the_reference(n_cols):
    rng = np.random.default_rng(60 + n_cols)
    sigmas = _random_sigma(rng, 6, 9, 3)
    sigmas = sigmas + 1e-2 * np.triu(rng.normal(size=sigmas.shape), 1)   # not symmetric
    ref = sparse_factorize(sigmas, 0.03, columns=n_cols, max_cycles=12, tol=1e-6,
                           backend="numpy")
    for b in range(sigmas.shape[0]):
        m, cycles, converged = _call_block(sigmas[b], 0.03, n_cols, 12, 1e-6)
        np.testing.assert_allclose(m, ref.factors[b], atol=1e-10)
        assert cycles == ref.cycles[b] and converged == ref.converged[b]


def test_plain_python_loops_match_the_reference():
    """The loops that numba compiles, run as they are (so that their arithmetic is tested
    where numba is absent or disabled, e.g. MK_TRACKER_NO_NUMBA=1 in make mutation)."""
    rng = np.random.default_rng(70)
    sigmas = _random_sigma(rng, 5, 7, 2)
    for n_cols in (1, 2):
        ref = sparse_factorize(sigmas, 0.05, columns=n_cols, max_cycles=8, tol=1e-6,
                               backend="numpy")
        out, cycles, converged = sf._factorize_loops(sigmas, 0.05, n_cols, 8, 1e-6)
        np.testing.assert_allclose(out, ref.factors, atol=1e-10)
        np.testing.assert_array_equal(cycles, ref.cycles)
        np.testing.assert_array_equal(converged, ref.converged)


def test_scalar_root_and_minimizer_match_the_vectorised_ones():
    rng = np.random.default_rng(80)
    p = np.concatenate([rng.normal(0, 3, 300), [0.0, -3.0, 3.0, 0.0]])
    q = np.concatenate([rng.normal(0, 3, 300), [0.0, 2.0, 0.0, -1.0]])
    roots = largest_real_root(p, q)
    for i in range(p.size):
        assert sf._root_scalar(p[i], q[i]) == pytest.approx(roots[i], abs=1e-9)
    c1 = np.concatenate([rng.normal(0, 2, 300), [-2.0, 0.0, 0.0, 1.0]])
    c2 = np.concatenate([rng.normal(0, 2, 300), [0.0, -4.0, 4.0, -0.5]])
    for lam in (0.0, 0.3):
        h = coordinate_minimizer(c1, c2, lam)
        for i in range(c1.size):
            assert sf._minimizer_scalar(c1[i], c2[i], lam) == pytest.approx(h[i], abs=1e-9)


def test_empty_batches():
    res = sparse_factorize(np.zeros((0, 3, 3)), 0.1, columns=2, backend="numpy")
    assert res.factors.shape == (0, 3, 2) and res.cycles.shape == (0,)
    res = sparse_factorize(np.zeros((2, 0, 0)), 0.1, backend="numpy", record_cost=True)
    assert res.factors.shape == (2, 0, 1)
    np.testing.assert_array_equal(res.cost_history[:, 0], [0.0, 0.0])


def test_coordinate_cost_by_hand():
    # h = -2, c1 = 1, c2 = 3, lambda = 0.5: 16 + 4 - 6 + 0.5 * 2 = 15
    assert coordinate_cost(np.array(-2.0), 1.0, 3.0, 0.5) == pytest.approx(15.0)
    # h = 0.5: 1/16 + 1/4 + 3/2 + 1/4 = 2.0625
    assert coordinate_cost(np.array(0.5), 1.0, 3.0, 0.5) == pytest.approx(2.0625)


@pytest.mark.parametrize("lam", [2.0, 5.0, 20.0])
def test_coordinate_update_with_a_large_lambda_attains_the_minimum(lam):
    # lambda above |c2| and 2: the shortcut that decides "0" without a root is exercised
    # on both sides of its threshold lambda - |c2| >= 2 (-c1/3)^(3/2)
    rng = np.random.default_rng(int(lam))
    c1 = rng.uniform(-40.0, 5.0, 300)
    c2 = rng.uniform(-lam, lam, 300)
    h = coordinate_minimizer(c1, c2, lam)
    nonzero = 0
    for i in range(c1.size):
        best, _ = dense_min(c1[i], c2[i], lam, -6.0, 6.0, 60001)
        got = coordinate_cost(np.array(h[i]), c1[i], c2[i], lam)
        assert got <= best + 1e-6, (c1[i], c2[i], h[i])
        assert sf._minimizer_scalar(c1[i], c2[i], lam) == pytest.approx(h[i], abs=1e-9)
        nonzero += h[i] != 0
    assert 0 < nonzero < c1.size                 # both outcomes occur


def _fact_error(**kwargs):
    sigma = kwargs.pop("sigma", np.eye(2))
    lam = kwargs.pop("lam", 0.1)
    with pytest.raises(FactorizationError) as info:
        sparse_factorize(sigma, lam, **kwargs)
    return str(info.value)


def test_factorization_error_messages():
    assert _fact_error(sigma=np.zeros((2, 3))) == "sigma must be (B, p, p), got shape (2, 3)"
    assert _fact_error(sigma=np.full((2, 2), np.nan)) == "sigma holds NaN or infinite values"
    assert _fact_error(lam=-1.0) == "lambda must be a finite non-negative number, got -1.0"
    assert _fact_error(columns=0) == "columns and max_cycles must be >= 1 and tol >= 0"
    assert _fact_error(backend="gpu") == "unknown backend 'gpu'"


def test_compiled_without_numba_message(monkeypatch):
    monkeypatch.setattr(sf, "_compiled_kernel", lambda: None)
    assert _fact_error(backend="compiled") == \
        "the compiled backend needs numba, which is not installed"


def test_defaults_are_ten_cycles_tol_1e_3_no_history():
    rng = np.random.default_rng(5)
    sigmas = _random_sigma(rng, 20, 8, 3)
    explicit = sparse_factorize(sigmas, 0.0, max_cycles=10, tol=1e-3, backend="numpy")
    default = sparse_factorize(sigmas, 0.0)
    np.testing.assert_allclose(default.factors, explicit.factors, atol=1e-10)
    assert default.cycles.tolist() == explicit.cycles.tolist()
    assert default.cost_history is None
    # the batch has blocks stopped by the cap of 10 cycles and blocks stopped by the
    # tolerance before it, so both defaults mattered
    assert (~default.converged & (default.cycles == 10)).any()
    assert (default.converged & (default.cycles < 10)).any()
    # tol = 0 is allowed: diag(4, 1) stops when a cycle changes nothing at all
    exact = sparse_factorize(np.diag([4.0, 1.0]), 0.0, tol=0.0, backend="numpy")
    assert exact.cycles.tolist() == [2] and exact.converged.tolist() == [True]


@pytest.fixture
def plain_compiled(monkeypatch):
    """The "compiled" backend with the uncompiled loops: the glue of sparse_factorize's
    compiled branch runs in Python, numba or not."""
    monkeypatch.setattr(sf, "_compiled_kernel", lambda: sf._factorize_loops)
    return sf


@pytest.mark.parametrize("columns", [1, 2])
def test_compiled_branch_glue_with_plain_loops(plain_compiled, columns):
    rng = np.random.default_rng(90 + columns)
    sigmas = _random_sigma(rng, 4, 6, 2)
    ref = sparse_factorize(sigmas, 0.05, columns=columns, max_cycles=7, tol=1e-5,
                           backend="numpy", record_cost=True)
    for backend in ("compiled", "auto"):
        got = sparse_factorize(sigmas, 0.05, columns=columns, max_cycles=7, tol=1e-5,
                               backend=backend)
        np.testing.assert_allclose(got.factors, ref.factors, atol=1e-10)
        np.testing.assert_array_equal(got.cycles, ref.cycles)
        np.testing.assert_array_equal(got.converged, ref.converged)
        assert got.converged.dtype == bool and got.cost_history is None
    # with a cost history the compiled branch records the first and the last cost
    hist = sparse_factorize(sigmas, 0.05, columns=columns, max_cycles=7, tol=1e-5,
                            backend="compiled", record_cost=True).cost_history
    assert hist.shape == (4, 8)
    np.testing.assert_allclose(hist[:, 0], ref.cost_history[:, 0])
    for b in range(4):
        c = ref.cycles[b]
        assert hist[b, c] == pytest.approx(ref.cost_history[b, c], rel=1e-12)
        assert np.isnan(np.delete(hist[b], [0, c])).all()
    assert plain_compiled.compiled_block_factorizer() is plain_compiled._factorize_block


# --- mutation testing (#18): cases that pin down details the tests above leave open -----

def _positive_stationary_point(p, q):
    """Largest root y > 0 of y^3 + p y + q where the cubic rises through 0 (a minimum of
    the quartic whose derivative it is), by bisection, or 0 if there is none: an oracle
    independent of the closed forms.  Beyond b = max(sqrt(-p/3), 0) the cubic increases;
    every root lies in |y| <= 1 + max(|p|, |q|) (Cauchy's bound)."""
    f = lambda y: y * y * y + p * y + q
    lo = np.sqrt(-p / 3.0) if p < 0 else 0.0
    hi = 1.0 + max(abs(p), abs(q))
    if f(lo) > 0:
        return 0.0
    for _ in range(400):
        mid = 0.5 * (lo + hi)
        if f(mid) > 0:
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


# (p, q, largest real root), each root derived by hand
HARD_CUBICS = [
    # y^3 + 1e-6 y + 0.5: y = -c + p/(3c) + O(p^2), c = cbrt(0.5); the "+ sqrt(D)" form
    # of Cardano loses everything here (-q/2 + sqrt(D) = 0 in floating point)
    (1e-6, 0.5, -0.5 ** (1.0 / 3.0) + 1e-6 / (3.0 * 0.5 ** (1.0 / 3.0))),
    # p >> q: y = -q/p - y^3/p = -q/p to 1e-24 relative; u - p/(3u) cancels almost
    # completely, so only the Newton polish makes the root accurate
    (1e8, 1.0, -1e-8),
    (1e12, 1.0, -1e-12),
    # (y - 1)^2 (y + 2) and (y - 15)^2 (y + 30): double largest roots, where fp ~ 0 and a
    # Newton step would divide rounding noise by ~0
    (-3.0, 2.0, 1.0),
    (-675.0, 6750.0, 15.0),
    # y^3 + y + 2 = (y + 1)(y^2 - y + 2); y^3 = 0
    (1.0, 2.0, -1.0),
    (0.0, 0.0, 0.0),
    # p = -3e-210 (m^3 ~ 5e-315, so -q/(2 m^3) overflows in the unused trigonometric branch)
    (-3e-210, 1e-5, -1e-5 ** (1.0 / 3.0)),
]


@pytest.mark.parametrize("p, q, root", HARD_CUBICS)
def test_largest_real_root_on_ill_conditioned_cubics(p, q, root):
    # the vectorised root raises no floating-point error (its unused branches divide by
    # zero, overflow and take 0/0 on these inputs)
    with np.errstate(divide="raise", invalid="raise", over="raise", under="ignore"):
        got = largest_real_root(np.array([p]), np.array([q]))[0]
        scalar = sf._root_scalar(p, q)
    assert got == pytest.approx(root, rel=1e-9, abs=1e-30)
    assert scalar == pytest.approx(root, rel=1e-9, abs=1e-30)


@pytest.mark.parametrize("a", [5.9, -5.9, 10.9, -10.9])
def test_largest_real_root_at_a_double_root(a):
    # (y - a)^2 (y + 2a) = y^3 - 3a^2 y + 2a^3: rounding can push the arccos argument
    # just outside [-1, 1] (it is exactly -1 or 1), which the clip must absorb
    p, q = -3.0 * a * a, 2.0 * a ** 3
    root = a if a > 0 else -2.0 * a
    assert largest_real_root(np.array([p]), np.array([q]))[0] == pytest.approx(root, abs=1e-6)
    assert sf._root_scalar(p, q) == pytest.approx(root, abs=1e-6)


def _exact_minimizer(c1, c2, lam):
    """Minimiser of h^4 + c1 h^2 + c2 h + lam |h| from the largest root of the derivative
    on the side of -c2 (bisection), compared with J(0) = 0."""
    a = abs(c2)
    y = _positive_stationary_point(0.5 * c1, 0.25 * (lam - a))
    if y <= 0 or y ** 4 + c1 * y * y + (lam - a) * y >= 0:
        return 0.0
    return -y if c2 > 0 else y


def test_coordinate_minimizer_computes_in_float64():
    # float32 inputs are converted, not computed in float32 (a float32 root is off by ~1e-8)
    c1 = np.array([-2.5, 1.3, -7.1, -0.3], np.float32)
    c2 = np.array([0.7, -3.3, 2.9, -1.1], np.float32)
    h = coordinate_minimizer(c1, c2, 0.1)
    assert h.dtype == np.float64
    for i in range(4):
        assert h[i] == pytest.approx(_exact_minimizer(float(c1[i]), float(c2[i]), 0.1),
                                     rel=1e-12)


@pytest.mark.parametrize("c2", [0.0, 1e-300, -1e-300, -10.0, 10.0])
def test_a_near_tie_with_zero_goes_to_zero(c2):
    # c1 = -6: t = 2 and the shortcut threshold is lambda - |c2| = 2 t^(3/2) = 4 sqrt(2);
    # one ulp below it h = -+sqrt(2) beats 0 by a few 1e-15 only, i.e. within the documented
    # tolerance 1e-15 (1 + |c1| + |c2|), so the tie rule returns 0 (a wrong sign of lambda
    # or a wrong tolerance, e.g. one that turns positive for |c2| > 1 + |c1|, returns it)
    lam = float(np.nextafter(abs(c2) + 4.0 * np.sqrt(2.0), 0.0))
    assert not lam - abs(c2) >= 4.0 * np.sqrt(2.0)          # the shortcut does not decide
    assert coordinate_minimizer(np.array([-6.0]), np.array([c2]), lam)[0] == 0.0
    assert sf._minimizer_scalar(-6.0, c2, lam) == 0.0


def test_scalar_minimizer_and_root_raise_no_floating_point_errors():
    # degenerate inputs: p = q = 0 (m = 0), c1 in [0, 1) (t = 0), c1 < 0 (t > 0)
    with np.errstate(all="raise"):
        assert sf._root_scalar(0.0, 0.0) == 0.0
        assert sf._root_scalar(0.0, -8.0) == pytest.approx(2.0)
        assert sf._minimizer_scalar(0.5, 0.0, 1.0) == 0.0
        assert sf._minimizer_scalar(0.0, 0.0, 0.0) == 0.0
        assert sf._minimizer_scalar(-2.0, 0.0, 0.0) == pytest.approx(1.0)
        assert sf._minimizer_scalar(-6.0, 0.0, 0.5) == pytest.approx(
            _exact_minimizer(-6.0, 0.0, 0.5), rel=1e-12)


def test_factorization_cost_of_one_block_is_a_scalar_in_float64():
    sigma = np.array([[1.0, 0.5], [0.5, 2.0]])
    cost = factorization_cost(sigma, np.array([1.0, -1.0]), 0.25)
    assert np.ndim(cost) == 0
    # float32 factors are converted first: M = 4097 (exact in float32) gives
    # M M^T = 16785409 > 2^24, which float32 would round to 16785408
    m32 = np.array([[4097.0]], np.float32)
    assert factorization_cost(np.zeros((1, 1)), m32, 0.5) == 16785409.0 ** 2 + 0.5 * 4097.0


def test_cost_history_has_one_column_per_possible_cycle():
    res = sparse_factorize(np.diag([4.0, 1.0]), 0.0, max_cycles=5, tol=1e-9,
                           record_cost=True, backend="numpy")
    # cost of M = 0: 16 + 1; after cycle 1 and 2 (M = (2, 0)): 1; cycles 3-5 not run
    np.testing.assert_array_equal(res.cost_history, [[17.0, 1.0, 1.0] + [np.nan] * 3])


def test_one_pixel_blocks_are_factorized():
    # p = 1: h^4 - 2 Sigma h^2 + lambda |h|, Sigma = 4, lambda = 0 -> h = 2; Sigma = 0 -> 0
    res = sparse_factorize(np.array([[[4.0]], [[0.0]]]), 0.0, tol=1e-9, backend="numpy")
    np.testing.assert_allclose(res.factors[:, :, 0], [[2.0], [0.0]], atol=1e-12)
    assert res.cycles.tolist() == [2, 1] and res.converged.tolist() == [True, True]


@pytest.mark.parametrize("shape", [(0, 3, 3), (2, 0, 0)])
def test_empty_blocks_report_no_cycle_and_no_convergence(shape):
    res = sparse_factorize(np.zeros(shape), 0.1, backend="numpy")
    assert res.cycles.tolist() == [0] * shape[0]
    assert res.converged.dtype == bool and res.converged.tolist() == [False] * shape[0]


@pytest.mark.parametrize("n_cols", [1, 2])
def test_fused_block_factorizer_with_tolerance_zero(n_cols):
    # tol = 0: diag(4, 1) stops once a cycle changes nothing (cycle 2), as the reference
    m, cycles, converged = _call_block(np.diag([4.0, 1.0]), 0.0, n_cols, 10, 0.0)
    assert (cycles, converged) == (2, True)


@pytest.fixture
def counting_compiled(monkeypatch):
    """Like plain_compiled, counting the calls of the (uncompiled) kernel."""
    calls = []

    def kernel(*args):
        calls.append(1)
        return sf._factorize_loops(*args)

    monkeypatch.setattr(sf, "_compiled_kernel", lambda: kernel)
    return calls


def test_backend_choice_with_a_compiled_kernel(counting_compiled):
    sigma = np.diag([4.0, 1.0, 0.5])
    sparse_factorize(sigma, 0.0, backend="numpy")
    assert counting_compiled == []                  # "numpy" means the reference
    sparse_factorize(sigma, 0.0, backend="auto")
    assert counting_compiled == [1]                 # "auto" compiles when it can ...
    res = sparse_factorize(sigma, 0.0, backend="auto", tol=1e-9, record_cost=True)
    assert counting_compiled == [1]                 # ... unless a cost history is asked
    # for: the reference records every cycle (the compiled branch only the first and last)
    np.testing.assert_array_equal(res.cost_history[0, :3], [16.0 + 1.0 + 0.25, 1.25, 1.25])


def test_compiled_block_factorizer_is_none_without_the_compiled_backend(monkeypatch):
    monkeypatch.setattr(sf, "_compiled_kernel", lambda: None)
    assert sf.compiled_block_factorizer() is None


def test_no_numba_environment_variable_disables_the_compiled_kernel(monkeypatch):
    # a fresh cache (the module caches its first answer); the compile step would rebind the
    # module's loop functions, so they are restored afterwards as well
    monkeypatch.setattr(sf, "_COMPILED", [])
    for name in ("_root_scalar", "_minimizer_scalar", "_factorize_block",
                 "_factorize_block_one_column"):
        monkeypatch.setattr(sf, name, getattr(sf, name))
    monkeypatch.setenv("MK_TRACKER_NO_NUMBA", "1")
    assert sf._compiled_kernel() is None
    assert sf._COMPILED == [None]
