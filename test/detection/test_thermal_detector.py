"""The thermal detector (Algorithm 2) on the paper's synthetic scenes, and on bad input."""

import dataclasses

import numpy as np
import pytest

from mk_tracker.parameters import parameter_specs
from mk_tracker.synthetic.presets import paper_scene, static_warm_objects_scene
from mk_tracker.synthetic.scene import make_scene
from mk_tracker.detection.thermal_detector import (ThermalDetection, ThermalDetector,
                                         ThermalDetectorConfig, ThermalInputError)
from mk_tracker.detection.threshold_detector import ThresholdDetector, ThresholdDetectorConfig


def centre(box):
    x, y, w, h = box
    return np.array([x + w / 2.0, y + h / 2.0])


def run_paper(scene, config=None, encoding=None):
    det = ThermalDetector(config or ThermalDetectorConfig())
    counts, errors, modes = [], {1: [], 2: [], 3: []}, []
    for i in range(len(scene)):
        fr = scene.frame(i)
        dets = det.process(fr.thermal, fr.stamp, encoding)
        modes.append(det.last_mode)
        if det.last_mode == "warming_up":
            assert dets == []
            continue
        counts.append(len(dets))
        for obj in fr.objects:
            c = centre(obj.box_thermal)
            errors[obj.id].append(min(np.linalg.norm(np.array(d.centroid) - c) for d in dets))
    rmse = {k: float(np.sqrt(np.mean(np.square(v)))) for k, v in errors.items()}
    return det, counts, rmse, modes


@pytest.fixture(scope="module")
def paper_run():
    return run_paper(paper_scene(0))


def test_paper_scene_three_objects_in_every_frame_after_start_up(paper_run):
    det, counts, _, modes = paper_run
    cfg = det.config
    assert modes[:cfg.startup_frames - 1] == ["warming_up"] * (cfg.startup_frames - 1)
    assert modes[cfg.startup_frames - 1] == "startup"
    assert "tracking" in modes and "reconfiguration" in modes
    assert len(counts) == 60 - cfg.startup_frames + 1
    assert counts == [3] * len(counts)


def test_paper_scene_centroid_rmse_at_most_one_pixel(paper_run):
    _, _, rmse, _ = paper_run
    for obj_id, value in rmse.items():
        assert value <= 1.0, (obj_id, rmse)


def test_paper_scene_detections_are_well_formed_and_filtered(paper_run):
    det, *_ = paper_run
    scene = paper_scene(0)
    fr = scene.frame(59)
    # the detector has seen all frames; its tracks move at the objects' speed (38 px/s)
    speeds = sorted(np.hypot(s[2], s[3]) for _, s in det.tracks)
    assert len(speeds) == 3
    assert all(abs(v - 90.0 / 59.0 * 25.0) < 8.0 for v in speeds), speeds
    det2 = ThermalDetector()
    out = []
    for i in range(12):
        f = scene.frame(i)
        out = det2.process(f.thermal, f.stamp)
    assert len(out) == 3
    for d in out:
        assert isinstance(d, ThermalDetection)
        assert 0.0 <= d.score <= 1.0
        assert d.pixel_count >= 50
        x, y, w, h = d.box
        assert 8 <= w <= 12 and 8 <= h <= 12
        assert x <= d.centroid[0] <= x + w and y <= d.centroid[1] <= y + h
        assert d.filtered_centroid is not None and d.velocity is not None
        assert d.object_id >= 1
    assert fr.index == 59


def test_paper_scene_with_five_percent_missing_pixels():
    base = paper_scene(1)
    scene = make_scene(dataclasses.replace(base.config, missing_pixel_fraction=0.05))
    frame = scene.frame(10).thermal
    assert 0.03 < np.mean(frame == 0) < 0.07          # the scene really drops pixels to 0
    _, counts, rmse, _ = run_paper(scene)
    assert counts == [3] * len(counts)
    for obj_id, value in rmse.items():
        assert value <= 2.0, (obj_id, rmse)


