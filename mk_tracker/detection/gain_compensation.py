"""Photometric compensation of automatic gain control (AGC) for the thermal detector.

Not in Schizas et al. (2018).  Uncooled LWIR cameras with 8-bit video map the sensor's
counts ``r`` (close to linear in the scene radiance) to grey levels by a gain and an
offset that their AGC changes when something hot or cold enters the view, slowly or in
jumps: ``y = g r + o``.  Two frames of a static scene taken with ``(g1, o1)`` and
``(g2, o2)`` are therefore related by the affine map ``y2 = (g2 / g1)(y1 - o1) + o2``.  The
kernel covariance (3.5) over a window of frames sees such a change as temporal change of
*every* pixel: by (3.6) a pixel whose level moved by more than the similarity radius
``sigma sqrt(2 ln 2)`` (~30 grey levels of a mono8 frame divided by 255) is as different
as a person against the background, so an AGC step inside the window of a full-frame
pass (Algorithm 2) turns the whole frame into support (one frame-sized object); in the
tracking passes, which look only in the (5.2) windows of the known objects, it is seen
there for F frames.  Cameras whose AGC equalises the histogram (plateau equalisation) apply a
monotone, not affine, map; a quadratic covers the gentle curves of that kind.

The compensation (relative radiometric normalisation, as between two images of one scene
taken with different exposures) maps every new frame onto the previous frame of the
detector's window, which was itself mapped onto its predecessor, so that all frames of a
window share the photometry of the window's first frame (up to the relaxation below):

1. sample every ``sample_step``-th pixel of every ``sample_step``-th row; pixels within 2 %
   of the encoding's limits (0 and the maximum of an integer frame: clipped, no
   intensity) in either frame, and missing ones, are left out;
2. ``p``, affine or quadratic, is fitted by least squares to the sorted sampled values of
   the new frame against the sorted values of the reference (quantile against quantile:
   histogram matching with a smooth map), then refitted ``iterations`` times on the
   pixels whose residual ``reference - p(new)`` is within 3 robust standard deviations
   (1.4826 x the median absolute deviation) of the last fit: the people, who moved between
   the two frames, have large residuals and drop out, and the static scene (background in
   both frames) stays.  Why quantiles and not a pixel-to-pixel least-squares fit: the
   latter's slope on a noisy ``new`` is attenuated by ``var(scene) / (var(scene) +
   var(noise))`` (regression dilution), a per cent or two a frame on BU-TIV-lab, and since
   the maps are chained it shrank that clip's contrast to a third within 150 frames; the
   quantile fit is symmetric in the two frames and has no such bias;
3. the fit is accepted when at least ``min_similar_fraction`` of the sampled pixels are
   similar in the kernel's own sense after it (``|p(new) - reference|`` within the
   similarity radius of (3.6)) and its gain ``p'`` at the sample mean lies in
   ``[1 / max_gain_ratio, max_gain_ratio]``; otherwise the change is too large to
   compensate (a frame that shows another scene, a gain jump that clipped most pixels) and
   the detector starts a new window from this frame (``ThermalDetector.gain_resets``).

The new frame is replaced by ``(1 - relaxation) p(new) + relaxation new``: a step of the
gain is undone at once, and the map then fades back to the frame as received over about
``1 / relaxation`` frames (50 by default, 1.7 s at 30 fps: a 30-level step then moves the
scene by 0.6 levels a frame, nothing to (3.5)), so slow drifts pass (they are no temporal
change within a window) and the chain of maps, each with its small error, cannot wander
off (without it BU-TIV-lab's contrast random-walked by +-15 %).  Values are rounded for
integer encodings, so that the detector's exact integer-level kernel tables still apply;
pixels of value 0 in integer frames keep 0, so the ignore regions (masked with 0) stay
constant.  A global gain change thus leaves the static scene unchanged before (3.5), and
what remains as temporal change is what moved.  Measured in docs/benchmark_thermal_gain.md.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from mk_tracker.parameters import parameter

__all__ = ["GainConfig", "IntensityMap", "fit_intensity_map", "compensate", "GAIN_MODELS"]

#: ``gain.model`` values -> polynomial degree (``off``: no compensation).
GAIN_MODELS = {"off": -1, "affine": 1, "quadratic": 2}

#: 1.4826 x the median absolute deviation is the standard deviation of a normal sample.
_MAD_TO_STD = 1.4826


@dataclass(frozen=True)
class GainConfig:
    """The constants of the AGC compensation (``detector.gain.*``)."""

    model: str = parameter(
        "off", "map every thermal frame onto the previous frame of the window before the "
        "kernel covariance (3.5), so that a change of the camera's automatic gain control "
        "leaves the static scene unchanged: an affine or quadratic intensity map fitted "
        "quantile to quantile over the pixels that stayed background "
        "(mk_tracker.detection.gain_compensation; not in the paper); off: frames as received",
        choices=tuple(GAIN_MODELS))
    sample_step: int = parameter(
        8, "the fit samples every n-th pixel of every n-th row", minimum=1, maximum=64)
    iterations: int = parameter(
        3, "robust refits, each on the pixels within 3 robust standard deviations of the "
        "last fit", minimum=0, maximum=20)
    min_similar_fraction: float = parameter(
        0.5, "a frame whose mapped samples are similar (kernel (3.6) >= 1/2) to the "
        "previous frame for fewer than this fraction cannot be compensated: the detector "
        "starts a new window from it (gain_resets)", minimum=0.0, maximum=1.0)
    relaxation: float = parameter(
        0.02, "each frame's map is moved this fraction of the way back to the frame as "
        "received, so that a compensated step fades out over ~1/relaxation frames (too "
        "slowly for (3.5) to see it within a window) and the chained maps cannot wander",
        minimum=0.0, maximum=1.0)
    max_gain_ratio: float = parameter(
        3.0, "a fitted gain above this or below its inverse cannot be compensated either",
        minimum=1.0, maximum=1000.0)


@dataclass(frozen=True)
class IntensityMap:
    """``p(x) = sum_k coefficients[k] u^k`` with ``u = (x - centre) / spread``."""

    coefficients: tuple[float, ...]
    centre: float
    spread: float
    #: fraction of the sampled pixels similar to the reference after the map (0..1)
    similar_fraction: float = 1.0

    @property
    def gain(self) -> float:
        """``p'(centre)``: the contrast change at the sampled pixels' mean level."""
        return self.coefficients[1] / self.spread if len(self.coefficients) > 1 else 1.0

    def relaxed(self, fraction: float) -> "IntensityMap":
        """``(1 - fraction) p(x) + fraction x``: this map moved ``fraction`` of the way back
        to the identity."""
        keep = 1.0 - fraction
        coef = [keep * v for v in self.coefficients]
        coef[0] += fraction * self.centre
        coef[1] += fraction * self.spread
        return IntensityMap(tuple(coef), self.centre, self.spread, self.similar_fraction)

    def __call__(self, values: np.ndarray) -> np.ndarray:
        """``p(values)`` as float32 (Horner's rule; NaN stays NaN)."""
        u = np.subtract(values, np.float32(self.centre), dtype=np.float32)
        u *= np.float32(1.0 / self.spread)
        out = np.full(u.shape, np.float32(self.coefficients[-1]), dtype=np.float32)
        for coef in reversed(self.coefficients[:-1]):
            out *= u
            out += np.float32(coef)
        return out


def identity_map() -> IntensityMap:
    """The map that leaves every value as it is."""
    return IntensityMap((0.0, 1.0), 0.0, 1.0)


def fit_intensity_map(frame: np.ndarray, reference: np.ndarray, degree: int,
                      radius: float, *, step: int = 8, iterations: int = 3,
                      limits: tuple[float, float] | None = None,
                      resolution: float = 0.0) -> IntensityMap:
    """Robust fit of ``reference ~ p(frame)``, ``p`` of ``degree`` 1 or 2 (module docstring).

    ``radius``: the similarity radius of (3.6) in the frames' units, for
    :attr:`IntensityMap.similar_fraction`.  ``limits``: values at which a pixel is clipped
    (pixels within 2 % of the range of them, in either frame, are left out).
    ``resolution``: the frames' quantisation step (1 for integer
    levels), a floor on the inlier band.  A frame too flat for a slope (fewer than two
    distinct sampled levels) gets an offset only; with fewer samples than coefficients the
    identity is returned.
    """
    if degree not in (1, 2):
        raise ValueError(f"degree must be 1 or 2, got {degree}")
    if frame.shape != reference.shape:
        raise ValueError(f"frame {frame.shape} and reference {reference.shape} differ")
    x = np.asarray(frame[::step, ::step], dtype=np.float64).ravel()
    y = np.asarray(reference[::step, ::step], dtype=np.float64).ravel()
    ok = np.isfinite(x) & np.isfinite(y)
    if limits is not None:
        # clipped in either frame, or close enough to a limit that noise was clipped (a
        # pair cut on one side only biases the fit): 2 % of the range on each side
        margin = 0.02 * (limits[1] - limits[0])
        lo, hi = limits[0] + margin, limits[1] - margin
        ok &= (x > lo) & (x < hi) & (y > lo) & (y < hi)
    x, y = x[ok], y[ok]
    if x.size < 2 * (degree + 1):
        return identity_map()
    centre = float(x.mean())
    spread = float(x.std())
    if not spread > max(resolution, 1e-9 * (abs(centre) + 1.0)):
        # no contrast to fit a gain on: the offset alone (median difference)
        offset = float(np.median(y - x))
        return IntensityMap((centre + offset, 1.0), centre, 1.0,
                            _similar(x + offset, y, radius))
    u = (x - centre) / spread
    design = np.vander(u, degree + 1, increasing=True)
    keep = np.ones(x.size, dtype=bool)
    coef = _quantile_fit(u, y, keep, degree)
    for _ in range(iterations):
        residual = y - design @ coef
        mad = float(np.median(np.abs(residual - np.median(residual))))
        band = max(3.0 * _MAD_TO_STD * mad, resolution)
        new_keep = np.abs(residual) <= band
        if np.count_nonzero(new_keep) < 2 * (degree + 1) or np.array_equal(new_keep, keep):
            break
        keep = new_keep
        coef = _quantile_fit(u, y, keep, degree)
    return IntensityMap(tuple(float(v) for v in coef), centre, spread,
                        _similar(design @ coef, y, radius))


def _quantile_fit(u: np.ndarray, y: np.ndarray, keep: np.ndarray, degree: int) -> np.ndarray:
    """Coefficients of ``p`` fitted by least squares to the sorted ``u[keep]`` against the
    sorted ``y[keep]`` (quantile against quantile: symmetric in the two frames, so free of
    the regression dilution of a pixel-to-pixel fit)."""
    uq = np.sort(u[keep])
    yq = np.sort(y[keep])
    return np.linalg.lstsq(np.vander(uq, degree + 1, increasing=True), yq, rcond=None)[0]


def _similar(mapped: np.ndarray, reference: np.ndarray, radius: float) -> float:
    """Fraction of samples whose mapped value is within ``radius`` of the reference."""
    return float(np.count_nonzero(np.abs(mapped - reference) <= radius)) / max(mapped.size, 1)


def compensate(frame: np.ndarray, reference: np.ndarray, config: GainConfig, radius: float
               ) -> tuple[np.ndarray | None, IntensityMap]:
    """``(frame mapped onto reference, the fitted map)`` for the detector's window (steps 1-3
    of the module docstring, then the relaxation); the frame is None when the change is too
    large to compensate (fewer than ``min_similar_fraction`` similar pixels after the fit,
    or a gain outside ``[1 / max_gain_ratio, max_gain_ratio]``): the caller starts a new
    window from ``frame`` as it is.  ``radius``: the similarity radius of (3.6) in the
    frame's units.  Integer frames are mapped by one look-up table of rounded levels, with
    0 kept at 0 (clipped, or masked by an ignore region: kept constant)."""
    integer = np.issubdtype(frame.dtype, np.integer)
    limits = (0.0, float(np.iinfo(frame.dtype).max)) if integer else None
    fit = fit_intensity_map(frame, reference, GAIN_MODELS[config.model], radius,
                            step=config.sample_step, iterations=config.iterations,
                            limits=limits, resolution=1.0 if integer else 0.0)
    if fit.similar_fraction < config.min_similar_fraction or not (
            1.0 / config.max_gain_ratio <= fit.gain <= config.max_gain_ratio):
        return None, fit
    mapped = fit.relaxed(config.relaxation)
    if not integer:
        return mapped(frame), fit
    table = mapped(np.arange(int(limits[1]) + 1, dtype=np.float32))
    np.rint(table, out=table)
    table[0] = 0.0
    return (cv2.LUT(frame, table) if frame.dtype == np.uint8 else np.take(table, frame)), fit
