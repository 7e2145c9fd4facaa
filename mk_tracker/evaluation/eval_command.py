"""``mk_tracker eval``: score tracking results against ground truth.

Multi-object (default)::

    mk_tracker eval --gt ../shared/data/mot/TUD-Campus result_a.txt result_b.txt

``--gt`` is a MOTChallenge ground-truth file or a sequence folder holding ``gt/gt.txt``; each
result is a MOTChallenge result file (any tracker's).  Prints MOTA, MOTP, IDF1, IDP, IDR, ID
switches, fragmentations, FP, FN, mostly tracked / partially tracked / mostly lost per result
(motmetrics), then HOTA, DetA and AssA (:mod:`mk_tracker.evaluation.hota`, the MOTChallenge
headline metric), optionally also as a markdown table (``--markdown``).

Single target (OTB protocol)::

    mk_tracker eval --single-target --gt ../shared/data/otb/Crossing result.txt --plot out.png

``--gt`` is an OTB ``groundtruth_rect.txt`` or its folder; a result is an ``x y w h`` per line
file or a MOTChallenge file (its first id is scored).  Prints the mean centre error, the
precision at 20 px and the success AUC; ``--plot`` draws the precision and success curves.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from mk_tracker.evaluation import metrics as ev
from mk_tracker.evaluation.hota import hota


def configure_parser(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("results", nargs="+", type=Path, help="result file(s) to score")
    parser.add_argument("--gt", required=True, type=Path,
                        help="ground truth: MOTChallenge gt.txt or sequence folder; with "
                             "--single-target an OTB groundtruth_rect.txt or its folder")
    parser.add_argument("--names", nargs="+", default=None,
                        help="a name per result (default: file names)")
    parser.add_argument("--iou", type=float, default=0.5,
                        help="IoU a box needs to match the ground truth (default 0.5)")
    parser.add_argument("--single-target", action="store_true",
                        help="OTB single-target protocol instead of CLEAR-MOT")
    parser.add_argument("--markdown", type=Path, default=None,
                        help="also write the table as markdown to this file")
    parser.add_argument("--plot", type=Path, default=None,
                        help="single target: write precision and success plots (PNG)")


def _gt_path(path: Path, single: bool) -> Path:
    if path.is_dir():
        candidates = ([path / "groundtruth_rect.txt"] if single
                      else [path / "gt" / "gt.txt", path / "gt.txt"])
        for c in candidates:
            if c.is_file():
                return c
        raise ev.EvaluationError(f"{path}: no {' or '.join(str(c) for c in candidates)}")
    return path


def _names(args: argparse.Namespace) -> list[str]:
    if args.names is None:
        return [p.stem if p.stem not in ("", ".") else str(p) for p in args.results]
    if len(args.names) != len(args.results):
        raise ev.EvaluationError(f"{len(args.names)} names for {len(args.results)} results")
    return list(args.names)


def _load_single_result(path: Path, num_frames: int):
    try:
        boxes = ev.read_box_list(path)
    except ev.EvaluationError:
        return ev.boxes_from_mot(ev.read_mot_file(path), num_frames)
    if len(boxes) < num_frames:
        boxes = boxes + [None] * (num_frames - len(boxes))
    return boxes[:num_frames]


def _run_single(args, names) -> list[dict]:
    gt = ev.read_box_list(_gt_path(args.gt, True))
    rows = []
    curves = []
    for name, path in zip(names, args.results):
        pred = _load_single_result(path, len(gt))
        m = ev.single_target_metrics(pred, gt)
        rows.append({"name": name, **m})
        curves.append((name, ev.center_errors(pred, gt), ev.overlaps(pred, gt)))
    if args.plot is not None:
        _plot(args.plot, curves)
    return rows


def _plot(path: Path, curves) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_p, ax_s) = plt.subplots(1, 2, figsize=(10, 4))
    thresholds = np.arange(0, 51)
    for name, err, ov in curves:
        ax_p.plot(thresholds, [ev.precision_at(err, t) for t in thresholds],
                  label=f"{name} [{ev.precision_at(err, 20):.3f}]")
        t, rates = ev.success_curve(ov)
        ax_s.plot(t, rates, label=f"{name} [{ev.success_auc(ov):.3f}]")
    ax_p.set(xlabel="location error threshold (px)", ylabel="precision", title="Precision")
    ax_s.set(xlabel="overlap threshold", ylabel="success rate", title="Success")
    for ax in (ax_p, ax_s):
        ax.set_ylim(0, 1.02)
        ax.grid(alpha=0.3)
        ax.legend(loc="lower right" if ax is ax_p else "lower left")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _markdown(rows: list[dict]) -> str:
    keys = [k for k in rows[0] if k != "name"]
    lines = ["| result | " + " | ".join(keys) + " |",
             "|---|" + "---|" * len(keys)]
    for r in rows:
        cells = [f"{r[k]:.3f}" if isinstance(r[k], float) else str(r[k]) for k in keys]
        lines.append(f"| {r['name']} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def run(args: argparse.Namespace) -> int:
    try:
        names = _names(args)
        if args.single_target:
            rows = _run_single(args, names)
            for r in rows:
                print(f"{r['name']}: frames {r['frames']}  mean centre error "
                      f"{r['mean_center_error']:.2f} px  precision@20px "
                      f"{r['precision_at_20px']:.3f}  success AUC {r['success_auc']:.3f}  "
                      f"missing {r['missing_frames']}")
        else:
            gt = ev.read_mot_file(_gt_path(args.gt, False), ground_truth=True)
            accs = {}
            rows = []
            for name, path in zip(names, args.results):
                hyp = ev.read_mot_file(path)
                accs[name] = ev.mot_accumulator(gt, hyp, iou_threshold=args.iou)
                rows.append({"name": name, **ev.mot_metrics(gt, hyp, iou_threshold=args.iou),
                             **hota(gt, hyp)})
            print(ev.render_summary(ev.mot_summary(accs)))
            width = max(len(r["name"]) for r in rows)
            print(f"{'':{width}}   HOTA   DetA   AssA   (Luiten et al. 2021; alpha "
                  "0.05..0.95, independent of --iou)")
            for r in rows:
                print(f"{r['name']:{width}} {100 * r['hota']:5.1f}% {100 * r['deta']:5.1f}% "
                      f"{100 * r['assa']:5.1f}%")
        if args.markdown is not None:
            args.markdown.parent.mkdir(parents=True, exist_ok=True)
            args.markdown.write_text(_markdown(rows), encoding="utf-8")
    except ev.EvaluationError as exc:
        print(f"mk_tracker eval: {exc}", file=sys.stderr)
        return 1
    return 0
