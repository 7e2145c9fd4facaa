"""Compensation of a thermal camera's automatic gain control (issue #19): the intensity map
fitted between two frames, and the detector on frames whose gain and offset jump."""

import dataclasses

import numpy as np
import pytest

from mk_tracker.detection.gain_compensation import GainConfig, compensate, fit_intensity_map
from mk_tracker.detection.thermal_detector import ThermalDetector, ThermalDetectorConfig

H, W = 96, 128
MOVER = 12             # side of the warm square that walks across the scene (px)


def background(seed: int = 0) -> np.ndarray:
    """A static scene with texture over most of the grey range: gradients and blobs."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:H, 0:W]
    scene = 40.0 + 90.0 * xx / W + 30.0 * np.sin(yy / 9.0) * np.cos(xx / 13.0)
    for _ in range(6):
        cy, cx = rng.uniform(0, H), rng.uniform(0, W)
        scene += 40.0 * np.exp(-((yy - cy) ** 2 + (xx - cx) ** 2) / 60.0)
    return scene


def scene_frame(k: int, gain: float = 1.0, offset: float = 0.0, seed: int = 0) -> np.ndarray:
    """Frame ``k``: the background with the mover at column ``10 + 3 k``, sensor noise, then
    the camera's gain and offset, as uint8."""
    rng = np.random.default_rng(1000 + k)
    f = background(seed) + rng.normal(0.0, 1.0, (H, W))
    x = 10 + 3 * k
    f[40:40 + MOVER, x:x + MOVER] = 235.0
    return np.clip(np.rint(gain * f + offset), 0, 255).astype(np.uint8)


def mover_centre(k: int) -> tuple[float, float]:
    return 10 + 3 * k + MOVER / 2.0, 40 + MOVER / 2.0


# -- the fit ---------------------------------------------------------------------------------

def test_affine_fit_maps_a_gain_and_offset_change_back():
    reference = scene_frame(0).astype(np.float32)
    changed = scene_frame(1, gain=0.7, offset=10.0)        # the mover moved, too
    fit = fit_intensity_map(changed, reference, 1, 30.0, step=2, limits=(0, 255),
                            resolution=1.0)
    assert fit.gain == pytest.approx(1.0 / 0.7, rel=0.02)
    mapped = fit(changed)
    still = np.ones((H, W), dtype=bool)
    still[40:40 + MOVER, 10:10 + MOVER + 3] = False          # the mover in either frame
    err = np.abs(mapped - reference)[still]
    # noise of two frames (std 1 each, the changed one scaled up by 1.4) and rounding
    assert err.mean() < 1.6 and np.percentile(err, 99) < 5.0
    assert fit.similar_fraction > 0.95
    # without the map the same pixels are far apart
    assert np.abs(changed.astype(np.float32) - reference)[still].mean() > 10.0


def test_compensate_maps_integer_frames_keeps_zero_and_refuses_too_large_a_change():
    reference = scene_frame(0)
    changed = scene_frame(1, gain=0.7, offset=10.0)
    changed[:8, :8] = 0                                        # masked: an ignore region
    cfg = GainConfig(model="affine", relaxation=0.0)
    mapped, fit = compensate(changed, reference.astype(np.float32), cfg, 30.0)
    # integer levels in, whole levels out (the detector's integer-level kernel tables)
    assert np.all(mapped == np.rint(mapped)) and fit.gain == pytest.approx(1.0 / 0.7, rel=0.03)
    assert np.all(mapped[:8, :8] == 0)
    still = np.ones((H, W), dtype=bool)
    still[40:40 + MOVER, 10:10 + MOVER + 3] = False
    still[:8, :8] = False
    diff = np.abs(mapped.astype(np.float32) - reference)[still]
    assert diff.mean() < 2.0
    # float frames: mapped without rounding
    mapped_f, _ = compensate(changed.astype(np.float32), reference.astype(np.float32), cfg,
                             30.0)
    assert not np.all(mapped_f == np.rint(mapped_f))
    # another scene altogether: no map, the caller starts a new window
    other = np.ascontiguousarray(np.flipud(np.fliplr(scene_frame(0, seed=5))))
    refused, fit = compensate(other, reference.astype(np.float32),
                              GainConfig(model="affine", max_gain_ratio=1.2), 5.0)
    assert refused is None and fit.similar_fraction < cfg.min_similar_fraction


