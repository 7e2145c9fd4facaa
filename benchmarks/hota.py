"""HOTA (Luiten et al., IJCV 2021) of MOTChallenge rows with ``trackeval`` 1.3.0.

A small adapter: ``trackeval.metrics.HOTA().eval_sequence`` takes per-frame id arrays
(contiguous 0-based ids) and gt x tracker IoU matrices; this builds them from
:class:`mk_tracker.evaluation.metrics.MotRow` lists.  Benchmarks only: ``trackeval`` is not a
dependency of the package (install: benchmarks/requirements-peers.txt).
"""

from __future__ import annotations

import numpy as np

from mk_tracker.boxes import iou_matrix


def hota(gt_rows, hyp_rows, n_frames: int | None = None) -> float | None:
    """HOTA averaged over the IoU thresholds 0.05..0.95, or None without ``trackeval``."""
    try:
        import trackeval  # noqa: F401
        from trackeval.metrics import HOTA
    except Exception:   # noqa: BLE001  (trackeval absent or broken: no HOTA column)
        return None
    frames = sorted({r.frame for r in gt_rows} | {r.frame for r in hyp_rows})
    if n_frames is None:
        n_frames = max(frames) if frames else 0
    gt_map = {i: k for k, i in enumerate(sorted({r.id for r in gt_rows}))}
    hyp_map = {i: k for k, i in enumerate(sorted({r.id for r in hyp_rows}))}
    by_frame_gt: dict[int, list] = {}
    by_frame_hyp: dict[int, list] = {}
    for r in gt_rows:
        by_frame_gt.setdefault(r.frame, []).append(r)
    for r in hyp_rows:
        by_frame_hyp.setdefault(r.frame, []).append(r)
    data = {"num_timesteps": n_frames, "num_gt_ids": len(gt_map),
            "num_tracker_ids": len(hyp_map), "num_gt_dets": len(gt_rows),
            "num_tracker_dets": len(hyp_rows), "gt_ids": [], "tracker_ids": [],
            "similarity_scores": []}
    for f in range(1, n_frames + 1):
        g = by_frame_gt.get(f, [])
        h = by_frame_hyp.get(f, [])
        data["gt_ids"].append(np.array([gt_map[r.id] for r in g], dtype=int))
        data["tracker_ids"].append(np.array([hyp_map[r.id] for r in h], dtype=int))
        data["similarity_scores"].append(
            iou_matrix(np.array([r.box for r in g], dtype=float).reshape(-1, 4),
                       np.array([r.box for r in h], dtype=float).reshape(-1, 4)))
    res = HOTA().eval_sequence(data)
    return float(np.mean(res["HOTA"]))
