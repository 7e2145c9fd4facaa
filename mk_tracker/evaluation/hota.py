"""HOTA, the MOTChallenge headline metric (Luiten et al., "HOTA: A Higher Order Metric for
Evaluating Multi-Object Tracking", IJCV 2021), of MOTChallenge rows.

For each localisation threshold ``alpha`` in 0.05, 0.10, ..., 0.95 (paper Sec. 5):

* every frame's ground-truth and tracker boxes are matched one-to-one (Hungarian) on the
  IoU weighted by a global alignment score of each (ground-truth id, tracker id) pair, so
  that pairs which overlap over the whole sequence are preferred (the reference
  implementation's matching; paper Sec. 5.2); a matched pair is a true positive when its
  IoU is at least ``alpha``;
* ``DetA = |TP| / (|TP| + |FN| + |FP|)`` (eq. 5);
* ``AssA = 1/|TP| * sum over TP c of A(c)`` with ``A(c) = |TPA| / (|TPA| + |FNA| + |FPA|)``,
  the Jaccard index of the two trajectories the matched pair belongs to (eqs. 6-8): with
  ``m`` the frames where the pair is matched, ``n_g`` and ``n_t`` the frames where either
  id appears, ``A = m / (n_g + n_t - m)``;
* ``HOTA_alpha = sqrt(DetA * AssA)`` (eq. 9).

HOTA, DetA and AssA are the means over the 19 thresholds (eq. 11).  The reference
implementation is TrackEval (``trackeval`` on PyPI); it is not a dependency here because
its package declares ``opencv-python``, a second OpenCV wheel beside the project's headless
one.  The benchmarks compare the two where TrackEval is installed.
"""

from __future__ import annotations

from typing import Iterable

import numpy as np
from scipy.optimize import linear_sum_assignment

from mk_tracker.boxes import iou_matrix

#: the localisation thresholds of the paper (0.05 to 0.95 in steps of 0.05)
ALPHAS = np.arange(1, 20) * 0.05
_EPS = np.finfo(float).eps


def _by_frame(rows) -> dict[int, list]:
    out: dict[int, list] = {}
    for r in rows:
        out.setdefault(int(r.frame), []).append(r)
    return out


def hota(gt_rows: Iterable, hyp_rows: Iterable) -> dict[str, float]:
    """``{"hota", "deta", "assa"}`` (means over :data:`ALPHAS`) of tracker rows
    ``hyp_rows`` against ``gt_rows`` (:class:`mk_tracker.evaluation.metrics.MotRow`: frame,
    id, box).  With neither ground truth nor tracker boxes every score is 0."""
    gt_rows, hyp_rows = list(gt_rows), list(hyp_rows)
    gt_ids = {i: k for k, i in enumerate(sorted({r.id for r in gt_rows}))}
    hyp_ids = {i: k for k, i in enumerate(sorted({r.id for r in hyp_rows}))}
    gt_frames, hyp_frames = _by_frame(gt_rows), _by_frame(hyp_rows)
    frames = []
    for f in sorted(set(gt_frames) | set(hyp_frames)):
        g, h = gt_frames.get(f, []), hyp_frames.get(f, [])
        frames.append((np.array([gt_ids[r.id] for r in g], dtype=int),
                       np.array([hyp_ids[r.id] for r in h], dtype=int),
                       iou_matrix(np.array([r.box for r in g], float).reshape(-1, 4),
                                  np.array([r.box for r in h], float).reshape(-1, 4))))
    n_g, n_t = len(gt_ids), len(hyp_ids)
    # global alignment: how much each pair of trajectories overlaps over the sequence
    potential = np.zeros((n_g, n_t))
    gt_count, hyp_count = np.zeros(n_g), np.zeros(n_t)
    for g, h, sim in frames:
        gt_count[g] += 1
        hyp_count[h] += 1
        if sim.size:
            union = sim.sum(axis=0, keepdims=True) + sim.sum(axis=1, keepdims=True) - sim
            share = np.divide(sim, union, out=np.zeros_like(sim), where=union > _EPS)
            potential[np.ix_(g, h)] += share
    alignment = potential / np.maximum(gt_count[:, None] + hyp_count[None, :] - potential,
                                       _EPS)
    tp, fn, fp = (np.zeros(len(ALPHAS)) for _ in range(3))
    matches = np.zeros((len(ALPHAS), n_g, n_t))
    for g, h, sim in frames:
        if sim.size == 0:
            fn += len(g)
            fp += len(h)
            continue
        rows, cols = linear_sum_assignment(-(alignment[np.ix_(g, h)] * sim))
        for a, alpha in enumerate(ALPHAS):
            ok = sim[rows, cols] >= alpha - _EPS
            count = int(ok.sum())
            tp[a] += count
            fn[a] += len(g) - count
            fp[a] += len(h) - count
            np.add.at(matches[a], (g[rows[ok]], h[cols[ok]]), 1.0)
    deta = tp / np.maximum(tp + fn + fp, 1.0)
    assa = np.zeros(len(ALPHAS))
    for a in range(len(ALPHAS)):
        m = matches[a]
        jaccard = m / np.maximum(gt_count[:, None] + hyp_count[None, :] - m, 1.0)
        assa[a] = float((m * jaccard).sum()) / max(tp[a], 1.0)
    per_alpha = np.sqrt(deta * assa)
    return {"hota": float(per_alpha.mean()), "deta": float(deta.mean()),
            "assa": float(assa.mean())}
