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

Below the level a look-alike can score as high as the person (TUD-Stadtmitte person 3 at
6.25 fps: searches at 0.37 and 0.24 ending 7 and 24 px towards a passer-by).  The optional
validation gate of Bar-Shalom & Fortmann (Tracking and Data Association, 1988, Sec. 2.3)
keeps a graded result only if its centre lies inside the region where the prediction expects
a match: the squared Mahalanobis distance ``nu^T S^-1 nu`` of the innovation ``nu`` under
``S = H P H^T + R(s_level)``, the prediction's covariance plus the *un-inflated* noise of a
match at the level, is at most ``gate`` (a chi-square quantile for 2 dof: 5.99 = 95%,
9.21 = 99%).  The inflated noise is not used for the gate: it would widen the gate exactly
for the poorest matches.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["graded_noise_scale", "within_validation_gate"]


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


def within_validation_gate(innovation, covariance, gate: float) -> bool:
    """True if the squared Mahalanobis distance ``nu^T S^-1 nu`` of ``innovation`` (2,) under
    ``covariance`` S (2, 2) is at most ``gate``; ``gate`` <= 0 means no gate (always True).
    A singular or non-finite S, or a non-finite innovation, fails the gate."""
    if gate <= 0.0:
        return True
    nu = np.asarray(innovation, dtype=np.float64).reshape(2)
    cov = np.asarray(covariance, dtype=np.float64).reshape(2, 2)
    if not (np.all(np.isfinite(nu)) and np.all(np.isfinite(cov))):
        return False
    try:
        d2 = float(nu @ np.linalg.solve(cov, nu))
    except np.linalg.LinAlgError:
        return False
    return math.isfinite(d2) and 0.0 <= d2 <= float(gate)
