"""The compiled footprint (a span flood fill, :func:`mk_tracker.detection.footprint._footprint_loops`)
against the numpy/OpenCV reference of :func:`~mk_tracker.detection.footprint.footprint_mask`
(``cv2.connectedComponents``) on shapes that a row-by-row fill can get wrong: holes,
U-shapes and spirals (runs that meet again from below), diagonal-only contacts (8-connectivity),
blobs cut by the patch's edges and by a Voronoi cell."""

import numpy as np
import pytest

import mk_tracker.detection.footprint as fp


def _compiled_and_reference(monkeypatch, frame, support, rows, cols, bounds, cell):
    if fp._footprint_kernel() is None:
        pytest.skip("numba not installed")
    args = (frame, np.float32(0.0), support, rows, cols, bounds, 2, np.float32(30.0), cell)
    stats = fp.footprint_stats(*args)
    fast = fp.footprint_mask(*args)
    with monkeypatch.context() as m:
        m.setattr(fp, "_FOOTPRINT", [None])
        ref = fp.footprint_mask(*args)
    return stats, fast, ref


def _assert_same(stats, fast, ref):
    assert (fast is None) == (ref is None)
    if ref is None:
        assert stats is None
        return
    assert fast[0] == ref[0]
    np.testing.assert_array_equal(fast[1], ref[1])
    fr, fc = np.nonzero(ref[1])
    y0, x0 = ref[0]
    obj = stats[2]
    assert obj.pixel_count == fr.size
    assert obj.box == (float(fc.min() + x0), float(fr.min() + y0),
                       float(fc.max() - fc.min() + 1), float(fr.max() - fr.min() + 1))
    assert obj.centroid == pytest.approx((fc.mean() + x0 + 0.5, fr.mean() + y0 + 0.5),
                                         abs=1e-9)


def _spiral(n):
    """A square spiral of warm pixels, one pixel wide, in an ``n x n`` patch."""
    img = np.zeros((n, n), dtype=bool)
    top, left, bottom, right = 0, 0, n - 1, n - 1
    while top <= bottom and left <= right:
        img[top, left:right + 1] = True
        img[top:bottom + 1, right] = True
        img[bottom, left:right + 1] = True
        img[top + 2:bottom + 1, left] = True
        top, left, bottom, right = top + 2, left + 2, bottom - 2, right - 2
        if top <= bottom:
            img[top - 1, left] = True        # the step into the next turn
    return img


@pytest.mark.parametrize("seed", range(12))
def test_compiled_footprint_equals_the_reference(monkeypatch, seed):
    rng = np.random.default_rng(seed)
    h, w = 60, 70
    warm = rng.random((h, w)) < 0.45                        # noise at the percolation edge
    if seed % 3 == 1:
        warm[10:50, 10:60] = _spiral(50)[:40, :50]
    if seed % 3 == 2:
        warm[:, :] = False
        warm[5:55, 20:25] = True                             # a U: two arms, one bottom
        warm[5:55, 45:50] = True
        warm[50:55, 20:50] = True
        warm[30, 26:44] = True                                # a bar joined by diagonals only
        warm[29, 25] = warm[31, 44] = True
    frame = np.where(warm, 200.0, 40.0).astype(np.float32)
    frame += rng.normal(0.0, 3.0, frame.shape).astype(np.float32)
    support = np.zeros((h, w), dtype=bool)
    support[rng.random((h, w)) < 0.05] = True
    support[20:40, 15:30] |= rng.random((20, 15)) < 0.5
    rows, cols = np.nonzero(support[15:45, 15:55])
    rows, cols = rows + 15, cols + 15
    bounds = (5, 55, 8, 66) if seed % 2 else (0, h, 0, w)
    cell = None
    if seed % 4 == 3:
        cell = fp._VoronoiCell(np.array([[30.0, 30.0], [52.0, 25.0], [20.0, 50.0]]), 0)
    _assert_same(*_compiled_and_reference(monkeypatch, frame, support, rows.astype(np.int64),
                                          cols.astype(np.int64), bounds, cell))


def test_compiled_footprint_of_nothing_warm_is_none(monkeypatch):
    frame = np.full((20, 20), 40.0, dtype=np.float32)
    support = np.zeros((20, 20), dtype=bool)
    support[8:12, 8:12] = True
    rows, cols = np.nonzero(support)
    stats, fast, ref = _compiled_and_reference(monkeypatch, frame, support, rows, cols,
                                               (0, 20, 0, 20), None)
    assert stats is None and fast is None and ref is None
