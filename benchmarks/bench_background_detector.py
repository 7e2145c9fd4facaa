"""Background-subtraction detector (issue #13): detection recall/precision and CPU time of
MOG2 and KNN, and the automatic RGB-only system (background detector -> this tracker)
against this tracker on the sequences' public detections.

    .venv/bin/python benchmarks/bench_background_detector.py --out docs/benchmark_background_detector.md

Sequences: TUD-Campus and TUD-Stadtmitte (../shared/data/mot, static cameras, people
present from the first frame), and a generated crowd scene (640x480, 3 people, seed 5).
Detection is matched to ground truth one-to-one (Hungarian) at IoU >= 0.5 over the frames
after the model's start-up; time is the detector's CPU time per 640x480 frame (median).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.optimize import linear_sum_assignment

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mk_tracker.bags.dataset_import import import_sequence  # noqa: E402
from mk_tracker.bags.datasets import read_sequence  # noqa: E402
from mk_tracker.boxes import iou_matrix  # noqa: E402
from mk_tracker.detection.background_detector import (BackgroundDetector,  # noqa: E402
                                                      BackgroundDetectorConfig)
from mk_tracker.synthetic.scene_bag import build_preset, write_scene_bag  # noqa: E402
from mk_tracker.tools import cli  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "mot"


def detection_scores(frames, truth, fps: float, model: str) -> dict:
    det = BackgroundDetector(BackgroundDetectorConfig(model=model))
    tp = fp = fn = 0
    times = []
    for k, img in enumerate(frames):
        t0 = time.thread_time()
        out = det.process(img, k / fps, encoding="bgr8")
        times.append(time.thread_time() - t0)
        if det.last_mode != "tracking":
            continue
        gt, boxes = truth[k], [d.box for d in out]
        good = 0
        if gt and boxes:
            m = iou_matrix(np.array(gt, float), np.array(boxes, float))
            r, c = linear_sum_assignment(-m)
            good = int((m[r, c] >= 0.5).sum())
        tp, fp, fn = tp + good, fp + len(boxes) - good, fn + len(gt) - good
    return {"recall": tp / max(tp + fn, 1), "precision": tp / max(tp + fp, 1),
            "ms": 1000 * float(np.median(times))}


def tracking_scores(bag: Path, out: Path, source: str) -> dict:
    cli.main(["process", str(bag), "--out", str(out), "--detections", source, "--quiet",
              "--no-video"])
    m = json.loads((out / "summary.json").read_text())["metrics"]
    return {k: m[k] for k in ("mota", "idf1", "recall", "precision")}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args(argv)
    rows_det, rows_trk = [], []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        sequences = []
        for name in ("TUD-Campus", "TUD-Stadtmitte"):
            if (DATA / name).is_dir():
                seq = read_sequence(DATA / name)
                import_sequence(seq, tmp / name)
                frames = [seq.image(k) for k in range(len(seq))]
                truth = [list(seq.ground_truth[k].values()) for k in range(len(seq))]
                sequences.append((name, tmp / name, frames, truth, seq.frame_rate, True))
        scene = build_preset("crowd", seed=5, people=3, frames=120, width=640, height=480)
        write_scene_bag(scene, tmp / "crowd")
        frames, truth = [], []
        for k in range(120):
            f = scene.frame(k)
            frames.append(f.rgb)
            truth.append([o.box_rgb for o in f.objects if o.visible_fraction > 0.5])
        sequences.append(("generated crowd-3 (seed 5)", tmp / "crowd", frames, truth, 25.0,
                          False))
        for name, bag, frames, truth, fps, public in sequences:
            for model in ("mog2", "knn"):
                s = detection_scores(frames, truth, fps, model)
                rows_det.append((name, model, s))
                print(name, model, s, file=sys.stderr)
            rows_trk.append((name, "background (MOG2) -> ours",
                             tracking_scores(bag, tmp / f"{name}-bg", "background")))
            if public:
                rows_trk.append((name, "public detections -> ours",
                                 tracking_scores(bag, tmp / f"{name}-pub", "topic:/detections")))
            print(rows_trk[-1], file=sys.stderr)
    lines = ["| sequence | model | recall | precision | CPU ms / frame |", "|---|---|---|---|---|"]
    lines += [f"| {n} | {m} | {s['recall']:.3f} | {s['precision']:.3f} | {s['ms']:.1f} |"
              for n, m, s in rows_det]
    lines += ["", "| sequence | detections -> tracker | MOTA | IDF1 | recall | precision |",
              "|---|---|---|---|---|---|"]
    lines += [f"| {n} | {w} | {s['mota']:.3f} | {s['idf1']:.3f} | {s['recall']:.3f} | "
              f"{s['precision']:.3f} |" for n, w, s in rows_trk]
    table = "\n".join(lines)
    print(table)
    if args.out:
        args.out.write_text("# Background-subtraction detector (issue #13)\n\nProduced by:\n\n"
                            "```\n.venv/bin/python benchmarks/bench_background_detector.py "
                            "--out docs/benchmark_background_detector.md\n```\n\n"
                            + __doc__.split("\n\n", 2)[2] + "\n" + table + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
