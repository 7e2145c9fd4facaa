"""The thermal detector under other thermal conditions than the generator's defaults: a warm
or cold background, a textured one, more sensor noise (issue #19: outdoor LWIR is not the
lab).

One generated crowd (:func:`mk_tracker.synthetic.presets.crowd_scene`, ``--people``
people, 640x480, ``--frames`` frames, ``--seed``) is rendered again with one scene
constant changed at a time (the people are the same: torso 301.5-304 K, head 4 K warmer,
legs 2.5 K cooler; mono8 maps 288-318 K to 0-255, or, in the "gain" rows, a 15 K range
around the scene as a camera's automatic gain would, or the frame's histogram is
equalised, or every column's offset flickers from frame to frame as on uncooled sensors).
The shipped detector runs on each; from frame 20 on, every person at least
half visible is matched to the detections (IoU >= 0.5), and for the people whose column
holds a detection starting above their middle, the detection's height over theirs is the
"box height / person height" (1 = the whole body).  Not a test: nothing is asserted.

    nice -n 10 .venv/bin/python benchmarks/bench_thermal_conditions.py
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from mk_tracker.boxes import iou_matrix  # noqa: E402
from mk_tracker.detection.thermal_detector import ThermalDetector  # noqa: E402
from mk_tracker.detection.thermal_detector_config import ThermalDetectorConfig  # noqa: E402
from mk_tracker.synthetic.presets import crowd_scene  # noqa: E402
from mk_tracker.parameters import updated  # noqa: E402
from mk_tracker.synthetic.scene import make_scene  # noqa: E402
from setting_values import setting_changes  # noqa: E402

#: (name, scene constants changed); the generator's defaults: background 293 K with a 2 K
#: gradient and 0.4 K of texture, sensor noise 0.3 K
CONDITIONS = (
    ("defaults (background 293 K)", {}),
    ("cold background 280 K", {"background_temperature": 280.0}),
    ("warm background 299 K", {"background_temperature": 299.0}),
    ("warm background 301 K", {"background_temperature": 301.0}),
    # a camera's automatic gain maps the scene's own range to 0-255 (288-318 K above)
    ("warm 299 K, gain on 296-311 K", {"background_temperature": 299.0,
                                       "mono8_min_kelvin": 296.0, "mono8_max_kelvin": 311.0}),
    ("warm 301 K, gain on 298-313 K", {"background_temperature": 301.0,
                                       "mono8_min_kelvin": 298.0, "mono8_max_kelvin": 313.0}),
    # ... or equalises its histogram (many LWIR cameras' 8-bit output): globally
    # (cv2.equalizeHist) or with a clip limit on the amplification (CLAHE, clip 2, 8x8 tiles)
    ("warm 299 K, equalised", {"background_temperature": 299.0, "equalise": "global"}),
    ("warm 299 K, CLAHE", {"background_temperature": 299.0, "equalise": "clahe"}),
    ("warm 301 K, CLAHE", {"background_temperature": 301.0, "equalise": "clahe"}),
    ("textured background 1.5 K", {"background_texture": 1.5}),
    ("sensor noise 0.8 K", {"thermal_noise_std": 0.8}),
    ("sensor noise 1.2 K", {"thermal_noise_std": 1.2}),
    ("sensor noise 1.6 K", {"thermal_noise_std": 1.6}),
    # uncooled sensors' column offsets flicker from frame to frame (grey levels, per column)
    ("column flicker 6 levels", {"column_noise": 6.0}),
    ("column flicker 10 levels", {"column_noise": 10.0}),
)
WARM_UP = 20


def measure(scene, config: ThermalDetectorConfig, equalise: str = "",
            column_noise: float = 0.0) -> dict:
    detector = ThermalDetector(config)
    clahe = cv2.createCLAHE(clipLimit=2.0, tileGridSize=(8, 8))
    rng = np.random.default_rng(0)
    matched = people = detections = 0
    ratios = []
    for i in range(len(scene)):
        frame = scene.frame(i)
        image = (cv2.equalizeHist(frame.thermal) if equalise == "global" else
                 clahe.apply(frame.thermal) if equalise == "clahe" else frame.thermal)
        if column_noise > 0.0:
            offsets = rng.normal(0.0, column_noise, (1, image.shape[1]))
            image = np.clip(np.rint(image + offsets), 0, 255).astype(np.uint8)
        found = detector.process(image, frame.stamp)
        if i < WARM_UP:
            continue
        truth = np.array([o.box_thermal for o in frame.objects if o.visible_fraction > 0.5],
                         dtype=float).reshape(-1, 4)
        boxes = np.array([d.box for d in found], dtype=float).reshape(-1, 4)
        people += len(truth)
        detections += len(boxes)
        if len(truth) and len(boxes):
            matched += int((iou_matrix(truth, boxes).max(axis=1) >= 0.5).sum())
        for g in truth:
            for b in boxes:
                if abs(b[0] + b[2] / 2 - g[0] - g[2] / 2) < g[2] / 2 and b[1] < g[1] + g[3] / 2:
                    ratios.append(b[3] / g[3])
    frames = max(len(scene) - WARM_UP, 1)
    return {"recall": matched / max(people, 1), "detections": detections / frames,
            "people": people / frames,
            "height": float(np.median(ratios)) if ratios else float("nan")}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--people", type=int, default=5)
    parser.add_argument("--frames", type=int, default=120)
    parser.add_argument("--seed", type=int, default=301)
    parser.add_argument("--set-detector", nargs="*", default=[], metavar="NAME=VALUE",
                        help="override a detector parameter (YAML value)")
    args = parser.parse_args(argv)
    config = updated(ThermalDetectorConfig(), setting_changes(args.set_detector))
    base = crowd_scene(args.people, seed=args.seed, width=640, height=480, frames=args.frames)
    print(f"crowd_scene({args.people} people, seed {args.seed}, 640x480, {args.frames} frames),"
          f" detector {' '.join(args.set_detector) or 'defaults'}, from frame {WARM_UP}\n")
    print("| condition | recall (IoU >= 0.5) | detections / frame | people / frame | box "
          "height / person height (median) |")
    print("|---|---:|---:|---:|---:|")
    for name, changes in CONDITIONS:
        changes = dict(changes)
        equalise = changes.pop("equalise", "")
        column_noise = changes.pop("column_noise", 0.0)
        m = measure(make_scene(dataclasses.replace(base.config, **changes)), config, equalise,
                    column_noise)
        print(f"| {name} | {m['recall']:.3f} | {m['detections']:.2f} | {m['people']:.2f} | "
              f"{m['height']:.2f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
