"""Colour histograms, K-L cost, mean-shift vector and scale ratio (Chu 2013 App. C, (9)-(10)):
the numpy reference (mk_tracker.tracking.kernel_histograms) and the fast path that must equal
it (mk_tracker.tracking.search_region)."""

import numpy as np
import pytest

from mk_tracker.tracking.kernel_histograms import (InvalidImageError, check_image, evaluate_kernel,
                                          kernel_histogram, kl_cost, mean_shift_vector,
                                          number_of_bins, pixel_weights, profile_values,
                                          quantize, roi_has_nan, sample_kernel, scale_ratio,
                                          similarity_from_cost)

BINS = (16, 8, 4)
M = number_of_bins(BINS)
RED = (0, 0, 255)
BLUE = (255, 0, 0)
GREY = (128, 128, 128)


def _image(h=120, w=160, colour=GREY):
    img = np.empty((h, w, 3), np.uint8)
    img[:] = colour
    return img


def test_hsv_quantisation_of_pure_colours():
    img = np.array([[RED, BLUE]], np.uint8)
    b = quantize(img, "hsv", BINS)
    # red: hue 0, full saturation and value
    assert b[0, 0] == (0 * 8 + 7) * 4 + 3
    # blue: OpenCV hue 120 of 180 -> bin 120*16//180 = 10
    assert b[0, 1] == (10 * 8 + 7) * 4 + 3
    assert quantize(img, "bgr", (4, 4, 4))[0, 0] == (0 * 4 + 0) * 4 + 3


def test_roof_profile_is_linear_with_constant_g():
    v = np.array([0.0, 0.25, 0.5, 0.99])
    k, g = profile_values(v, "roof")
    assert np.allclose(k, 1 - v) and np.allclose(g, 1.0)
    k, g = profile_values(v, "gaussian")
    assert np.all(np.diff(k) < 0) and np.allclose(g, 2 * k)


def test_histogram_weights_pixels_by_the_profile():
    img = _image(colour=BLUE)
    img[:, :80] = RED                   # left half red, right half blue
    bins = quantize(img, "hsv", BINS)
    centred = kernel_histogram(sample_kernel(bins, (0, 0), np.array([80.0, 60.0]),
                                             np.array([20.0, 20.0])), M)
    assert centred.sum() == pytest.approx(1.0)
    red_bin, blue_bin = bins[0, 0], bins[0, 159]
    assert centred[red_bin] == pytest.approx(0.5, abs=0.03)
    # moved right: blue dominates, and the few red pixels at the rim weigh little (k ~ 0)
    right = kernel_histogram(sample_kernel(bins, (0, 0), np.array([95.0, 60.0]),
                                           np.array([20.0, 20.0])), M)
    assert right[blue_bin] > 0.9


def test_kl_cost_and_similarity():
    rng = np.random.default_rng(1)
    q = rng.random(M)
    q /= q.sum()
    assert kl_cost(q, q) == pytest.approx(0.0, abs=1e-3)
    assert similarity_from_cost(kl_cost(q, q)) == pytest.approx(1.0, abs=1e-3)
    p = rng.random(M)
    p /= p.sum()
    assert kl_cost(q, p) > 0.1
    # a histogram that shares no bin with q: finite cost (smoothing), tiny similarity
    disjoint = np.zeros(M)
    disjoint[q.argmin()] = 1.0
    cost = kl_cost(np.eye(M)[q.argmax()], disjoint)
    assert np.isfinite(cost) and cost > 5
    assert 0.0 < similarity_from_cost(cost) < 0.01


def _blob_scene():
    rng = np.random.default_rng(3)
    img = rng.integers(90, 160, size=(120, 160, 3)).astype(np.uint8)
    img[:, :, 1] = img[:, :, 0]
    img[40:80, 70:100] = RED            # the target: a red block centred at (85, 60)
    return img


def test_mean_shift_points_to_the_weighted_mode():
    img = _blob_scene()
    bins = quantize(img, "hsv", BINS)
    axes = np.array([15.0, 20.0])
    q = kernel_histogram(sample_kernel(bins, (0, 0), np.array([85.0, 60.0]), axes), M)
    for offset in ([7.0, -5.0], [-6.0, 8.0], [0.0, 9.0]):
        start = np.array([85.0, 60.0]) + offset
        s = sample_kernel(bins, (0, 0), start, axes)
        p = kernel_histogram(s, M)
        m = mean_shift_vector(s, pixel_weights(s, q, p, 0.01), start)
        back = -np.asarray(offset)
        cos = m @ back / (np.linalg.norm(m) * np.linalg.norm(back))
        assert cos > 0.9 and np.linalg.norm(m) > 1.0


def test_mean_shift_is_zero_at_a_symmetric_mode():
    img = _blob_scene()
    bins = quantize(img, "hsv", BINS)
    axes = np.array([15.0, 20.0])
    centre = np.array([85.0, 60.0])
    s = sample_kernel(bins, (0, 0), centre, axes)
    q = kernel_histogram(s, M)
    m = mean_shift_vector(s, pixel_weights(s, q, q, 0.01), centre)
    assert np.linalg.norm(m) < 0.5


def _disc_scene(radius):
    yy, xx = np.mgrid[0:200, 0:200]
    img = _image(200, 200, BLUE)
    img[(xx + 0.5 - 100) ** 2 + (yy + 0.5 - 100) ** 2 < radius ** 2] = RED
    return quantize(img, "hsv", BINS)


def test_scale_ratio_sign_follows_the_size_change():
    axes = np.array([40.0, 40.0])
    centre = np.array([100.0, 100.0])
    q = kernel_histogram(sample_kernel(_disc_scene(30), (0, 0), centre, axes), M)
    ratios = {}
    for radius in (24, 30, 36):
        bins = _disc_scene(radius)
        s = sample_kernel(bins, (0, 0), centre, axes)
        p = kernel_histogram(s, M)
        ratios[radius] = scale_ratio(s, pixel_weights(s, q, p, 0.01), axes)
    assert ratios[36] > 0 > ratios[24]
    assert abs(ratios[30]) < 0.2 * min(abs(ratios[36]), abs(ratios[24]))


def test_a_kernel_outside_the_region_is_empty_not_an_error():
    bins = quantize(_image(), "hsv", BINS)
    q = np.full(M, 1.0 / M)
    ev = evaluate_kernel(bins, (0, 0), np.array([500.0, 500.0]), np.array([10.0, 10.0]), q)
    assert ev.similarity == 0.0 and ev.cost == np.inf and ev.n_pixels == 0
    assert np.all(ev.mean_shift == 0)


def test_sample_only_reads_the_roi_with_its_origin():
    img = _blob_scene()
    full = quantize(img, "hsv", BINS)
    roi = full[30:90, 60:110]
    a = sample_kernel(full, (0, 0), np.array([85.3, 60.7]), np.array([12.0, 18.0]))
    b = sample_kernel(roi, (60, 30), np.array([85.3, 60.7]), np.array([12.0, 18.0]))
    assert np.array_equal(a.bins, b.bins) and np.allclose(a.xs, b.xs) and np.allclose(a.k, b.k)


