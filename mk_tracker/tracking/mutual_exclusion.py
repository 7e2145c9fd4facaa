"""Mutual exclusion between targets: two people cannot stand in one place.

Chu et al. (2013, Sec. IV-D) place an undetected target where its multiple kernels match
best, from the Kalman prediction.  Among people who look alike (the same clothes, or 20-px
people whose histograms carry little colour) that place may be a neighbour, and the track
then follows the neighbour: an identity switch at the next detection (issue #16's unseen B,
reproduced by ``benchmarks/bench_small_far.py --alike``, docs/failure_analysis.md).  A
neighbour that was assigned its own detection this frame is already explained; a refined
box that lands on it is refused, and the track coasts on its Kalman prediction instead.
This is the exclusion term of multi-target energy models (Milan, Roth & Schindler, TPAMI
2014, "Continuous energy minimization for multitarget tracking", the exclusion energy
that keeps two trajectories apart) in its hard, one-frame form; the kernels are still the
measurement wherever no other target's detection claims the place.

Pure numpy; rclpy is not imported here.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from mk_tracker.boxes import iou_matrix


def claimed_by_other(track_id: int, box: np.ndarray, claimed: Mapping[int, np.ndarray],
                     max_iou: float) -> int | None:
    """The id of another track whose box ``claimed`` this frame (the box of its assigned
    detection) overlaps ``box`` by more than ``max_iou``, the most overlapping one; ``None``
    when there is none, or when ``max_iou`` is 0 (off).  The track's own entry is ignored."""
    if max_iou <= 0.0:
        return None
    others = [(tid, b) for tid, b in claimed.items() if tid != track_id]
    if not others:
        return None
    overlap = iou_matrix(np.asarray(box, dtype=np.float64).reshape(1, 4),
                         np.array([b for _, b in others], dtype=np.float64).reshape(-1, 4))[0]
    best = int(np.argmax(overlap))
    return others[best][0] if overlap[best] > max_iou else None
