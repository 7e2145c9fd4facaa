"""The kernel's bandwidth widened to the stream's temporal noise (issue #19: real LWIR
streams are noisier than the paper's).

Schizas, Maroulas & Ren (2018) fix the bandwidth of the RBF kernel (3.6) (Sec. 6:
``sigma^2 = 0.01`` on the unit intensity scale, 25.5 grey levels of mono8 as ``sigma``).
Algorithm 1 factors a block when a pixel's kernel variance ``Sigma(j, j)`` of (3.5) passes
``T(lambda)``, and for a pixel that only sees sensor noise of std ``s`` that variance grows
with ``s^2 / sigma^2``.  When the noise is a large fraction of ``sigma``, every block passes,
the support covers the frame and the detector reports one frame-sized object a frame
(docs/benchmark_thermal_conditions.md: 1.2 K of noise on the generator's mono8 scale,
10.5 grey levels, collapses at ``sigma / s`` = 2.4; 0.8 K, 3.5, does not).  Cameras whose
automatic gain stretches a uniform scene over the 8-bit range, or that equalise the
histogram, deliver such streams.

The rule: at each full-frame pass the temporal noise std ``s`` of the window is measured
(:func:`temporal_noise_std`), and the bandwidth used is
``sigma = max(sqrt(sigma2), noise_bandwidth * s)``: the configured ``sigma2`` wherever the
stream is as quiet as the paper's, wider where it is not.  It never narrows the kernel.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

__all__ = ["temporal_noise_std", "NoiseBandwidth"]

#: median |N(0, 1)|: the median absolute difference of two samples of noise of std ``s`` is
#: ``sqrt(2) * 0.6745 * s``
_MAD_GAUSS = 0.6744897501960817


def temporal_noise_std(frames: list[np.ndarray], step: int = 4) -> float:
    """Robust std of a pixel's temporal noise in ``frames`` (consecutive, same shape), in
    their units: the median over a grid of every ``step``-th pixel of the absolute
    differences of consecutive frames, divided by ``sqrt(2) * 0.6745`` (the median
    absolute value of the difference of two Gaussian samples).  The people who move
    cover a minority of the pixels, so the median is the noise's.  A stream whose static
    pixels are bit-identical between frames (H.264) gives 0."""
    if len(frames) < 2:
        return 0.0
    sub = [np.asarray(f)[::step, ::step].astype(np.float32, copy=False) for f in frames]
    diffs = np.abs(np.diff(np.stack(sub), axis=0)).ravel()
    diffs = diffs[np.isfinite(diffs)]
    if diffs.size == 0:
        return 0.0
    return float(np.median(diffs)) / (math.sqrt(2.0) * _MAD_GAUSS)


class NoiseBandwidth:
    """The kernel variance (3.6) in use: ``sigma2`` widened to ``factor`` times the median
    of the last ``memory`` noise measurements (one per full-frame pass), on the unit
    intensity scale.  ``factor`` 0 keeps ``sigma2``."""

    #: a widened variance is rounded to this many steps per doubling, so that the kernel
    #: tables (one per variance) stay few and a steady stream keeps one bandwidth
    STEPS_PER_OCTAVE = 8

    def __init__(self, sigma2: float, factor: float, memory: int = 5) -> None:
        self.base = float(sigma2)
        self.factor = float(factor)
        self._noise: deque[float] = deque(maxlen=max(int(memory), 1))
        self.sigma2 = self.base

    def observe(self, frames: list[np.ndarray], scale: float) -> float:
        """Measure the noise of ``frames`` (raw units; ``scale`` maps them to the unit
        scale) and return the variance to use from now on."""
        if self.factor <= 0.0:
            return self.sigma2
        self._noise.append(temporal_noise_std(frames) * float(scale))
        wide = (self.factor * float(np.median(self._noise))) ** 2
        if wide <= self.base:
            self.sigma2 = self.base
        else:
            k = math.ceil(self.STEPS_PER_OCTAVE * math.log2(wide / self.base))
            self.sigma2 = self.base * 2.0 ** (k / self.STEPS_PER_OCTAVE)
        return self.sigma2

    @property
    def noise(self) -> float:
        """The median noise std of the memory (unit scale), 0 before any measurement."""
        return float(np.median(self._noise)) if self._noise else 0.0