@pytest.mark.parametrize("bad", [np.zeros((10, 10), np.uint8), np.zeros((0, 5, 3), np.uint8),
                                 np.zeros((4, 4, 3), np.int64), [[1, 2, 3]]])
def test_bad_images_raise_our_error(bad):
    with pytest.raises(InvalidImageError):
        check_image(bad)


@pytest.mark.parametrize("stride", [1, 2, 3])
def test_template_fast_path_matches_the_direct_evaluation(stride):
    from mk_tracker.tracking.kernel_histograms import KernelTemplate, PaddedBins
    img = _blob_scene()
    origin = (8, 4)                          # ROI starts at image pixel (8, 4)
    roi = img[origin[1]::stride, origin[0]::stride]
    bins = quantize(roi, "hsv", BINS)
    axes = np.array([15.0, 20.0])
    q = kernel_histogram(sample_kernel(bins, origin, np.array([85.5, 60.5]), axes,
                                       stride=stride), M)
    template = KernelTemplate(axes, stride)
    padded = PaddedBins(bins, origin, stride, M, template.reach)
    right = origin[0] + stride * (bins.shape[1] - 1)
    bottom = origin[1] + stride * (bins.shape[0] - 1)
    # off-grid centres, one so close to the ROI corner that part of the kernel is outside
    for centre in ([85.5, 60.5], [71.3, 49.8], [30.9, 22.2], [right - 0.3, bottom + 0.4]):
        centre = np.array(centre)
        direct = evaluate_kernel(bins, origin, centre, axes, q, stride=stride)
        fast = padded.evaluate(template, centre, q)
        assert fast.n_pixels == direct.n_pixels > 0
        assert fast.cost == pytest.approx(direct.cost, abs=1e-12)
        assert np.allclose(fast.mean_shift, direct.mean_shift)
        assert fast.scale_ratio == pytest.approx(direct.scale_ratio, abs=1e-12)
    # a kernel too large for the padding is refused rather than read out of bounds
    with pytest.raises(ValueError, match="padding"):
        padded.evaluate(KernelTemplate(axes * 2, stride), np.array([40.5, 40.5]), q)


def test_batched_evaluation_equals_one_kernel_at_a_time():
    from mk_tracker.tracking.kernel_histograms import KernelTemplate, PaddedBins
    img = _blob_scene()
    stride = 2
    bins = quantize(img[::stride, ::stride], "hsv", BINS)
    axes = [np.array([15.0, 20.0]), np.array([9.0, 12.0]), np.array([6.0, 6.0])]
    centres = np.array([[85.3, 60.7], [70.1, 95.5], [900.0, 900.0]])   # the last is outside
    rng = np.random.default_rng(4)
    models = rng.random((3, M))
    models /= models.sum(axis=1, keepdims=True)
    templates = [KernelTemplate(a, stride) for a in axes]
    padded = PaddedBins(bins, (0, 0), stride, M, templates[0].reach)
    batch = padded.evaluate_many(templates, centres, models)
    for i in range(2):
        direct = evaluate_kernel(bins, (0, 0), centres[i], axes[i], models[i], stride=stride)
        assert batch[i].n_pixels == direct.n_pixels > 0
        assert batch[i].cost == pytest.approx(direct.cost, abs=1e-12)
        assert np.allclose(batch[i].p, direct.p)
        assert np.allclose(batch[i].mean_shift, direct.mean_shift)
        assert batch[i].scale_ratio == pytest.approx(direct.scale_ratio, abs=1e-12)
    assert batch[2].n_pixels == 0 and batch[2].similarity == 0.0


# -- compiled fast path (numba) against the numpy reference --------------------------------

from mk_tracker.tracking.kernel_histograms import bin_lookup_tables  # noqa: E402
from mk_tracker.tracking.search_region import (KernelBackendError, SearchRegion,  # noqa: E402
                                               compiled_kernels, quantize_region,
                                               resolve_backend)

needs_numba = pytest.mark.skipif(compiled_kernels() is None,
                                 reason="numba not installed or MK_TRACKER_NO_NUMBA set")


def test_lookup_tables_give_the_hsv_bins_of_opencv():
    import cv2
    rng = np.random.default_rng(8)
    img = rng.integers(0, 256, size=(64, 64, 3)).astype(np.uint8)
    hsv = cv2.cvtColor(img, cv2.COLOR_BGR2HSV).astype(np.int64)
    h_bin = np.minimum(hsv[..., 0] * 16 // 180, 15)
    expected = (h_bin * 8 + (hsv[..., 1] * 8 >> 8)) * 4 + (hsv[..., 2] * 4 >> 8)
    assert np.array_equal(quantize(img, "hsv", BINS), expected)
    assert bin_lookup_tables("bgr", (4, 4, 4))[0, 255] == 3 * 16
    with pytest.raises(ValueError):
        bin_lookup_tables("lab", BINS)


def test_backend_names_are_checked():
    assert resolve_backend("numpy") == "numpy"
    # "auto" is the compiled backend exactly when numba is installed and not disabled
    import importlib.util
    import os
    numba_on = (importlib.util.find_spec("numba") is not None
                and not os.environ.get("MK_TRACKER_NO_NUMBA"))
    expected_auto = "compiled" if numba_on else "numpy"
    assert resolve_backend("auto") == expected_auto
    with pytest.raises(KernelBackendError):
        resolve_backend("gpu")
    assert issubclass(KernelBackendError, ValueError)


def test_without_numba_auto_falls_back_and_compiled_is_refused():
    import os
    import subprocess
    import sys
    code = ("from mk_tracker.tracking.search_region import *\n"
            "assert compiled_kernels() is None and resolve_backend('auto') == 'numpy'\n"
            "try:\n    resolve_backend('compiled')\nexcept KernelBackendError:\n    print('refused')\n")
    env = dict(os.environ, MK_TRACKER_NO_NUMBA="1")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "refused"


@needs_numba
def test_compiled_hsv_bins_equal_opencv_on_every_colour():
    import cv2
    level = np.arange(256, dtype=np.uint8)
    img = np.empty((256, 256, 256, 3), np.uint8)
    img[..., 0] = level[:, None, None]
    img[..., 1] = level[None, :, None]
    img[..., 2] = level[None, None, :]
    img = img.reshape(4096, 4096, 3)
    # one bin per HSV level: the bin index spells out the converted pixel
    fast = quantize_region(img, (0, 0, 4096, 4096), 1, "hsv", (180, 256, 256), "compiled")
    hsv = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)
    for channel, shift in ((0, 16), (1, 8), (2, 0)):
        assert np.array_equal((fast >> shift) & 255, hsv[..., channel])


