"""The man with crossed arms at the back left of BU-TIV-lab (issue #19): is he detected, is
he tracked, and what does the thermal image offer him?

    .venv/bin/python benchmarks/diagnose_ids.py --cache out/lab_inputs.pkl      # capture once
    .venv/bin/python benchmarks/diagnose_still_man.py --cache out/lab_inputs.pkl [--set NAME=VALUE ...]

He stands at about ``MAN`` (x, y, w, h) from the first frame to the last.  On the captured
tracker inputs of ``diagnose_ids.py`` (the pipeline's detections, counter masked) and a
replay of the tracker, it prints the frames in which a detection / a reported box overlaps
his box at IoU >= 0.3 (and >= 0.1), and at a few frames the grey levels of his box (upper
quartile, median) and of a ring of 0.3 box sizes around it, beside those of the
detections of that frame.
"""

from __future__ import annotations

import argparse
import pickle
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from diagnose_ids import _plane, replay  # noqa: E402
from mk_tracker.boxes import iou  # noqa: E402
from mk_tracker.parameters import updated  # noqa: E402
from mk_tracker.tools.pipeline_config import load_pipeline_config  # noqa: E402
from setting_values import setting_changes  # noqa: E402

#: the still man's box in BU-TIV-lab (512x512), read off frames 0, 150, 300, 561
MAN = (85.0, 38.0, 55.0, 178.0)


def levels(grey: np.ndarray, box, ring: float = 0.3) -> tuple[float, float, float]:
    """Upper quartile and median of ``box``'s grey levels, median of the ring around it."""
    h_img, w_img = grey.shape
    x, y, w, h = (int(v) for v in box)
    x, y = max(x, 0), max(y, 0)
    w, h = min(w, w_img - x), min(h, h_img - y)
    inner = grey[y:y + h, x:x + w].astype(float)
    x0, y0 = max(int(x - ring * w), 0), max(int(y - ring * h), 0)
    x1, y1 = min(int(x + w + ring * w), w_img), min(int(y + h + ring * h), h_img)
    outside = np.ones((y1 - y0, x1 - x0), dtype=bool)
    outside[y - y0:y - y0 + h, x - x0:x - x0 + w] = False
    return (float(np.percentile(inner, 75)), float(np.median(inner)),
            float(np.median(grey[y0:y1, x0:x1][outside])))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cache", type=Path, required=True,
                        help="tracker inputs captured by diagnose_ids.py --cache")
    parser.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE")
    parser.add_argument("--frames", type=int, nargs="*", default=[10, 150, 300, 450, 561])
    args = parser.parse_args(argv)
    with open(args.cache, "rb") as fh:
        inputs = pickle.load(fh)[0]
    config = updated(load_pipeline_config([]).tracker, setting_changes(args.set))
    reported = replay(inputs, config)[0]
    det_best = [max((iou(MAN, d.box) for d in dets), default=0.0) for _, _, dets in inputs]
    trk_best = [max((iou(MAN, b) for _, b, _ in frame), default=0.0) for frame in reported]
    for name, best in (("detection", det_best), ("reported box", trk_best)):
        hit = [k for k, v in enumerate(best) if v >= 0.3]
        print(f"{name}: IoU >= 0.3 in {len(hit)} frames"
              f"{f' ({hit[0]}-{hit[-1]})' if hit else ''}, >= 0.1 in "
              f"{sum(v >= 0.1 for v in best)}")
    for k in args.frames:
        if not 0 <= k < len(inputs):
            continue
        grey = _plane(inputs[k][0])
        q, med, bg = levels(grey, MAN)
        print(f"frame {k}: man upper quartile {q:.0f} median {med:.0f} ring {bg:.0f}; "
              "detections " + ", ".join(
                  "{:.0f}/{:.0f}/{:.0f}".format(*levels(grey, d.box)) for d in inputs[k][2]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
