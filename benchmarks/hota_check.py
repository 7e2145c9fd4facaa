"""Check :mod:`mk_tracker.evaluation.hota` against TrackEval (the reference implementation
of HOTA, ``trackeval`` 1.3.0 from benchmarks/requirements-peers.txt) on the TUD sequences:
the public detections as one-frame tracks, and the ground truth with jitter, 15% of the
boxes dropped and half of the ids switched after frame 40.  Prints both figures.

    .venv/bin/python benchmarks/hota_check.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mk_tracker.boxes import iou_matrix  # noqa: E402
from mk_tracker.evaluation.hota import hota  # noqa: E402
from mk_tracker.evaluation.metrics import MotRow, read_mot_file  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "mot"


def trackeval_hota(gt_rows, hyp_rows) -> float:
    """HOTA by TrackEval's ``HOTA().eval_sequence`` on the same rows."""
    from trackeval.metrics import HOTA

    n = max(r.frame for r in list(gt_rows) + list(hyp_rows))
    gt_map = {i: k for k, i in enumerate(sorted({r.id for r in gt_rows}))}
    hyp_map = {i: k for k, i in enumerate(sorted({r.id for r in hyp_rows}))}
    data = {"num_timesteps": n, "num_gt_ids": len(gt_map), "num_tracker_ids": len(hyp_map),
            "num_gt_dets": len(gt_rows), "num_tracker_dets": len(hyp_rows), "gt_ids": [],
            "tracker_ids": [], "similarity_scores": []}
    for f in range(1, n + 1):
        g = [r for r in gt_rows if r.frame == f]
        h = [r for r in hyp_rows if r.frame == f]
        data["gt_ids"].append(np.array([gt_map[r.id] for r in g], dtype=int))
        data["tracker_ids"].append(np.array([hyp_map[r.id] for r in h], dtype=int))
        data["similarity_scores"].append(iou_matrix(
            np.array([r.box for r in g], float).reshape(-1, 4),
            np.array([r.box for r in h], float).reshape(-1, 4)))
    return float(np.mean(HOTA().eval_sequence(data)["HOTA"]))


def main() -> int:
    rng = np.random.default_rng(0)
    for seq in ("TUD-Campus", "TUD-Stadtmitte"):
        gt = read_mot_file(DATA / seq / "gt" / "gt.txt", ground_truth=True)
        det = read_mot_file(DATA / seq / "det" / "det.txt")
        noisy = []
        for r in gt:
            if rng.random() < 0.15:
                continue
            x, y, w, h = r.box
            dx, dy = rng.normal(0, 0.1 * w, 2)
            tid = r.id + (100 if r.frame > 40 and r.id % 2 else 0)
            noisy.append(MotRow(r.frame, tid, (x + dx, y + dy, w * (1 + rng.normal(0, 0.05)),
                                                h)))
        for name, hyp in (("public detections", [MotRow(r.frame, k + 1, r.box)
                                                 for k, r in enumerate(det)]),
                          ("jittered ground truth", noisy)):
            print(f"{seq} {name}: mk_tracker {hota(gt, hyp)['hota']:.6f}  "
                  f"TrackEval {trackeval_hota(gt, hyp):.6f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
