"""Hand-started tracks of people at the image edge (issue #16 item 3): which single-target
sequences start or end at the left / right image border, and how the hand-started tracker
(and CSRT, when opencv-contrib is installed) do in the frames where the person is at the
border.

    .venv/bin/python benchmarks/diagnose_edge.py [--margin 5] [--set NAME=VALUE ...]
        [--sequences 'TUD-Stadtmitte person 10,...'] [--frames]

For every real sequence of ``bench_single_target.development_set`` it prints the first and
last truth box (clipped to the image, as scored), whether it touches a side border (within
``--margin`` px) and its visible width / height, and per tracker the mean centre error (px)
and mean IoU over the frames whose truth touches the border ("edge") and over the others
("inside").  ``--frames`` also prints every edge frame.  The tracker is the one of
``bench_single_target.full_tracker_factory`` at the defaults (``--set`` overrides, as in
``bench_single_target.py``).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench_single_target as bst  # noqa: E402
from mk_tracker.boxes import iou  # noqa: E402
from mk_tracker.parameters import updated  # noqa: E402
from mk_tracker.tracking.tracker_config import MultiObjectTrackerConfig  # noqa: E402
from setting_values import setting_changes  # noqa: E402


def border_side(box, width: int, margin: float) -> str:
    """``"left"``, ``"right"`` or ``""``: which side border the box touches (within
    ``margin`` px)."""
    if box is None:
        return ""
    x, _, w, _ = box
    if x <= margin:
        return "left"
    if x + w >= width - margin:
        return "right"
    return ""


def _centre(b):
    return np.array([b[0] + b[2] / 2.0, b[1] + b[3] / 2.0])


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--margin", type=float, default=5.0)
    p.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE")
    p.add_argument("--sequences", default="")
    p.add_argument("--frames", action="store_true")
    args = p.parse_args(argv)
    config = updated(MultiObjectTrackerConfig(), setting_changes(args.set))
    peers = [("ours", bst.full_tracker_factory(config))]
    csrt = bst._contrib("CSRT")
    if csrt is not None:
        peers.append(("CSRT", bst.opencv_tracker_factory(csrt)))
    wanted = bst._names(args.sequences)
    for clip, seq in bst.development_set():
        if clip.startswith("generator") or not bst._selected(seq.name, wanted):
            continue
        frames = list(seq.frames())
        width = frames[0].shape[1]
        sides = [border_side(b, width, args.margin) for b in seq.truth]
        first, last = seq.truth[0], [b for b in seq.truth if b is not None][-1]
        if not any(sides):
            continue
        def desc(b):
            return f"({b[0]:.0f},{b[1]:.0f},{b[2]:.0f},{b[3]:.0f}) w/h {b[2] / b[3]:.2f}"
        print(f"{seq.name}: {len(frames)} frames, first {desc(first)} {sides[0] or '-'}, "
              f"last {desc(last)} {sides[len(seq.truth) - 1] or '-'}; "
              f"{sum(bool(s) for s in sides)} frames at the border")
        cached = replace(seq, frames=lambda: iter(frames))
        for name, factory in peers:
            m, _ = bst.run(cached, factory)
            boxes = m["boxes"]
            rows = {"edge": [], "inside": []}
            for k in range(1, len(frames)):
                t = seq.truth[k]
                if t is None:
                    continue
                e = float(np.linalg.norm(_centre(boxes[k]) - _centre(t)))
                o = float(iou(np.asarray(boxes[k], float), np.asarray(t, float)))
                rows["edge" if sides[k] else "inside"].append((e, o))
                if args.frames and sides[k]:
                    print(f"    {name} frame {k}: truth {desc(t)} box "
                          f"({boxes[k][0]:.0f},{boxes[k][1]:.0f},{boxes[k][2]:.0f},"
                          f"{boxes[k][3]:.0f}) err {e:.1f} IoU {o:.2f}")
            cells = []
            for part, r in rows.items():
                if r:
                    a = np.array(r)
                    cells.append(f"{part} {len(r)} fr: err {a[:, 0].mean():.1f} "
                                 f"IoU {a[:, 1].mean():.2f}")
            print(f"  {name}: overall err {m['mean_center_error']:.1f} AUC "
                  f"{m['success_auc']:.2f}; " + "; ".join(cells), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