@pytest.mark.parametrize("encoding", ["mono16", "32FC1"])
def test_paper_scene_in_other_encodings(encoding):
    base = paper_scene(2)
    scene = make_scene(dataclasses.replace(base.config, thermal_encoding=encoding,
                                           frames=30))
    assert scene.frame(0).thermal.dtype == (np.uint16 if encoding == "mono16" else np.float32)
    _, counts, rmse, _ = run_paper(scene, encoding=encoding)
    assert counts == [3] * len(counts)
    assert max(rmse.values()) <= 1.0


def test_static_warm_objects_threshold_miscounts_kernel_counts_right():
    """Table 1: static warm objects plus one cooler moving person."""
    scene = static_warm_objects_scene(0, frames=30)
    kernel = ThermalDetector()
    low = ThresholdDetector(ThresholdDetectorConfig(threshold=0.3))
    high = ThresholdDetector(ThresholdDetectorConfig(threshold=0.5))
    kernel_counts, low_counts, high_counts = [], [], []
    for i in range(len(scene)):
        fr = scene.frame(i)
        dets = kernel.process(fr.thermal, fr.stamp)
        if kernel.last_mode == "warming_up":
            continue
        kernel_counts.append(len(dets))
        low_counts.append(len(low.process(fr.thermal, fr.stamp)))
        high_counts.append(len(high.process(fr.thermal, fr.stamp)))
        person = fr.object(1)
        for d in dets:
            x, y, w, h = person.box_thermal
            assert x <= d.centroid[0] <= x + w and y <= d.centroid[1] <= y + h
    assert kernel_counts == [1] * len(kernel_counts)
    assert all(c != 1 for c in low_counts), low_counts      # person + warm objects
    assert all(c != 1 for c in high_counts), high_counts    # warm objects, person missed


def moving_square_frames(n, shape=(40, 48), dtype=np.uint8):
    frames = []
    for i in range(n):
        f = np.full(shape, 20, dtype)
        x = 5 + 2 * i % (shape[1] - 15)
        f[10:20, x:x + 8] = 230
        frames.append(f)
    return frames


def test_frame_size_change_resets_and_says_so():
    det = ThermalDetector()
    for i, f in enumerate(moving_square_frames(10)):
        det.process(f, i * 0.04)
    assert det.last_mode == "tracking" and det.resets == 0
    out = det.process(np.full((30, 30), 20, np.uint8), 0.5)
    assert out == [] and det.resets == 1 and det.last_reset
    assert det.last_mode == "warming_up"
    det.process(np.full((30, 30), 20, np.uint8), 0.54)
    assert not det.last_reset
    # a change of encoding at the same size is a reset too
    det.process(np.full((30, 30), 2000, np.uint16), 0.58)
    assert det.resets == 2


def test_scene_played_twice_resets_once_and_detects_again():
    """A bag played in a loop: the second pass's stamps start again below the first's.
    The detector resets once (window and objects cleared), says so, and detects from the
    new frames within F_s frames, like at start-up."""
    cfg = ThermalDetectorConfig()
    frames = moving_square_frames(16)
    stamps = [10.0 + 0.04 * i for i in range(len(frames))]
    det = ThermalDetector(cfg)
    first = [det.process(f, t) for f, t in zip(frames, stamps)]
    assert det.resets == 0 and det.time_resets == 0
    assert all(len(d) == 1 for d in first[cfg.startup_frames - 1:])
    second, modes, events = [], [], []
    for i, (f, t) in enumerate(zip(frames, stamps)):
        second.append(det.process(f, t))
        modes.append(det.last_mode)
        events.append(det.last_event)
        if i == 0:
            assert det.last_reset and det.tracks == []
    gap = stamps[-1] - stamps[0]
    assert events[0] == f"time went backwards by {gap:.3f} s: reset"
    assert events[1:] == [None] * (len(frames) - 1)
    assert det.time_resets == 1 and det.resets == 1
    assert "out_of_order" not in modes
    # no frame of the new pass is skipped; the first F_s - 1 fill the new window
    assert modes[:cfg.startup_frames - 1] == ["warming_up"] * (cfg.startup_frames - 1)
    resumed = next(i for i, d in enumerate(second) if d)
    assert resumed <= cfg.startup_frames - 1
    assert all(len(d) == 1 for d in second[resumed:])
    # same frames, same window: the second pass finds the square where the first did
    for a, b in zip(first[resumed:], second[resumed:]):
        assert np.allclose(a[0].centroid, b[0].centroid, atol=1e-6)


