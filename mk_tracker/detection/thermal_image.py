"""Thermal frames as they come off real cameras, and their normalisation for the RBF kernel.

The kernel variance of Schizas et al. (3.6), ``sigma^2 = 0.01`` (Sec. 6), refers to pixel
intensities on the unit scale: the paper's 8-bit frames divided by 255.  With that scale two
pixels are "similar" (kernel > 1/2) when they differ by less than
``sigma * sqrt(2 ln 2) ~ 0.118``, i.e. ~30 grey levels of an 8-bit frame.

Accepted inputs (:data:`THERMAL_ENCODINGS`):

* ``mono8`` / ``8UC1`` (uint8): divided by 255, exactly as in the paper;
* ``mono16`` / ``16UC1`` (uint16 raw counts, e.g. 14-bit radiometric cores with the scene in
  a few thousand counts) and ``32FC1`` (float32 temperatures, which may hold NaN or +-inf for
  dead pixels): mapped affinely from a range ``[lo, hi]`` onto ``[0, 1]``.  The range is
  either fixed by the caller or, by default, the robust range (0.5 and 99.5 percentiles of
  the finite pixels) of the frames of a full-frame pass, kept until the next one so that all
  frames of a sliding window share one map (a map that changed inside a window would look
  like temporal change to (3.5)).

Missing pixels: NaN and +-inf are missing.  :func:`fill_missing` replaces each missing pixel
with the last valid value of that pixel (temporal hold), so a pixel that is missing stays
constant and, by the argument in :mod:`mk_tracker.detection.kernel_covariance`, contributes a zero row
and column to the kernel covariance instead of a spurious change.
"""

from __future__ import annotations

from typing import Any

import numpy as np

#: encoding -> numpy dtype of the raw frame.
THERMAL_ENCODINGS: dict[str, np.dtype] = {
    "mono8": np.dtype(np.uint8), "8UC1": np.dtype(np.uint8),
    "mono16": np.dtype(np.uint16), "16UC1": np.dtype(np.uint16),
    "32FC1": np.dtype(np.float32),
}

_DTYPE_ENCODING = {np.dtype(np.uint8): "mono8", np.dtype(np.uint16): "mono16",
                   np.dtype(np.float32): "32FC1", np.dtype(np.float64): "32FC1"}

#: Smallest accepted span hi - lo of a normalisation range; a narrower one (an all-constant
#: scene) is widened to 1 so the map stays finite (everything maps to ~0 -> no detections).
MIN_SPAN = 1e-6


class ThermalInputError(ValueError):
    """A thermal frame cannot be used (shape, dtype, encoding)."""


def thermal_encoding(frame: Any, encoding: str | None = None) -> str:
    """The canonical encoding (``mono8``, ``mono16`` or ``32FC1``) of a raw frame.

    ``encoding`` is checked against the array's dtype; ``None`` infers it from the dtype
    (float64 is accepted as ``32FC1``).
    """
    arr = np.asarray(frame)
    if encoding is None:
        if arr.dtype not in _DTYPE_ENCODING:
            raise ThermalInputError(f"thermal frame of dtype {arr.dtype} is not supported; "
                                    "expected uint8, uint16 or float32")
        return _DTYPE_ENCODING[arr.dtype]
    if encoding not in THERMAL_ENCODINGS:
        raise ThermalInputError(f"thermal encoding {encoding!r} is not supported; expected one "
                                f"of {sorted(THERMAL_ENCODINGS)}")
    expected = THERMAL_ENCODINGS[encoding]
    if arr.dtype != expected and not (expected == np.float32 and arr.dtype == np.float64):
        raise ThermalInputError(f"encoding {encoding} needs dtype {expected}, got {arr.dtype}")
    return _DTYPE_ENCODING[expected]


