"""The thermal detector on slower cameras (issue #19: many thermal cameras deliver 8.7-9 Hz).

Each generated crowd (:func:`mk_tracker.synthetic.presets.crowd_scene`, 25 fps) is fed to
the detector at its own rate and at 1/2, 1/3 and 1/4 of it (every N-th frame with its
stamp: 12.5, 8.3 and 6.25 Hz; the people walk as before, so they move N times farther
between frames).  From frame 60 on, every person at least half visible is matched to the
detections at IoU >= 0.5 (recall), and the detections per frame are counted.  Run with
the shipped detector and with ``--set-detector counts_fps=0`` (its frame counts at any
rate).  Not a test: nothing is asserted.

    nice -n 5 .venv/bin/python benchmarks/bench_thermal_frame_rate.py \\
        --scenes 5:311:640x480 8:312:640x480 15:313:640x480 3:314:320x240 8:315:320x240
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from mk_tracker.boxes import iou_matrix  # noqa: E402
from mk_tracker.detection.thermal_detector import ThermalDetector  # noqa: E402
from mk_tracker.detection.thermal_detector_config import ThermalDetectorConfig  # noqa: E402
from mk_tracker.parameters import updated  # noqa: E402
from mk_tracker.synthetic.presets import crowd_scene  # noqa: E402
from setting_values import setting_changes  # noqa: E402

WARM_UP = 60


def measure(scene, config: ThermalDetectorConfig, step: int) -> dict:
    """Recall (IoU >= 0.5, people at least half visible) and detections per frame of the
    detector fed every ``step``-th frame of ``scene``, from frame ``WARM_UP``."""
    detector = ThermalDetector(config)
    matched = people = detections = frames = 0
    for i in range(0, len(scene), step):
        frame = scene.frame(i)
        found = detector.process(frame.thermal, frame.stamp)
        if i < WARM_UP:
            continue
        frames += 1
        boxes = np.array([d.box for d in found], dtype=float).reshape(-1, 4)
        truth = np.array([o.box_thermal for o in frame.objects if o.visible_fraction > 0.5],
                         dtype=float).reshape(-1, 4)
        people += len(truth)
        detections += len(boxes)
        if len(truth) and len(boxes):
            matched += int((iou_matrix(truth, boxes).max(axis=1) >= 0.5).sum())
    return {"recall": matched / max(people, 1), "detections": detections / max(frames, 1),
            "people": people / max(frames, 1), "full_passes": detector.full_passes}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["5:301:640x480", "8:302:640x480",
                                                         "3:303:320x240"],
                        metavar="PEOPLE:SEED:WxH")
    parser.add_argument("--steps", type=int, nargs="+", default=[1, 2, 3, 4])
    parser.add_argument("--frames", type=int, default=300)
    parser.add_argument("--set-detector", nargs="*", default=[], metavar="NAME=VALUE",
                        help="override a detector parameter (YAML value)")
    args = parser.parse_args(argv)
    config = updated(ThermalDetectorConfig(), setting_changes(args.set_detector))
    print(f"detector {' '.join(args.set_detector) or 'defaults'}; {args.frames} frames at "
          f"25 fps, scored from frame {WARM_UP}\n")
    print("| people | seed | size | rate (Hz) | recall (IoU >= 0.5) | detections / frame | "
          "people / frame | full-frame passes |")
    print("|---:|---:|---|---:|---:|---:|---:|---:|")
    for spec in args.scenes:
        people, seed, size = spec.split(":")
        width, height = (int(v) for v in size.split("x"))
        scene = crowd_scene(int(people), seed=int(seed), width=width, height=height,
                            frames=args.frames)
        for step in args.steps:
            m = measure(scene, config, step)
            print(f"| {people} | {seed} | {size} | {25.0 / step:.2f} | {m['recall']:.3f} | "
                  f"{m['detections']:.2f} | {m['people']:.2f} | {m['full_passes']} |",
                  flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