def test_quadratic_fit_follows_a_gamma_change_better_than_affine():
    reference = scene_frame(0).astype(np.float32)
    changed = np.clip(np.rint(255.0 * (scene_frame(0) / 255.0) ** 1.6), 0, 255).astype(np.uint8)
    errors = {}
    for degree in (1, 2):
        fit = fit_intensity_map(changed, reference, degree, 30.0, step=2, limits=(0, 255),
                                resolution=1.0)
        errors[degree] = float(np.abs(fit(changed) - reference).mean())
    assert errors[2] < 0.5 * errors[1]


def test_a_flat_frame_gets_an_offset_and_no_gain():
    reference = np.full((H, W), 100.0, dtype=np.float32)
    changed = np.full((H, W), 130, dtype=np.uint8)
    fit = fit_intensity_map(changed, reference, 1, 30.0, limits=(0, 255), resolution=1.0)
    assert fit.gain == 1.0
    np.testing.assert_allclose(fit(changed), reference)


def test_clipped_and_missing_pixels_stay_out_of_the_fit():
    reference = background().astype(np.float32)
    changed = 0.9 * reference + 10.0
    changed[:, :W // 3] = np.nan                             # missing: not fitted, stay NaN
    changed[:10] = 0.0                                      # at the lower limit: left out
    fit = fit_intensity_map(changed, reference, 1, 30.0, step=1, limits=(0.0, 255.0))
    assert fit.gain == pytest.approx(1.0 / 0.9, rel=1e-4)
    mapped = fit(changed)
    assert np.isnan(mapped[10:, :W // 3]).all()
    np.testing.assert_allclose(mapped[10:, W // 3:], reference[10:, W // 3:], atol=1e-3)


def test_bad_arguments_are_refused():
    frame = np.zeros((H, W), dtype=np.float32)
    with pytest.raises(ValueError, match="degree"):
        fit_intensity_map(frame, frame, 3, 30.0)
    with pytest.raises(ValueError, match="differ"):
        fit_intensity_map(frame, frame[:10], 1, 30.0)


# -- the detector ----------------------------------------------------------------------------

def run(model: str, gain_at, n: int = 40, **over):
    """Detections per frame of a detector with ``gain.model = model`` on frames whose
    ``(gain, offset)`` is ``gain_at(k)``."""
    config = ThermalDetectorConfig(gain=GainConfig(model=model, **over))
    det = ThermalDetector(config)
    out = []
    for k in range(n):
        out.append(det.process(scene_frame(k, *gain_at(k)), k / 30.0))
    return det, out


#: the gain steps two frames before the first reconfiguration (F_s = 6, T_c = 25: full-frame
#: passes at frames 5 and 30), whose window then holds frames from both sides of the step
STEP = 28


def step(k: int) -> tuple[float, float]:
    return (0.6, -10.0) if k >= STEP else (1.0, 0.0)


def largest_area(frames) -> float:
    return max((d.box[2] * d.box[3] for dets in frames for d in dets), default=0.0)


def test_without_compensation_a_gain_step_floods_the_frame():
    # the check that the scene is a real test: the step is seen by (3.5) as change everywhere
    det, frames = run("off", step)
    assert det.config.startup_frames == 6 and det.config.reconfigure_period == 25
    assert largest_area(frames[STEP:STEP + 4]) > 0.5 * H * W


@pytest.mark.parametrize("model", ["affine", "quadratic"])
def test_with_compensation_a_gain_step_gives_no_frame_sized_detection_and_keeps_the_mover(
        model):
    det, frames = run(model, step)
    _, plain = run("off", lambda k: (1.0, 0.0))           # no step, no compensation
    assert largest_area(frames) < 8 * MOVER * MOVER
    assert det.gain_resets == 0

    def error(dets, k):
        cx, cy = mover_centre(k)
        return min(np.hypot(d.centroid[0] - cx, d.centroid[1] - cy) for d in dets)
    for k in range(det.config.startup_frames, len(frames)):
        assert frames[k], f"the mover is lost at frame {k}"
        # as well placed as without any step (a full-frame pass reports the swept area)
        assert error(frames[k], k) <= error(plain[k], k) + 1.0, k


def test_unchanged_gain_gives_the_same_detections_as_no_compensation():
    _, plain = run("off", lambda k: (1.0, 0.0))
    _, mapped = run("affine", lambda k: (1.0, 0.0))
    assert [len(d) for d in plain] == [len(d) for d in mapped]
    for a, b in zip(plain, mapped):
        for da, db in zip(a, b):
            assert np.allclose(da.box, db.box, atol=1.0)


def test_a_change_too_large_to_compensate_starts_a_new_window_and_says_so():
    def inverted_from_12(k):            # a negative gain is no AGC: another picture
        return (-1.0, 255.0) if k >= 12 else (1.0, 0.0)

    det = ThermalDetector(ThermalDetectorConfig(gain=GainConfig(model="affine")))
    events, frames = [], []
    for k in range(30):
        frames.append(det.process(scene_frame(k, *inverted_from_12(k)), k / 30.0))
        events.append(det.last_event)
    assert det.gain_resets == 1 and det.resets == 1
    assert "too large to compensate" in events[12]
    assert all(e is None for i, e in enumerate(events) if i != 12)
    fs = det.config.startup_frames
    assert all(f == [] for f in frames[12:12 + fs - 1])      # a new window fills up
    assert largest_area(frames) < 8 * MOVER * MOVER
    assert all(frames[k] for k in range(12 + fs - 1, 30))   # and detection resumes


def test_float_frames_with_missing_pixels_and_a_gain_step():
    def run_float(model, gain_at):
        det = ThermalDetector(ThermalDetectorConfig(gain=GainConfig(model=model)))
        found = []
        for k in range(40):
            frame = scene_frame(k, *gain_at(k)).astype(np.float32) * 0.1 + 273.0   # kelvin
            frame[5:9, 5:60] = np.nan
            found.append(det.process(frame, k / 30.0))
        return det, found
    _, plain = run_float("off", lambda k: (1.0, 0.0))
    _, flooded = run_float("off", step)
    det, found = run_float("affine", step)
    assert largest_area(flooded) > 0.5 * H * W
    assert det.gain_resets == 0
    assert largest_area(found) <= largest_area(plain)
    assert all(found[k] for k in range(det.config.startup_frames, 40))


def test_constant_frames_with_a_level_step_give_nothing_and_no_error():
    det = ThermalDetector(ThermalDetectorConfig(gain=GainConfig(model="affine")))
    for k in range(20):
        level = 90 if k < 10 else 140
        assert det.process(np.full((H, W), level, dtype=np.uint8), k / 30.0) == []
    assert det.gain_resets == 0


def test_masked_pixels_stay_constant_under_a_gain_step():
    # ignore regions are masked with 0 before the detector: a gain step must not make them
    # change (the map sends 0 to its offset)
    def masked(k):
        f = scene_frame(k, *step(k))
        f[:30, :30] = 0
        return f
    det = ThermalDetector(ThermalDetectorConfig(gain=GainConfig(model="affine")))
    for k in range(30):
        for d in det.process(masked(k), k / 30.0):
            assert not (d.box[0] < 30 and d.box[1] < 30), (k, d.box)


def test_the_gain_parameters_are_declared():
    fields = {f.name for f in dataclasses.fields(GainConfig)}
    assert {"model", "sample_step", "iterations", "min_similar_fraction",
            "max_gain_ratio"} <= fields


def test_mono16_frames_with_a_gain_step():
    def run16(model):
        det = ThermalDetector(ThermalDetectorConfig(gain=GainConfig(model=model)))
        found = []
        for k in range(40):
            frame = (scene_frame(k, *step(k)).astype(np.uint16) * 40 + 3000).astype(np.uint16)
            found.append(det.process(frame, k / 30.0))
        return det, found
    _, flooded = run16("off")
    det, found = run16("affine")
    assert largest_area(flooded) > 0.5 * H * W
    assert det.gain_resets == 0
    assert largest_area(found) < 8 * MOVER * MOVER
    assert all(found[k] for k in range(det.config.startup_frames, 40))