def as_thermal_array(frame: Any, encoding: str | None = None) -> tuple[np.ndarray, str]:
    """``(float32 H x W array, canonical encoding)``; missing pixels become NaN.

    Accepts ``(H, W)`` or ``(H, W, 1)``.  Raises :class:`ThermalInputError` otherwise.
    """
    arr, enc = thermal_view(frame, encoding)
    out = arr.astype(np.float32, copy=True)
    if enc == "32FC1":
        out[~np.isfinite(out)] = np.nan
    return out, enc


def thermal_view(frame: Any, encoding: str | None = None) -> tuple[np.ndarray, str]:
    """``(H x W array as received, canonical encoding)``: the checks of
    :func:`as_thermal_array` without its float32 copy (a view when possible; its values
    are the raw ones, missing pixels not yet NaN)."""
    try:
        arr = np.asarray(frame)
    except Exception as exc:  # noqa: BLE001 - anything numpy cannot read is bad input
        raise ThermalInputError(f"thermal frame is not an array: {exc}") from exc
    enc = thermal_encoding(arr, encoding)
    if arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[:, :, 0]
    if arr.ndim != 2:
        raise ThermalInputError(f"thermal frame must be 2-D (H, W), got shape {arr.shape}")
    if arr.shape[0] < 1 or arr.shape[1] < 1:
        raise ThermalInputError(f"thermal frame is empty, shape {arr.shape}")
    return arr, enc


def robust_range(frames: np.ndarray, low_percentile: float = 0.5,
                 high_percentile: float = 99.5,
                 max_samples: int = 50_000) -> tuple[float, float] | None:
    """``(lo, hi)`` percentiles of the finite values of ``frames``; ``None`` if none is finite.

    A deterministic stride subsample of at most ``max_samples`` values keeps it cheap.
    """
    flat = np.asarray(frames, dtype=np.float32).reshape(-1)
    step = max(1, flat.size // max_samples)
    sample = flat[::step]
    sample = sample[np.isfinite(sample)]
    if sample.size == 0:
        return None
    lo, hi = np.percentile(sample, [low_percentile, high_percentile])
    return float(lo), float(hi)


def normalization_map(encoding: str, value_range: tuple[float, float] | None
                      ) -> tuple[float, float]:
    """``(offset, scale)`` such that ``(raw - offset) * scale`` is on the kernel's unit scale.

    ``mono8`` without a range is the paper's ``raw / 255``.  Otherwise ``value_range`` is
    required and mapped onto ``[0, 1]``.
    """
    if value_range is None:
        if encoding == "mono8":
            return 0.0, 1.0 / 255.0
        raise ThermalInputError(f"{encoding} frames need a normalisation range (lo, hi)")
    lo, hi = (float(v) for v in value_range)
    if not (np.isfinite(lo) and np.isfinite(hi)):
        raise ThermalInputError(f"normalisation range {value_range!r} is not finite")
    span = hi - lo
    if span < MIN_SPAN:
        span = 1.0
    return lo, 1.0 / span


def normalize(raw: np.ndarray, offset: float, scale: float) -> np.ndarray:
    """``(raw - offset) * scale`` as float32 (NaN stays NaN)."""
    out = np.subtract(raw, np.float32(offset), dtype=np.float32)
    out *= np.float32(scale)
    return out


def fill_missing(frame: np.ndarray, previous: np.ndarray | None) -> tuple[np.ndarray, int]:
    """Replace NaN pixels by ``previous`` (temporal hold); ``(filled copy, n_missing)``.

    Without a previous frame, missing pixels get the median of the frame's valid pixels
    (0 if there is none).
    """
    missing = np.isnan(frame)
    n = int(np.count_nonzero(missing))
    if n == 0:
        return frame, 0
    out = frame.copy()
    if previous is not None and previous.shape == frame.shape:
        out[missing] = previous[missing]
    else:
        valid = frame[~missing]
        out[missing] = np.float32(np.median(valid)) if valid.size else np.float32(0.0)
    return out, n