@needs_numba
@pytest.mark.parametrize("stride", [1, 2, 3])
def test_compiled_quantisation_equals_numpy(stride):
    rng = np.random.default_rng(stride)
    img = rng.integers(0, 256, size=(90, 130, 3)).astype(np.uint8)
    for region in [(0, 0, 130, 90), (stride * 3, stride * 2, 101, 77), (5, 7, 6, 8)]:
        for cs, bins in [("hsv", BINS), ("bgr", (4, 8, 2)), ("grey", (1, 1, 16))]:
            a = quantize_region(img, region, stride, cs, bins, "compiled")
            b = quantize_region(img, region, stride, cs, bins, "numpy")
            assert a.dtype == np.int32 and np.array_equal(a, b)
            x0, y0, x1, y1 = region
            assert np.array_equal(b, quantize(img[y0:y1:stride, x0:x1:stride], cs, bins))
    bad = img.astype(np.float32)
    bad[10, 10] = np.nan
    for backend in ("compiled", "numpy"):
        assert quantize_region(bad, (0, 0, 130, 90), 1, "hsv", BINS, backend) is None
        assert np.array_equal(quantize_region(img.astype(np.float64), (0, 0, 130, 90), 2,
                                              "hsv", BINS, backend),
                              quantize_region(img, (0, 0, 130, 90), 2, "hsv", BINS, "numpy"))