def test_constant_and_all_nan_frames_give_no_detections():
    det = ThermalDetector()
    for i in range(12):
        assert det.process(np.full((32, 32), 77, np.uint8), i * 0.04) == []
    # a constant stream repeats its first frame: a frozen camera, skipped
    assert det.last_mode == "repeated_frame" and det.repeated_frames == 11
    det = ThermalDetector()
    for i in range(12):
        assert det.process(np.full((32, 32), np.nan, np.float32), i * 0.04) == []
    assert det.last_mode == "invalid_frame" and det.skipped_frames == 12
    det = ThermalDetector()
    for i in range(12):
        assert det.process(np.full((32, 32), 301.5, np.float32), i * 0.04, "32FC1") == []


def test_fewer_than_startup_frames_returns_nothing_yet():
    cfg = ThermalDetectorConfig(startup_frames=6)
    det = ThermalDetector(cfg)
    frames = moving_square_frames(6)
    for i, f in enumerate(frames[:5]):
        assert det.process(f, i * 0.04) == []
        assert det.last_mode == "warming_up"
    assert len(det.process(frames[5], 0.2)) == 1
    assert det.last_mode == "startup"


def test_bad_input_raises_our_error_or_is_skipped():
    det = ThermalDetector()
    with pytest.raises(ThermalInputError):
        det.process(np.zeros((4, 4, 3), np.uint8), 0.0)
    with pytest.raises(ThermalInputError):
        det.process(np.zeros((4, 4), np.int64), 0.0)
    with pytest.raises(ThermalInputError):
        det.process(np.zeros((4, 4), np.uint8), float("nan"))
    with pytest.raises(ThermalInputError):
        det.process(np.zeros((4, 4), np.uint8), 0.0, encoding="mono16")
    det.process(np.zeros((4, 4), np.uint8), 1.0)
    assert det.process(np.zeros((4, 4), np.uint8), 1.0) == []      # same stamp again
    assert det.last_mode == "out_of_order"
    with pytest.raises(ValueError):
        ThermalDetector(ThermalDetectorConfig(block_size=1))


def test_memory_stays_bounded_over_a_long_stream():
    cfg = ThermalDetectorConfig(reconfigure_period=7)
    det = ThermalDetector(cfg)
    frames = moving_square_frames(16)
    for i in range(160):
        det.process(frames[i % 16], i * 0.04)
        assert len(det._window) <= max(cfg.window_frames, cfg.startup_frames)
        assert len(det.tracks) <= cfg.max_objects
    assert det.full_passes >= 160 // 7 - 1


def test_reset_forgets_everything():
    det = ThermalDetector()
    for i, f in enumerate(moving_square_frames(10)):
        det.process(f, i * 0.04)
    assert det.tracks
    det.reset()
    assert det.tracks == [] and det.last_mode == "warming_up"
    assert det.process(moving_square_frames(1)[0], 0.0) == []   # earlier stamps are fine now


def test_every_constant_is_a_declared_parameter_with_paper_defaults():
    specs = {s.name: s for s in parameter_specs(ThermalDetectorConfig)}
    assert specs["sigma2"].default == 0.01
    for name in ("lam", "max_cycles", "tol", "block_size", "window_frames", "startup_frames",
                 "reconfigure_period", "merge_distance_sq", "max_objects", "kalman.sigma_u",
                 "kalman.sigma_w"):
        assert name in specs
    assert specs["kalman.sigma_w"].default < 3.0           # Sec. 4: "less than 3 pixels"


# -- compiled paths against the numpy reference ----------------------------------------------

