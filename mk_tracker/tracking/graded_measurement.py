"""Graded measurement of a track started by hand (issue #16, ``manual_track.graded_measurement``).

A track started by hand has one measurement per frame: the multiple-kernel search of Chu,
Hwang, Pai & Lan (IEEE TMM 2013) from the Kalman prediction (Sec. IV-D, Algorithm 1 with the
step (8)).  Each kernel's similarity is ``rho_i = exp(-J_i)``, ``J_i`` the K-L distance between
the kernel's model and candidate histograms (Sec. V: "We use K-L distance for all the
similarity-related and cost computations"; the total cost (3), weighted (7)), and the
visibility statistic ``s`` (``mk_tracker.tracking.multi_kernel.visibility_similarity``) is
their (adaptively weighted) mean.  The tracker accepts the result as a measurement when
``s`` is at least ``occlusion_similarity`` and otherwise coasts: an accept/reject decision.

On OTB Woman and TUD-Stadtmitte the searches that are on the person score 0.31-0.40, just
below the level, so the track coasts on a velocity learnt in a few frames and leaves the
person (docs/benchmark_single_target.md, "Diagnosis").  Probabilistic colour trackers
(Perez, Hue, Vermaak & Gangnet, ECCV 2002; Nummiaro, Koller-Meier & Van Gool 2003) do not
threshold: the colour match enters as a likelihood ``p(z | x) ~ exp(-lambda D)`` of the
histogram distance ``D``.  The graded measurement carries that into the Kalman update
(4.4)-(4.5): below the level, the measurement's information ``1 / R`` is the information of
a match at the level scaled by the likelihood ratio of the two matches,

    1 / R(s) = 1 / R(s_level) * exp(-lambda (J - J_level)),   J = -ln s,

so ``sigma(s) = sigma(s_level) * (s_level / s) ** (lambda / 2)``, down to a floor below which
the result is rejected as before.  Above the level nothing changes.
"""

from __future__ import annotations

import math

__all__ = ["graded_noise_scale"]


def graded_noise_scale(similarity: float, level: float, floor: float,
                       sharpness: float) -> float | None:
    """Factor on the std of a measurement at ``level`` for a search result of visibility
    statistic ``similarity`` below it: ``(level / similarity) ** (sharpness / 2)``.

    Returns None when the result is not a graded measurement: at or above ``level`` (a plain
    measurement), below ``floor`` or not positive (rejected), or not finite.
    """
    s = float(similarity)
    if not math.isfinite(s) or s >= level or s < floor or s <= 0.0:
        return None
    return (float(level) / s) ** (0.5 * float(sharpness))
