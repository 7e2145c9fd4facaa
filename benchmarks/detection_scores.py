"""What scores the project's detectors emit, against the tracker's ``min_detection_score``.

``min_detection_score`` applies to every detection source, so a default chosen on public RGB
detections (benchmarks/bench_multi_object.py) must not drop what the project's own detectors
report.  This prints, per detector and sequence, how many detections there are, their score
quantiles and the share below each threshold given:

* the sparse kernel covariance detector (Schizas et al. 2018; score = mean local variance
  ratio / 0.5, capped at 1) on the real thermal clip BU-TIV-lab (counter masked) and on the
  generated thermal->RGB crowd of benchmarks/bench_groups.py (seed 201, 640x480, 8 people);
* the background-subtraction detector (score = share of foreground pixels in the box) on
  TUD-Campus and TUD-Stadtmitte.

    .venv/bin/python benchmarks/detection_scores.py --thresholds 0.2
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_real_thermal import COUNTER_REGION, DEFAULT_CLIP, run_pipeline  # noqa: E402

from mk_tracker.bags.datasets import read_sequence  # noqa: E402
from mk_tracker.bags.recording_import import import_recording, open_recording  # noqa: E402
from mk_tracker.detection.background_detector import BackgroundDetector  # noqa: E402
from mk_tracker.synthetic.scene_bag import build_preset, write_scene_bag  # noqa: E402

DATA = ROOT.parent / "shared" / "data"


def thermal_scores(bag: Path, out: Path, regions: tuple) -> list[float]:
    """Scores of the default thermal detector's detections over the bag (pipeline run)."""
    _, detections, _ = run_pipeline(bag, out, regions)
    return [d[4] for frame in detections for d in frame]


def background_scores(folder: Path) -> list[float]:
    seq = read_sequence(folder)
    det = BackgroundDetector()
    return [d.score for k in range(len(seq))
            for d in det.process(seq.image(k), k / seq.frame_rate, encoding="bgr8")]


def line(name: str, scores: list[float], thresholds: list[float]) -> str:
    s = np.asarray(scores, dtype=float)
    if s.size == 0:
        return f"| {name} | 0 | - | " + " | ".join("-" for _ in thresholds) + " |"
    q = np.percentile(s, [0, 5, 50, 95, 100])
    below = [f"{np.mean(s < t):.3f}" for t in thresholds]
    return (f"| {name} | {s.size} | " + " / ".join(f"{v:.3f}" for v in q) + " | "
            + " | ".join(below) + " |")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--thresholds", type=float, nargs="+", default=[0.2])
    args = parser.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        if DEFAULT_CLIP.exists():
            bag = tmp / "clip"
            import_recording(open_recording(DEFAULT_CLIP, None), bag, thermal=True)
            rows.append(("kernel covariance, BU-TIV-lab (counter masked)",
                         thermal_scores(bag, tmp / "clip_out", COUNTER_REGION)))
        scene = build_preset("crowd", seed=201, people=8, frames=150, width=640, height=480)
        write_scene_bag(scene, tmp / "crowd")
        rows.append(("kernel covariance, generated crowd-8 seed 201",
                     thermal_scores(tmp / "crowd", tmp / "crowd_out", ())))
    for name in ("TUD-Campus", "TUD-Stadtmitte"):
        if (DATA / "mot" / name).is_dir():
            rows.append((f"background subtraction, {name}",
                         background_scores(DATA / "mot" / name)))
    print("| detector, sequence | detections | score min / 5% / median / 95% / max | "
          + " | ".join(f"share < {t:g}" for t in args.thresholds) + " |")
    print("|---|---|---|" + "---|" * len(args.thresholds))
    for name, scores in rows:
        print(line(name, scores, args.thresholds))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