def _random_case(rng, trial):
    stride = int(rng.integers(1, 4))
    img = rng.integers(0, 256, size=(150, 200, 3)).astype(np.uint8)
    img[40:100, 60:120] = rng.integers(0, 256, 3)          # a blob so histograms differ
    x0 = int(rng.integers(0, 30)) // stride * stride
    y0 = int(rng.integers(0, 30)) // stride * stride
    bins = quantize_region(img, (x0, y0, 200, 150), stride, "hsv", BINS, "numpy")
    n_k = int(rng.integers(1, 6))
    axes = rng.uniform(2.0, 35.0, size=(n_k, 2))
    centres = rng.uniform(-20.0, 220.0, size=(n_k, 2))     # some kernels partly or all outside
    models = rng.random((n_k, M)) * (rng.random((n_k, M)) < 0.3)
    models /= models.sum(axis=1, keepdims=True)
    profile = PROFILES_[trial % 2]
    weighting = WEIGHTINGS_[(trial // 2) % 2]
    return bins, (x0, y0), stride, axes, centres, models, profile, weighting


PROFILES_ = ("roof", "gaussian")
WEIGHTINGS_ = ("kl", "bhattacharyya")


@needs_numba
def test_compiled_kernel_evaluation_equals_the_numpy_reference():
    rng = np.random.default_rng(12)
    seen_empty = seen_full = 0
    for trial in range(60):
        bins, origin, stride, axes, centres, models, profile, weighting = \
            _random_case(rng, trial)
        results = [SearchRegion(bins, origin, stride, M, profile, backend).evaluate(
            axes, centres, models, 0.01, weighting) for backend in ("compiled", "numpy")]
        a, b = results
        assert np.array_equal(a.n_pixels, b.n_pixels)
        assert np.array_equal(np.isinf(a.costs), a.n_pixels == 0)
        assert np.array_equal(np.isinf(b.costs), b.n_pixels == 0)
        seen_empty += int(np.sum(a.n_pixels == 0))
        seen_full += int(np.sum(a.n_pixels > 0))
        for name in ("p", "similarities", "mean_shift", "scale_ratios"):
            assert np.allclose(getattr(a, name), getattr(b, name), rtol=0, atol=1e-9), name
        fin = np.isfinite(b.costs)
        assert np.allclose(a.costs[fin], b.costs[fin], rtol=0, atol=1e-9)
    assert seen_empty > 0 and seen_full > 50      # both cases were exercised


def test_search_region_equals_the_direct_per_kernel_evaluation():
    from mk_tracker.tracking.kernel_histograms import evaluate_kernel
    rng = np.random.default_rng(13)
    for trial in range(12):
        bins, origin, stride, axes, centres, models, profile, weighting = \
            _random_case(rng, trial)
        centres = rng.uniform(40.0, 160.0, size=centres.shape)   # inside the ROI
        for backend in ("numpy", "auto"):
            batch = SearchRegion(bins, origin, stride, M, profile, backend).evaluate(
                axes, centres, models, 0.01, weighting)
            for i in range(len(axes)):
                d = evaluate_kernel(bins, origin, centres[i], axes[i], models[i],
                                    profile=profile, weighting=weighting, stride=stride)
                assert batch.n_pixels[i] == d.n_pixels
                if d.n_pixels == 0:                  # a thin kernel between grid nodes
                    assert batch.similarities[i] == 0.0 and np.isinf(batch.costs[i])
                    continue
                assert batch.costs[i] == pytest.approx(d.cost, abs=1e-9)
                assert np.allclose(batch.p[i], d.p, atol=1e-12)
                assert np.allclose(batch.mean_shift[i], d.mean_shift, atol=1e-9)
                assert batch.scale_ratios[i] == pytest.approx(d.scale_ratio, abs=1e-9)


@pytest.mark.parametrize("backend", ["numpy", "auto"])
def test_search_region_refuses_bins_and_models_that_do_not_fit(backend):
    from mk_tracker.tracking.search_region import BinMismatchError
    bins = quantize(_blob_scene(), "hsv", BINS)
    with pytest.raises(BinMismatchError):
        SearchRegion(bins, (0, 0), 1, 64, backend=backend)          # indices up to 511
    with pytest.raises(BinMismatchError):
        SearchRegion(bins - 600, (0, 0), 1, M, backend=backend)
    region = SearchRegion(bins, (0, 0), 1, M, backend=backend)
    with pytest.raises(BinMismatchError):
        region.evaluate(np.ones((2, 2)) * 10, np.ones((2, 2)) * 50, np.full((2, 64), 1 / 64))
    with pytest.raises(BinMismatchError):
        region.evaluate(np.ones((2, 2)) * 10, np.ones((3, 2)) * 50, np.full((2, M), 1 / M))
    assert issubclass(BinMismatchError, ValueError)


# -- the loops that numba compiles, run as plain Python -------------------------------------
# The tests above compare the compiled loops with the numpy reference only where numba is
# present and enabled; these run the same loop functions uncompiled (as make mutation does,
# with MK_TRACKER_NO_NUMBA=1), on inputs small enough for Python speed.

def _plain_quantize(img, region, stride, colour_space, bins):
    from mk_tracker.tracking import search_region as kh
    x0, y0, x1, y1 = region
    out = np.empty((-(-(y1 - y0) // stride), -(-(x1 - x0) // stride)), np.int32)
    return kh._quantize_loops(img, y0, x0, stride, kh._MODES[colour_space],
                              bin_lookup_tables(colour_space, bins), kh._SAT_RECIPROCAL,
                              kh._HUE_RECIPROCAL, out)


def test_plain_quantize_loops_give_the_hsv_of_opencv():
    import cv2
    rng = np.random.default_rng(31)
    colours = rng.integers(0, 256, size=(4096 - 45, 3))
    # ties for the maximum (greys, two equal channels), pure and dark colours
    special = [(0, 0, 0), (255, 255, 255), (7, 7, 7), (200, 200, 10), (10, 200, 200),
               (200, 10, 200), (255, 0, 0), (0, 255, 0), (0, 0, 255), (1, 0, 0), (0, 1, 2),
               (3, 2, 1), (255, 254, 0), (0, 254, 255), (254, 0, 255)]
    colours = np.vstack([colours, np.array(special * 3)])
    img = colours.astype(np.uint8).reshape(64, 64, 3)
    hsv = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)
    fast = _plain_quantize(img, (0, 0, 64, 64), 1, "hsv", (180, 256, 256))
    for channel, shift in ((0, 16), (1, 8), (2, 0)):
        assert np.array_equal((fast >> shift) & 255, hsv[..., channel]), channel


@pytest.mark.parametrize("stride", [1, 3])
def test_plain_quantize_loops_equal_the_numpy_quantisation(stride):
    rng = np.random.default_rng(40 + stride)
    img = rng.integers(0, 256, size=(30, 41, 3)).astype(np.uint8)
    for region in [(0, 0, 41, 30), (stride * 2, stride, 38, 29)]:
        x0, y0, x1, y1 = region
        for cs, bins in [("hsv", BINS), ("bgr", (4, 8, 2)), ("grey", (1, 1, 16))]:
            expected = quantize(img[y0:y1:stride, x0:x1:stride], cs, bins)
            assert np.array_equal(_plain_quantize(img, region, stride, cs, bins), expected)


def test_plain_kernel_loops_equal_the_numpy_reference():
    from mk_tracker.tracking import search_region as kh
    rng = np.random.default_rng(14)
    seen_empty = seen_full = 0
    for trial in range(16):
        bins, origin, stride, axes, centres, models, profile, weighting = \
            _random_case(rng, trial)
        axes = np.minimum(axes, 14.0)                       # Python speed
        ref = SearchRegion(bins, origin, stride, M, profile, "numpy").evaluate(
            axes, centres, models, 0.01, weighting)
        n_k = len(axes)
        p, costs, sims = np.zeros((n_k, M)), np.zeros(n_k), np.zeros(n_k)
        ms, counts, ratios = np.zeros((n_k, 2)), np.zeros(n_k, np.int64), np.zeros(n_k)
        kh._kernels_loops(np.ascontiguousarray(bins, np.int32), origin[0], origin[1], stride,
                          centres, axes, models, 0.01, weighting == "bhattacharyya",
                          profile == "gaussian", p, costs, sims, ms, counts, ratios)
        assert np.array_equal(counts, ref.n_pixels)
        assert np.array_equal(np.isinf(costs), counts == 0)
        seen_empty += int(np.sum(counts == 0))
        seen_full += int(np.sum(counts > 0))
        for got, want in ((p, ref.p), (sims, ref.similarities), (ms, ref.mean_shift),
                          (ratios, ref.scale_ratios)):
            assert np.allclose(got, want, rtol=0, atol=1e-9)
        fin = np.isfinite(ref.costs)
        assert np.allclose(costs[fin], ref.costs[fin], rtol=0, atol=1e-9)
    assert seen_empty > 0 and seen_full > 10


@pytest.fixture
def plain_compiled(monkeypatch):
    """The "compiled" backend with the uncompiled loops: its glue code (argument packing,
    the copy of read-only images, output shapes) runs in Python, numba or not."""
    from mk_tracker.tracking import search_region as kh
    monkeypatch.setattr(kh, "compiled_kernels", lambda: (kh._quantize_loops, kh._kernels_loops))
    return kh


@pytest.mark.parametrize("stride", [1, 2, 3])
def test_compiled_backend_glue_with_plain_loops_quantises_like_numpy(plain_compiled, stride):
    rng = np.random.default_rng(50 + stride)
    img = rng.integers(0, 256, size=(23, 31, 3)).astype(np.uint8)
    frozen = img.copy()
    frozen.setflags(write=False)                      # a read-only message buffer
    for image in (img, frozen, np.ascontiguousarray(img[:, ::-1])[:, ::-1]):
        for region in [(0, 0, 31, 23), (stride * 2, stride, 29, 20), (5, 7, 6, 8)]:
            x0, y0, x1, y1 = region
            for cs, bins in [("hsv", BINS), ("bgr", (4, 8, 2)), ("grey", (1, 1, 16))]:
                got = quantize_region(image, region, stride, cs, bins, "compiled")
                expected = quantize(img[y0:y1:stride, x0:x1:stride], cs, bins)
                assert got.dtype == np.int32 and np.array_equal(got, expected)
    bad = img.astype(np.float32)
    bad[3, 4] = np.nan
    assert quantize_region(bad, (0, 0, 31, 23), 1, "hsv", BINS, "compiled") is None
    assert np.array_equal(quantize_region(img.astype(np.float64), (0, 0, 31, 23), 1, "hsv",
                                          BINS, "compiled"), quantize(img, "hsv", BINS))


def test_compiled_backend_glue_with_plain_loops_evaluates_like_numpy(plain_compiled):
    rng = np.random.default_rng(15)
    for trial in range(8):
        bins, origin, stride, axes, centres, models, profile, weighting = \
            _random_case(rng, trial)
        axes = np.minimum(axes, 12.0)
        region = SearchRegion(bins, origin, stride, M, profile, "compiled")
        assert region.backend == "compiled"
        a = region.evaluate(axes, centres, models, 0.02, weighting)
        b = SearchRegion(bins, origin, stride, M, profile, "numpy").evaluate(
            axes, centres, models, 0.02, weighting)
        assert np.array_equal(a.n_pixels, b.n_pixels)
        for name in ("p", "similarities", "mean_shift", "scale_ratios"):
            assert np.allclose(getattr(a, name), getattr(b, name), rtol=0, atol=1e-9), name
        fin = np.isfinite(b.costs)
        assert np.array_equal(np.isinf(a.costs), ~fin)
        assert np.allclose(a.costs[fin], b.costs[fin], rtol=0, atol=1e-9)


def test_warm_up_call_matches_the_loops_signatures():
    # the start-up warm-up of the numba loops must be a valid call of both loops (a wrong
    # argument list raises TypeError here), and it must call each of them once: a warm-up
    # that skipped one would leave its compile to the first frame
    from mk_tracker.tracking import search_region as kh
    calls = []

    def recording(name, loops):
        def call(*args):
            calls.append(name)
            return loops(*args)
        return call

    kh._warm_up(recording("quantize", kh._quantize_loops),
                recording("kernels", kh._kernels_loops))
    assert calls == ["quantize", "kernels"]


def test_number_of_bins_is_the_product():
    assert number_of_bins((16, 8, 4)) == 512
    assert number_of_bins((2, 3, 5)) == 30
    assert isinstance(number_of_bins((2.0, 3, 5)), int)


def test_usable_images_pass_the_check_unchanged():
    for image in (np.zeros((2, 3, 3), np.uint8), np.ones((1, 1, 3), np.float32),
                  np.zeros((5, 4, 3), np.float64)):
        assert check_image(image) is image


@pytest.mark.parametrize("bad, message", [
    ([[1, 2, 3]], "image must be a numpy array, got list"),
    (np.zeros((10, 10), np.uint8), "image must be H x W x 3 (BGR), got shape (10, 10)"),
    (np.zeros((4, 4, 4), np.uint8), "image must be H x W x 3 (BGR), got shape (4, 4, 4)"),
    (np.zeros((0, 5, 3), np.uint8), "image is empty"),
    (np.zeros((5, 0, 3), np.uint8), "image is empty"),
    (np.zeros((4, 4, 3), np.int64), "image must be uint8 or float, got int64"),
])
def test_bad_images_are_named_in_the_error(bad, message):
    with pytest.raises(InvalidImageError) as info:
        check_image(bad)
    assert str(info.value) == message


def test_roi_has_nan_only_for_float_rois_with_a_bad_value():
    assert not roi_has_nan(np.zeros((2, 2, 3), np.uint8))
    assert not roi_has_nan(np.zeros((2, 2, 3), np.float32))
    bad = np.zeros((2, 2, 3), np.float32)
    bad[1, 1, 2] = np.inf
    assert roi_has_nan(bad)


# -- mutation testing (#18): details the tests above leave open -----------------------------

from mk_tracker.tracking import kernel_histograms as _kh  # noqa: E402
from mk_tracker.tracking import search_region as _sr  # noqa: E402


def test_error_messages_name_the_bad_value():
    cases = [
        (lambda: bin_lookup_tables("lab", BINS),
         "colour_space must be one of ('hsv', 'bgr', 'grey'), got 'lab'"),
        (lambda: bin_lookup_tables("hsv", (0, 8, 4)), "bins must lie in [1, 256], got (0, 8, 4)"),
        (lambda: profile_values(np.zeros(2), "box"),
         "profile must be one of ('roof', 'gaussian'), got 'box'"),
        (lambda: _kh.KernelTemplate(np.array([3.0, 3.0]), 1, "box"),
         "profile must be one of ('roof', 'gaussian'), got 'box'"),
        (lambda: SearchRegion(np.zeros((4, 4), np.int32), (0, 0), 1, M, "box", "numpy"),
         "profile must be one of ('roof', 'gaussian'), got 'box'"),
        (lambda: resolve_backend("gpu"),
         "backend must be one of ('auto', 'numpy', 'compiled'), got 'gpu'"),
        (lambda: SearchRegion(np.full((2, 2), M, np.int32), (0, 0), 1, M, backend="numpy"),
         f"bin indices must lie in [0, {M})"),
        (lambda: SearchRegion(np.zeros((4, 4), np.int32), (0, 0), 1, M, backend="numpy")
         .evaluate(np.ones((2, 2)), np.ones((3, 2)), np.ones((2, M))),
         f"2 kernels need 2 centres and models of {M} bins, got centres (3, 2) and "
         f"models (2, {M})"),
    ]
    weight_msg = "weighting must be one of ('kl', 'bhattacharyya'), got 'l2'"
    sample = sample_kernel(np.zeros((9, 9), np.int64), (0, 0), np.array([4.5, 4.5]),
                           np.array([2.0, 2.0]))
    q = np.full(M, 1.0 / M)
    template = _kh.KernelTemplate(np.array([2.0, 2.0]), 1)
    padded = _kh.PaddedBins(np.zeros((9, 9), np.int64), (0, 0), 1, M, template.reach)
    cases += [
        (lambda: pixel_weights(sample, q, q, 0.01, "l2"), weight_msg),
        (lambda: evaluate_kernel(np.zeros((9, 9), np.int64), (0, 0), np.array([4.5, 4.5]),
                                 np.array([2.0, 2.0]), q, weighting="l2"), weight_msg),
        (lambda: padded.evaluate(template, np.array([4.5, 4.5]), q, 0.01, "l2"), weight_msg),
        (lambda: SearchRegion(np.zeros((4, 4), np.int32), (0, 0), 1, M, backend="numpy")
         .evaluate(np.ones((1, 2)), np.ones((1, 2)), np.ones((1, M)), 0.01, "l2"), weight_msg),
    ]
    for call, message in cases:
        with pytest.raises(ValueError) as info:
            call()
        assert str(info.value) == message


def test_compiled_refused_message_without_numba(monkeypatch):
    monkeypatch.setattr(_sr, "compiled_kernels", lambda: None)
    with pytest.raises(KernelBackendError) as info:
        resolve_backend("compiled")
    assert str(info.value) == ("the compiled backend needs numba, which is not installed "
                               "(or MK_TRACKER_NO_NUMBA is set)")
    assert resolve_backend("auto") == "numpy" and resolve_backend("numpy") == "numpy"


def test_lookup_tables_accept_1_to_256_bins_and_are_shared_read_only_int32():
    for bins in [(1, 1, 1), (256, 256, 256), (180, 1, 256)]:
        table = bin_lookup_tables("hsv", bins)
        assert table.shape == (3, 256) and table.dtype == np.int32
        assert not table.flags.writeable
        assert bin_lookup_tables("hsv", bins) is table          # built once
        # every level combination is a valid flat bin, even hue levels >= 180 that OpenCV
        # never produces (the compiled loops index histograms without bounds checks)
        assert int(table[0].max() + table[1].max() + table[2].max()) < number_of_bins(bins)
    assert bin_lookup_tables("hsv", (16, 8, 4))[0, 255] == 15 * 8 * 4     # hue bin clamped
    for bins in [(257, 8, 4), (16, 0, 4), (16, 8, 257)]:
        with pytest.raises(ValueError):
            bin_lookup_tables("bgr", bins)


def test_float_rois_are_clipped_to_0_255():
    roi = np.array([[[-5.0, 300.0, 256.0], [0.0, 255.0, 1.0]]])
    # bgr with 256 levels per channel: the bin spells out the (clipped) levels
    b = quantize(roi, "bgr", (256, 256, 256))
    assert b.tolist() == [[(0 * 256 + 255) * 256 + 255, (0 * 256 + 255) * 256 + 1]]


def test_a_sample_outside_the_roi_is_empty_and_its_histogram_zero():
    bins = np.zeros((10, 10), np.int32)
    s = sample_kernel(bins, (0, 0), np.array([50.0, 50.0]), np.array([3.0, 3.0]))
    for name in ("bins", "k", "g", "xs", "ys", "v"):
        assert getattr(s, name).shape == (0,), name
    assert s.bins.dtype.kind == "i" and s.empty
    assert np.array_equal(kernel_histogram(s, M), np.zeros(M))


def _brute_force_pixels(shape, origin, stride, centre, axes):
    """(row, col) of the ROI elements whose pixel centres are strictly inside the ellipse."""
    out = []
    for r in range(shape[0]):
        for c in range(shape[1]):
            x = origin[0] + c * stride + 0.5
            y = origin[1] + r * stride + 0.5
            if ((x - centre[0]) / axes[0]) ** 2 + ((y - centre[1]) / axes[1]) ** 2 < 1.0:
                out.append((r, c))
    return out


def test_sample_kernel_takes_exactly_the_pixels_inside_the_ellipse():
    rng = np.random.default_rng(21)
    shape = (17, 23)
    bins = np.arange(shape[0] * shape[1]).reshape(shape)       # the bin names the element
    for trial in range(60):
        stride = int(rng.integers(1, 4))
        origin = (int(rng.integers(-12, 12)), int(rng.integers(-12, 12)))   # negative too
        axes = rng.uniform(0.6, 9.0, 2)
        centre = rng.uniform(-15.0, 60.0, 2)
        s = sample_kernel(bins, origin, centre, axes, stride=stride)
        expected = _brute_force_pixels(shape, origin, stride, centre, axes)
        assert sorted(s.bins.tolist()) == sorted(r * shape[1] + c for r, c in expected)
        assert s.xs.dtype == np.float64 and s.ys.dtype == np.float64


def test_a_one_pixel_kernel_has_a_one_hot_histogram():
    # axes 0.6 around a pixel centre: only that pixel, k = 1 - 0 = 1; off-centre by 0.3 px,
    # k = 1 - 0.25 = 0.75 (a total weight below 1 is normalised as well)
    bins = np.arange(25).reshape(5, 5)
    for centre, k in (([2.5, 2.5], 1.0), ([2.5, 2.8], 0.75)):
        s = sample_kernel(bins, (0, 0), np.array(centre), np.array([0.6, 0.6]))
        assert s.bins.tolist() == [12] and s.k.tolist() == pytest.approx([k])
        assert np.array_equal(kernel_histogram(s, 25), np.eye(25)[12])


def test_bhattacharyya_weights_are_the_square_root_of_the_kl_weights():
    # q = (0.5, 0.5, 0, 0), p = (0.25, 0.25, 0.25, 0.25), eps = 0: q/p = (2, 2, 0, 0)
    s = _kh.KernelSample(bins=np.array([0, 1, 2]), k=np.ones(3), g=np.ones(3), xs=np.zeros(3),
                         ys=np.zeros(3), v=np.zeros(3))
    q = np.array([0.5, 0.5, 0.0, 0.0])
    p = np.full(4, 0.25)
    assert pixel_weights(s, q, p, 0.0).tolist() == [2.0, 2.0, 0.0]
    assert pixel_weights(s, q, p, 0.0, "bhattacharyya").tolist() == \
        pytest.approx([np.sqrt(2.0), np.sqrt(2.0), 0.0])


def test_scale_ratio_by_hand_with_little_kernel_weight():
    # k = (0.3, 0.4), v = (0.7, 0.6), g = 1, w = (1, 3), h^2 = 1 + 1:
    # r = 2/2 (sum w g v / sum w k - sum g v / sum k) = 2.5/1.5 - 1.3/0.7
    s = _kh.KernelSample(bins=np.array([0, 1]), k=np.array([0.3, 0.4]), g=np.ones(2),
                         xs=np.zeros(2), ys=np.zeros(2), v=np.array([0.7, 0.6]))
    r = scale_ratio(s, np.array([1.0, 3.0]), np.array([1.0, 1.0]))
    assert r == pytest.approx(2.5 / 1.5 - 1.3 / 0.7, rel=1e-12)


def test_evaluate_kernel_defaults_and_fields():
    bins = np.zeros((20, 20), np.int64)
    bins[:, 10:] = 1
    q = np.zeros(4)
    q[0] = 1.0
    # axes (2, 2) at a pixel corner (10, 10), stride 1 by default: offsets -1.5..1.5,
    # v = (dx^2 + dy^2) / 4 < 1 for 12 of the 16 pixels (not the corners, v = 1.125)
    ev = evaluate_kernel(bins, (0, 0), np.array([10.0, 10.0]), np.array([2.0, 2.0]), q)
    assert ev.n_pixels == 12
    assert ev.similarity == pytest.approx(np.exp(-ev.cost), rel=1e-12)
    # half the weight in bin 0: p~_0 = 0.99 * 0.5 + 0.01 / 4, J = log(1 / p~_0)
    assert ev.cost == pytest.approx(-np.log(0.99 * 0.5 + 0.0025), rel=1e-12)
    empty = evaluate_kernel(bins, (0, 0), np.array([90.0, 90.0]), np.array([2.0, 2.0]), q)
    assert np.array_equal(empty.p, np.zeros(4)) and empty.mean_shift.shape == (2,)
    assert empty.scale_ratio == 0.0


def test_template_reach_is_the_ellipse_plus_one_stride():
    t = _kh.KernelTemplate(np.array([15.0, 20.0]), 2)
    assert t.reach == (9, 11)                 # ceil(15 / 2) + 1, ceil(20 / 2) + 1
    t = _kh.KernelTemplate(np.array([4.0, 3.0]), 1)
    assert t.reach == (5, 4)


def test_padded_evaluation_far_outside_the_roi_with_the_smallest_padding():
    # centres beyond every edge: the grid node is clamped into the ROI, and with the padding
    # equal to the reach the gathered offsets must stay inside the padded array
    img = _blob_scene()
    bins = quantize(img[:40, :50], "hsv", BINS)
    axes = np.array([9.0, 7.0])
    q = np.full(M, 1.0 / M)
    template = _kh.KernelTemplate(axes, 1)
    padded = _kh.PaddedBins(bins, (0, 0), 1, M, template.reach)
    for centre in ([55.0, 20.0], [20.0, 45.0], [-5.0, 20.0], [20.0, -4.0], [56.0, 44.0]):
        centre = np.array(centre)
        fast = padded.evaluate(template, centre, q)
        n = len(_brute_force_pixels(bins.shape, (0, 0), 1, centre, axes))
        assert n > 0 and fast.n_pixels == n
        direct = evaluate_kernel(bins, (0, 0), centre, axes, q)
        assert fast.cost == pytest.approx(direct.cost, abs=1e-12)
        assert sorted(zip(fast.sample.xs.tolist(), fast.sample.ys.tolist())) == \
            sorted(zip(direct.sample.xs.tolist(), direct.sample.ys.tolist()))


def test_search_region_repads_for_larger_kernels_in_either_direction():
    img = _blob_scene()
    bins = quantize(img, "hsv", BINS)
    q = np.full((1, M), 1.0 / M)
    centre = np.array([[85.3, 60.7]])
    # small, then wider only, then taller only, then small again; and in a fresh region a
    # tall kernel followed by a wide one (its width beyond the x padding but not the y one)
    sequences = ([[4.0, 4.0], [30.0, 4.0], [4.0, 30.0], [30.0, 30.0], [4.0, 4.0]],
                 [[4.0, 30.0], [20.0, 4.0]])
    for sequence in sequences:
        region = SearchRegion(bins, (0, 0), 1, M, "roof", "numpy")
        for axes in sequence:
            axes = np.array([axes])
            batch = region.evaluate(axes, centre, q)
            direct = evaluate_kernel(bins, (0, 0), centre[0], axes[0], q[0])
            assert batch.n_pixels[0] == direct.n_pixels
            assert batch.costs[0] == pytest.approx(direct.cost, abs=1e-12)
            assert np.allclose(batch.mean_shift[0], direct.mean_shift, atol=1e-9)


def test_default_epsilon_is_0_01_and_weighting_kl():
    img = _blob_scene()
    bins = quantize(img, "hsv", BINS)
    rng = np.random.default_rng(2)
    q = rng.random((1, M))
    q /= q.sum()
    axes, centre = np.array([[12.0, 9.0]]), np.array([[80.2, 55.9]])
    region = SearchRegion(bins, (0, 0), 1, M, "roof", "numpy")
    a = region.evaluate(axes, centre, q)
    b = region.evaluate(axes, centre, q, 0.01, "kl")
    assert a.costs[0] == b.costs[0] and np.array_equal(a.mean_shift, b.mean_shift)
    template = _kh.KernelTemplate(axes[0], 1)
    padded = _kh.PaddedBins(bins, (0, 0), 1, M, template.reach)
    c = padded.evaluate_batch([template], centre, q)
    assert c.costs[0] == b.costs[0] and np.array_equal(c.mean_shift, b.mean_shift)
    assert region.evaluate(axes, centre, q, 0.5).costs[0] != b.costs[0]   # epsilon matters


def _hand_kernel(bins, origin, stride, centre, axes, q, eps, weighting="kl",
                 profile="roof"):
    """Every output of one kernel straight from the definitions (module docstring), pixel by
    pixel: an oracle that shares no code with the module."""
    m = q.size
    pix = []
    for r in range(bins.shape[0]):
        for c in range(bins.shape[1]):
            x = origin[0] + c * stride + 0.5
            y = origin[1] + r * stride + 0.5
            v = ((x - centre[0]) / axes[0]) ** 2 + ((y - centre[1]) / axes[1]) ** 2
            if v < 1.0:
                k = 1.0 - v if profile == "roof" else np.exp(-2.0 * v)
                g = 1.0 if profile == "roof" else 2.0 * np.exp(-2.0 * v)
                pix.append((int(bins[r, c]), x, y, v, k, g))
    if not pix:
        return dict(n=0, p=np.zeros(m), cost=np.inf, sim=0.0, ms=np.zeros(2), ratio=0.0)
    p = np.zeros(m)
    for b, x, y, v, k, g in pix:
        p[b] += k
    p /= p.sum()
    ps = (1.0 - eps) * p + eps / m
    cost = sum(q[u] * np.log(q[u] / ps[u]) for u in range(m) if q[u] > 0)
    w = {b: (q[b] / ps[b]) ** (0.5 if weighting == "bhattacharyya" else 1.0)
         for b, *_ in pix}
    s = sum(w[b] * g for b, x, y, v, k, g in pix)
    ms = np.zeros(2)
    if s > 0:
        ms = np.array([sum(w[b] * g * x for b, x, y, v, k, g in pix) / s - centre[0],
                       sum(w[b] * g * y for b, x, y, v, k, g in pix) / s - centre[1]])
    sk = sum(k for *_, k, g in pix)
    wk = sum(w[b] * k for b, x, y, v, k, g in pix)
    ratio = 0.0
    if wk > 0:
        ratio = 2.0 / (axes[0] ** 2 + axes[1] ** 2) * (
            sum(w[b] * g * v for b, x, y, v, k, g in pix) / wk
            - sum(g * v for *_, v, k, g in pix) / sk)
    return dict(n=len(pix), p=p, cost=cost, sim=np.exp(-max(cost, 0.0)), ms=ms, ratio=ratio,
                pixels=sorted((b, x, y) for b, x, y, *_ in pix))


# small kernels on a 6 x 7 ROI whose bin names the element: empty first (a kernel after an
# empty one must still be evaluated), one pixel with k = 0.75 (total weight below 1), two
# pixels with k = 0.67 and 0.27, a pixel exactly on the ellipse (v = 1, not inside), and
# kernels that hang over the ROI's edges
SMALL_KERNELS = [((40.0, 40.0), (1.0, 1.0)), ((2.5, 2.8), (0.6, 0.6)),
                 ((2.9, 2.5), (0.7, 0.4)), ((3.0, 2.5), (1.5, 1.0)),
                 ((0.2, 0.3), (1.3, 1.1)), ((6.9, 5.8), (1.2, 1.6)), ((3.5, 3.5), (2.2, 1.7))]


@pytest.mark.parametrize("weighting", ["kl", "bhattacharyya"])
@pytest.mark.parametrize("profile", ["roof", "gaussian"])
def test_every_path_equals_the_definitions_on_small_kernels(weighting, profile):
    bins = np.arange(42).reshape(6, 7)
    m = 42
    centres = np.array([c for c, _ in SMALL_KERNELS])
    axes = np.array([a for _, a in SMALL_KERNELS])
    models = np.zeros((len(centres), m))
    for i, (c, a) in enumerate(zip(centres, axes)):
        hand = _hand_kernel(bins, (0, 0), 1, c, a, np.full(m, 1.0 / m), 0.01, weighting,
                            profile)
        models[i] = hand["p"] if hand["n"] else 1.0 / m    # its own histogram: cost < 1
        models[i, (i * 5) % m] += 0.3
        models[i] /= models[i].sum()
    hands = [_hand_kernel(bins, (0, 0), 1, c, a, q, 0.01, weighting, profile)
             for c, a, q in zip(centres, axes, models)]
    assert [h["n"] for h in hands][:4] == [0, 1, 2, 2]     # (3, 2.5): v = 1 at x = 1.5, 4.5
    assert any(0 < h["cost"] < 1 for h in hands)

    def check(n, p, cost, sim, ms, ratio):
        for i, h in enumerate(hands):
            assert n[i] == h["n"], i
            assert np.allclose(p[i], h["p"], rtol=0, atol=1e-12), i
            assert cost[i] == pytest.approx(h["cost"], abs=1e-12), i
            assert sim[i] == pytest.approx(h["sim"], abs=1e-12), i
            assert np.allclose(ms[i], h["ms"], rtol=0, atol=1e-12), i
            assert ratio[i] == pytest.approx(h["ratio"], abs=1e-12), i

    with np.errstate(all="raise"):
        evs = [evaluate_kernel(bins, (0, 0), c, a, q, profile=profile, weighting=weighting)
               for c, a, q in zip(centres, axes, models)]
        check(*zip(*[(e.n_pixels, e.p, e.cost, e.similarity, e.mean_shift, e.scale_ratio)
                     for e in evs]))
        templates = [_kh.KernelTemplate(a, 1, profile) for a in axes]
        padded = _kh.PaddedBins(bins, (0, 0), 1, m,
                                tuple(int(r) for r in np.max([t.reach for t in templates], 0)))
        many = padded.evaluate_many(templates, centres, models, 0.01, weighting)
        check(*zip(*[(e.n_pixels, e.p, e.cost, e.similarity, e.mean_shift, e.scale_ratio)
                     for e in many]))
        for e, h in zip(many, hands):          # the kept pixels, in image coordinates
            if h["n"]:
                got = sorted(zip(e.sample.bins.tolist(), e.sample.xs.tolist(),
                                 e.sample.ys.tolist()))
                assert np.allclose(got, h["pixels"], rtol=0, atol=1e-12)
        for backend in ("numpy", "plain"):
            if backend == "plain":
                n_k = len(centres)
                b = _kh.KernelBatch(np.zeros((n_k, m)), np.zeros(n_k), np.zeros(n_k),
                                    np.zeros((n_k, 2)), np.zeros(n_k, np.int64), np.zeros(n_k))
                _sr._kernels_loops(bins.astype(np.int32), 0, 0, 1, centres, axes, models,
                                   0.01, weighting == "bhattacharyya", profile == "gaussian",
                                   b.p, b.costs, b.similarities, b.mean_shift, b.n_pixels,
                                   b.scale_ratios)
            else:
                b = SearchRegion(bins, (0, 0), 1, m, profile, "numpy").evaluate(
                    axes, centres, models, weighting=weighting)
                assert b.n_pixels.dtype == np.int64
            check(b.n_pixels, b.p, b.costs, b.similarities, b.mean_shift, b.scale_ratios)
        # all kernels valid: the batch's fast path
        b = padded.evaluate_batch(templates[1:], centres[1:], models[1:], 0.01, weighting)
        assert b.n_pixels.dtype == np.int64
        check(np.r_[0, b.n_pixels], np.r_[[np.zeros(m)], b.p], np.r_[np.inf, b.costs],
              np.r_[0.0, b.similarities], np.r_[[np.zeros(2)], b.mean_shift],
              np.r_[0.0, b.scale_ratios])


def test_a_kernel_reaching_past_the_padding_in_one_direction_is_refused():
    bins = np.zeros((20, 20), np.int64)
    padded = _kh.PaddedBins(bins, (0, 0), 1, M, (4, 4))
    for axes in ([8.0, 2.0], [2.0, 8.0]):
        with pytest.raises(ValueError, match="padding"):
            padded.evaluate(_kh.KernelTemplate(np.array(axes), 1), np.array([10.0, 10.0]),
                            np.full(M, 1.0 / M))


def test_a_template_serves_rois_of_different_widths():
    # the template caches its flat offsets for one row width; another ROI width needs others
    bins = np.arange(42).reshape(6, 7)
    q = np.full(42, 1.0 / 42)
    template = _kh.KernelTemplate(np.array([1.5, 1.2]), 1)
    for width in (7, 5, 7):
        roi = bins[:, :width]
        padded = _kh.PaddedBins(roi, (0, 0), 1, 42, template.reach)
        ev = padded.evaluate(template, np.array([2.6, 3.1]), q)
        hand = _hand_kernel(roi, (0, 0), 1, np.array([2.6, 3.1]), np.array([1.5, 1.2]), q,
                            0.01)
        assert sorted(ev.sample.bins.tolist()) == sorted(
            int(roi[int(y - 0.5), int(x - 0.5)]) for x, y in zip(ev.sample.xs, ev.sample.ys))
        assert ev.n_pixels == hand["n"] and np.allclose(ev.p, hand["p"], atol=1e-12)


def test_compiled_loops_take_exactly_the_pixels_inside_the_ellipse():
    rng = np.random.default_rng(23)
    shape = (9, 11)
    bins = np.arange(99, dtype=np.int32).reshape(shape)
    for trial in range(40):
        stride = int(rng.integers(1, 4))
        origin = (int(rng.integers(0, 5)), int(rng.integers(0, 5)))
        n_k = 4
        axes = rng.uniform(0.5, 4.0, (n_k, 2))
        centres = rng.uniform(-3.0, 40.0, (n_k, 2))
        models = np.full((n_k, 99), 1.0 / 99)
        p, costs, sims = np.zeros((n_k, 99)), np.zeros(n_k), np.zeros(n_k)
        ms, counts, ratios = np.zeros((n_k, 2)), np.zeros(n_k, np.int64), np.zeros(n_k)
        _sr._kernels_loops(bins, origin[0], origin[1], stride, centres, axes, models, 0.01,
                           False, False, p, costs, sims, ms, counts, ratios)
        for i in range(n_k):
            expected = _brute_force_pixels(shape, origin, stride, centres[i], axes[i])
            assert counts[i] == len(expected)
            assert np.array_equal(p[i] > 0, np.isin(np.arange(99), [r * 11 + c for r, c
                                                                      in expected])), i


def test_backend_numpy_never_uses_the_compiled_loops(monkeypatch):
    calls = []

    def quantize_loops(*args):
        calls.append("q")
        return _sr._quantize_loops(*args)

    def kernels_loops(*args):
        calls.append("k")
        return _sr._kernels_loops(*args)

    monkeypatch.setattr(_sr, "compiled_kernels", lambda: (quantize_loops, kernels_loops))
    assert resolve_backend("numpy") == "numpy" and resolve_backend("auto") == "compiled"
    img = _blob_scene()[:20, :30]
    for backend in ("numpy", "compiled", "auto"):
        before = len(calls)
        got = quantize_region(img, (2, 1, 29, 19), 2, "hsv", BINS, backend)
        assert np.array_equal(got, quantize(img[1:19:2, 2:29:2], "hsv", BINS))
        assert len(calls) - before == (0 if backend == "numpy" else 1)
    # the default backend is "auto"
    assert np.array_equal(quantize_region(img, (0, 0, 30, 20), 1, "bgr", (4, 4, 4)),
                          quantize(img, "bgr", (4, 4, 4)))
    # an empty region gives an empty array on either path (bgr: OpenCV's HSV conversion
    # refuses an empty image, so the numpy path raises for an empty HSV region)
    for backend in ("numpy", "compiled"):
        assert quantize_region(img, (5, 5, 5, 9), 1, "bgr", BINS, backend).shape == (4, 0)
        assert quantize_region(img, (5, 5, 8, 5), 2, "bgr", BINS, backend).shape == (0, 2)
    region = SearchRegion(quantize(img, "hsv", BINS), (0, 0), 1, M, "roof", "compiled")
    batch = region.evaluate(np.array([[3.0, 2.0]]), np.array([[10.0, 10.0]]),
                            np.full((1, M), 1.0 / M))
    assert calls[-1] == "k" and batch.n_pixels.dtype == np.int64 and batch.n_pixels[0] > 0


def test_no_numba_environment_variable_disables_the_compiled_kernels(monkeypatch):
    monkeypatch.setattr(_sr, "_COMPILED", [])
    monkeypatch.setenv("MK_TRACKER_NO_NUMBA", "1")
    assert _sr.compiled_kernels() is None
    assert _sr._COMPILED == [None]


def test_search_region_backend_defaults_to_auto():
    region = SearchRegion(np.zeros((4, 4), np.int32), (0, 0), 1, M)
    assert region.backend == resolve_backend("auto")


@needs_numba
@pytest.mark.filterwarnings("ignore:divide by zero")
@pytest.mark.parametrize("backend", ["compiled", "numpy"])
def test_a_kernel_with_a_zero_half_axis_has_no_pixel_on_both_backends(backend):
    # found by the property test's dev profile: the layout of a box clipped to a sliver
    # 1.8e-15 px high has zero half-axes; the compiled loop raised ZeroDivisionError
    region = SearchRegion(np.zeros((4, 16), np.int32), (0, 0), 1, 2, "roof", backend)
    out = region.evaluate(np.array([[4.0, 0.0], [0.0, 2.0], [4.0, 2.0]]),
                          np.array([[8.0, 2.0], [8.0, 2.0], [8.0, 2.0]]), np.full((3, 2), 0.5))
    assert out.n_pixels[:2].tolist() == [0, 0]
    assert np.isinf(out.costs[:2]).all() and out.similarities[:2].tolist() == [0.0, 0.0]
    assert out.mean_shift[:2].tolist() == [[0.0, 0.0], [0.0, 0.0]]
    # the well-formed kernel beside them is evaluated: every pixel is in bin 0, so p = (1, 0)
    # and J = 0.5 log(0.5 / (0.99 + 0.005)) + 0.5 log(0.5 / 0.005)
    assert out.n_pixels[2] > 0
    want = 0.5 * np.log(0.5 / 0.995) + 0.5 * np.log(0.5 / 0.005)
    assert out.costs[2] == pytest.approx(want, rel=1e-12)