def _moving_blob_levels(rng, n_frames, h, w, lo=20, hi=230, offset=0):
    frames = rng.integers(lo - 3, lo + 4, size=(n_frames, h, w)).astype(np.float32)
    for t in range(n_frames):
        for k in range(3):
            y, x = 5 + 7 * k + t, 4 + 9 * k + 2 * t
            frames[t, y:y + 6, x:x + 5] = hi - 10 * k
    frames[:, h // 2, w // 3] = [lo + 60 * (t % 2) for t in range(n_frames)]   # flicker
    return frames - offset


@pytest.mark.parametrize("h,w,offset", [(40, 48, 0), (37, 45, 0), (37, 45, 30)])
def test_compiled_support_equals_the_numpy_reference(h, w, offset):
    """The fused numba block loop (variance, skip rule, (3.5), Algorithm 1 per block) gives
    the support and the kernel variance of the numpy reference: whole frame, a block mask,
    frame sizes that are not multiples of rho (padding), and negative levels (an offset
    above some pixels, as mono16 normalisation produces)."""
    from mk_tracker.detection.block_support import _fused_kernel, support_in_frame
    if _fused_kernel() is None:
        pytest.skip("numba not installed")
    rng = np.random.default_rng(h * w + offset)
    cfg = ThermalDetectorConfig()
    window = _moving_blob_levels(rng, 5, h, w, offset=offset)
    rho = cfg.block_size
    mask = np.zeros((-(-h // rho), -(-w // rho)), dtype=bool)
    mask[1:7, 2:9] = True
    mask[-1, -1] = True
    for block_mask in (None, mask):
        ref = support_in_frame(window, cfg, 1 / 255, True, block_mask, backend="numpy")
        fast = support_in_frame(window, cfg, 1 / 255, True, block_mask, backend="compiled")
        assert ref.blocks_factored > 3
        assert fast.blocks_factored == ref.blocks_factored
        assert fast.blocks_total == ref.blocks_total
        np.testing.assert_array_equal(fast.support, ref.support)
        np.testing.assert_allclose(fast.variance, ref.variance, atol=1e-6)
        assert ref.support.any()
    with pytest.raises(ThermalInputError):
        support_in_frame(window, cfg, 1 / 255, False, backend="compiled")


def test_compiled_support_with_many_active_blocks_equals_the_numpy_reference():
    """More active blocks than the lock-step batch holds, and not a multiple of it: full
    batches and the last partial one are factored and written where their blocks are."""
    from mk_tracker.detection.block_support import (_LOCKSTEP_BLOCKS, _fused_kernel,
                                                    support_in_frame)
    if _fused_kernel() is None:
        pytest.skip("numba not installed")
    rng = np.random.default_rng(11)
    cfg = ThermalDetectorConfig()
    window = _moving_blob_levels(rng, 4, 62, 70)
    window[:, 40:56, 10:50] = rng.integers(20, 230, size=(4, 16, 40))    # busy patch
    ref = support_in_frame(window, cfg, 1 / 255, True, backend="numpy")
    fast = support_in_frame(window, cfg, 1 / 255, True, backend="compiled")
    assert ref.blocks_factored > 3 * _LOCKSTEP_BLOCKS
    assert ref.blocks_factored % _LOCKSTEP_BLOCKS != 0
    assert fast.blocks_factored == ref.blocks_factored
    np.testing.assert_array_equal(fast.support, ref.support)
    np.testing.assert_allclose(fast.variance, ref.variance, atol=1e-6)


def test_compiled_detector_equals_the_numpy_reference(monkeypatch):
    """Whole detector, 5 people at 320x240: the compiled support loop, support ownership and
    footprint flood fill give exactly the detections of the numpy/OpenCV reference
    (MK_TRACKER_NO_NUMBA)."""
    import mk_tracker.detection.kernel_covariance as kc
    import mk_tracker.detection.sparse_factorization as sf
    import mk_tracker.detection.block_support as bs
    import mk_tracker.detection.footprint as fp
    from mk_tracker.synthetic.presets import crowd_scene
    if bs._fused_kernel() is None or fp._footprint_kernel() is None or \
            fp._owner_kernel() is None:
        pytest.skip("numba not installed")
    scene = crowd_scene(5, seed=3, width=320, height=240, frames=36)
    frames = [scene.frame(i) for i in range(len(scene))]

    def run():
        det = ThermalDetector(ThermalDetectorConfig(reconfigure_period=10))
        out = []
        for fr in frames:
            out.append([(d.centroid, d.box, d.pixel_count, d.object_id, d.score)
                        for d in det.process(fr.thermal, fr.stamp)])
        return out

    fast = run()
    for module, name in ((bs, "_FUSED"), (fp, "_FOOTPRINT"), (fp, "_OWNER"),
                         (sf, "_COMPILED"), (kc, "_LEVEL_KERNELS")):
        monkeypatch.setattr(module, name, [None])
    assert bs._fused_kernel() is None and sf._compiled_kernel() is None
    ref = run()
    assert sum(len(f) for f in ref) > 60            # people were found
    assert len(fast) == len(ref)
    for a, b in zip(fast, ref):
        assert [x[1:4] for x in a] == [x[1:4] for x in b]
        for x, y in zip(a, b):
            assert x[0] == pytest.approx(y[0], abs=1e-9)
            assert x[4] == pytest.approx(y[4], abs=1e-6)


def test_compiled_background_median_equals_numpy_median():
    """The footprint's background level: counting (integer levels) and partition (other
    values) give np.median's value exactly, odd and even sample sizes."""
    import mk_tracker.detection.footprint as fp
    if fp._footprint_kernel() is None:
        pytest.skip("numba not installed")
    rng = np.random.default_rng(11)
    samples = [rng.integers(0, 256, n).astype(np.float32) for n in (1, 2, 7, 8, 2047, 2048)]
    samples += [rng.integers(-40, 4000, n).astype(np.float32) for n in (3, 10, 1001)]
    samples += [np.full(6, 17, np.float32), np.array([5, 5, 9, 9], np.float32)]
    samples += [rng.normal(300.0, 2.0, n).astype(np.float32) for n in (5, 64, 999)]
    for sample in samples:
        expected = np.float32(np.median(sample))
        assert fp._sample_median(sample) == expected, sample[:8]
        assert fp._median(sample) == expected


def test_stale_compiled_support_cache_is_dropped(tmp_path):
    """The fused support loop embeds code of two other modules, which numba's cache does
    not track: a changed digest of their sources flushes the cache, an unchanged one not."""
    from mk_tracker.detection.block_support import _drop_stale_cache

    class FakeCache:
        cache_path = str(tmp_path)
        flushed = 0

        def flush(self):
            self.flushed += 1

    class FakeKernel:
        _cache = FakeCache()

    kernel = FakeKernel()
    assert _drop_stale_cache(kernel) and kernel._cache.flushed == 1     # no digest yet
    assert not _drop_stale_cache(kernel) and kernel._cache.flushed == 1
    (tmp_path / "block_support._support_loops.deps").write_text("0" * 64)
    assert _drop_stale_cache(kernel) and kernel._cache.flushed == 2     # sources changed
    assert not _drop_stale_cache(kernel)


def test_levels_beyond_the_kernel_table_fall_back_to_the_exponential_path():
    """mono16 counts spanning more than the table inside one block: the compiled loop
    declines (-1) and the numpy path with exponentials gives the support."""
    from mk_tracker.detection.block_support import TABLE_LEVELS, _fused_kernel, support_in_frame
    rng = np.random.default_rng(5)
    window = _moving_blob_levels(rng, 5, 24, 32, lo=100, hi=100 + TABLE_LEVELS + 900)
    cfg = ThermalDetectorConfig()
    scale = 1.0 / (TABLE_LEVELS + 1000)
    ref = support_in_frame(window, cfg, scale, False, backend="numpy")
    assert ref.support.any()
    auto = support_in_frame(window, cfg, scale, True)
    np.testing.assert_array_equal(auto.support, ref.support)
    np.testing.assert_allclose(auto.variance, ref.variance, atol=1e-6)
    if _fused_kernel() is not None:
        with_table = support_in_frame(window[:, :8, :8] * 0 + 7, cfg, scale, True,
                                      backend="compiled")
        assert not with_table.support.any()


def _touching_pair_frames(n_frames: int = 8) -> list[np.ndarray]:
    """Two warm 'people' (bodies 110 and 125, heads 165) side by side with no gap, walking
    right 2 px per frame over a background of 40 (mono8)."""
    frames = []
    for t in range(n_frames):
        f = np.full((80, 120), 40, dtype=np.uint8)
        x = 20 + 2 * t
        f[25:70, x:x + 14] = 110             # body of the left one
        f[25:70, x + 14:x + 28] = 125        # body of the right one, touching it
        f[15:25, x + 3:x + 11] = 165         # heads
        f[15:25, x + 17:x + 25] = 165
        frames.append(f)
    return frames


def test_touching_people_are_split_along_the_valley_between_them():
    """The footprints of two people who touch are one connected region (and one object
    without the split); split_by_valleys gives one detection per person, each centroid
    inside that person."""
    frames = _touching_pair_frames()

    def first_detections(**over):
        det = ThermalDetector(ThermalDetectorConfig(**over))
        for t, f in enumerate(frames):
            out = det.process(f, float(t) / 10.0)
            if det.last_mode == "startup":
                return out, 20 + 2 * t
        raise AssertionError("no start-up pass")

    merged, _ = first_detections(split_by_valleys=False)
    assert len(merged) == 1
    split, x = first_detections(split_by_valleys=True)
    assert len(split) == 2
    cxs = sorted(d.centroid[0] for d in split)
    assert x <= cxs[0] < x + 14 <= cxs[1] < x + 28


def _startup_boxes(frames, **over):
    """The boxes of the detector's start-up pass over ``(t, frame, x)`` and that ``x``."""
    det = ThermalDetector(ThermalDetectorConfig(**over))
    for t, f, x in frames:
        out = det.process(f, float(t) / 10.0)
        if det.last_mode == "startup":
            return sorted(tuple(d.box) for d in out), x
    raise AssertionError("no start-up pass")


def test_valley_columns_keeps_a_person_cut_at_the_belt_whole():
    """One person, warm upper body (165, rows 12-39) over a cool belt (80, rows 40-42) and
    legs (125, rows 43-69), 14 columns wide: the valley split cuts it across the belt into an
    upper and a lower box; with valley_columns the two parts share all their columns, so
    they are one person: one box, columns x .. x + 13, rows 12 .. 69."""
    def frames():
        for t in range(8):
            f = np.full((80, 120), 40, dtype=np.uint8)
            x = 30 + 2 * t
            f[12:40, x:x + 14] = 165
            f[40:43, x:x + 14] = 80
            f[43:70, x:x + 14] = 125
            yield t, f, x

    cut, x = _startup_boxes(frames(), split_by_valleys=True)
    assert len(cut) == 2 and cut[0][1] + cut[0][3] <= cut[1][1]        # stacked parts
    whole, x = _startup_boxes(frames(), split_by_valleys=True, valley_columns=True)
    assert whole == [(float(x), 12.0, 14.0, 58.0)]


def test_valley_columns_cuts_touching_people_into_whole_columns():
    """The touching pair of _touching_pair_frames (bodies 110 | 125, columns x .. x + 13 and
    x + 14 .. x + 27, rows 25-69; heads rows 15-24): cut at the emptiest column between the
    heads' mean columns x + 6.5 and x + 20.5.  Columns x + 11 .. x + 16 hold 45 pixels each;
    the coolest of them are x + 11 .. x + 13 (110), and x + 13 is nearest the midpoint
    x + 13.5: the left person gets columns x .. x + 12, the right one x + 13 .. x + 27, both
    with whole rows 15 .. 69 (the heads' rows are inside each part's columns)."""
    frames = ((t, f, 20 + 2 * t) for t, f in enumerate(_touching_pair_frames()))
    boxes, x = _startup_boxes(frames, split_by_valleys=True, valley_columns=True)
    assert boxes == [(float(x), 15.0, 13.0, 55.0), (float(x + 13), 15.0, 15.0, 55.0)]


def test_a_single_person_with_warm_hands_is_one_detection():
    """A person's hands are as warm as its head: small peaks beside a big one are parts of
    it (valley_min_peak_fraction), not people."""
    frames = []
    for t in range(8):
        f = np.full((80, 120), 40, dtype=np.uint8)
        x = 30 + 2 * t
        f[25:70, x:x + 18] = 120
        f[15:25, x + 5:x + 13] = 165           # head, 80 px
        f[48:50, x - 2:x] = 165                # hands, 4 px each, at the sides
        f[48:50, x + 18:x + 20] = 165
        frames.append(f)
    det = ThermalDetector(ThermalDetectorConfig(split_by_valleys=True))
    for t, f in enumerate(frames):
        out = det.process(f, float(t) / 10.0)
        if det.last_mode == "startup":
            assert len(out) == 1
            break
    else:
        raise AssertionError("no start-up pass")
    det = ThermalDetector(ThermalDetectorConfig(split_by_valleys=True,
                                                valley_min_peak_fraction=0.0,
                                                min_object_pixels=1))
    for t, f in enumerate(frames):
        out = det.process(f, float(t) / 10.0)
        if det.last_mode == "startup":
            assert len(out) > 1            # without the size rule the hands are split off
            break


def test_a_walking_person_passing_one_who_stands_still_keeps_its_own_box():
    """A person who stands still has no support (no temporal change), but its pixels are
    foreground: when a tracked person walks up to it, the tracked footprint fuses with it
    and its box grows; split_by_valleys splits it in the tracking pass and the tracked
    person keeps its own part.  (Bodies have cooler sides, as optics blur them with the
    background: the valley where two people touch.)"""
    def person(f, x, body):
        f[25:70, x:x + 14] = body
        f[25:70, x] = f[25:70, x + 13] = 80
        f[15:25, x + 3:x + 11] = 165

    def frames():
        for t in range(16):
            f = np.full((80, 120), 40, dtype=np.uint8)
            person(f, 70, 110)                     # standing still
            x = 30 + 2 * t                         # walking right, touching it from t = 13
            person(f, x, 125)                      # (in front of it)
            yield t, f, x

    def widths(**over):
        # the valley split alone (the person-size split would bring a full-frame pass
        # forward when the fused box appears)
        det = ThermalDetector(ThermalDetectorConfig(split_by_person_size=False,  # 10 Hz stamps,
                                                    counts_fps=0.0, **over))  # frames counted
        out = []
        for t, f, x in frames():
            dets = det.process(f, float(t) / 10.0)
            if t == 5:
                assert det.last_mode == "startup" and len(dets) == 1
            if t >= 13:
                assert det.last_mode == "tracking"
                assert len(dets) == 1
                out.append((dets[0].box[2], dets[0].centroid[0], x))
        return out

    fused = widths(split_by_valleys=False)
    assert fused and all(w > 20 for w, _, _ in fused)          # both people in one box
    split = widths(split_by_valleys=True)
    assert len(split) == len(fused)
    for w, cx, x in split:
        assert w <= 16 and x <= cx < x + 14


def test_a_small_far_person_of_the_scene_generator_is_never_split():
    """The scene (seed 2, one person, 320x240) where a coarser valley sweep split a far
    person into head and hand: one detection at most in every frame."""
    from mk_tracker.synthetic.presets import crowd_scene
    scene = crowd_scene(1, seed=2, width=320, height=240, frames=60)
    det = ThermalDetector(ThermalDetectorConfig(split_by_valleys=True))
    passes = 0
    for i in range(len(scene)):
        fr = scene.frame(i)
        assert len(det.process(fr.thermal, fr.stamp)) <= 1
        passes += det.last_mode in ("startup", "reconfiguration")
    assert passes == 3
