"""Ghost reset (mk_tracker/detection/ghosts.py) against the shipped background detector:
detection recall / precision / F1 / CPU ms per frame on the sequences of
benchmarks/bench_background_detector.py, its loaders and scoring (all frames, IoU >= 0.5).

    nice -n 10 .venv/bin/python benchmarks/compare_ghost_reset.py
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_background_detector import detection_scores, load_sequences  # noqa: E402
from mk_tracker.detection.background_detector import BackgroundDetectorConfig  # noqa: E402

SETTINGS = [{}] + [
    {"ghost_reset": reset, "learning_rate": rate, "ghost_time": time, "ghost_share": share}
    for reset in ("model", "memory") for rate in (-1.0, 0.005) for time in (0.3, 1.0)
    for share in (0.6, 0.9)]


def main() -> int:
    with tempfile.TemporaryDirectory() as tmp:
        sequences = load_sequences(Path(tmp))
        print("| setting | " + " | ".join(s[0] for s in sequences) + " | mean F1 |")
        print("|---|" + "---|" * (len(sequences) + 1))
        for setting in SETTINGS:
            cfg = BackgroundDetectorConfig(**setting)
            res = [detection_scores(frames, truth, fps, cfg)
                   for _n, _b, frames, truth, fps, _p in sequences]
            cells = [f"{r['recall']:.2f} / {r['precision']:.2f} / {r['f1']:.3f} / "
                     f"{r['ms']:.1f} ms" for r in res]
            label = ", ".join(f"{k}={v}" for k, v in setting.items()) or "shipped defaults"
            print(f"| {label} | " + " | ".join(cells)
                  + f" | {np.mean([r['f1'] for r in res]):.3f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
