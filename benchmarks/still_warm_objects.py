"""Static warm objects against ``detector.still_people`` (issue #19): does the rule report a
radiator, a lamp or an upright warm column as a person?

    .venv/bin/python benchmarks/still_warm_objects.py [--frames 150] [--seed 0]

Scenes: ``static_warm_objects_scene`` (two radiators 90x50 and 80x45 px, a lamp 36x36 px,
warmer than the one person who walks by) and the same with an upright warm column of a
person's shape (30x110 px at 310 K).  The thermal detector runs with the rule off and on;
printed per run: detections, those not on the person (IoU <= 0.1 with their box) and those
on a warm object (IoU > 0.3).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mk_tracker.boxes import iou  # noqa: E402
from mk_tracker.detection.still_people import StillPeopleConfig  # noqa: E402
from mk_tracker.detection.thermal_detector import (ThermalDetector,  # noqa: E402
                                                   ThermalDetectorConfig)
from mk_tracker.synthetic.presets import static_warm_objects_scene  # noqa: E402
from mk_tracker.synthetic.scene import make_scene  # noqa: E402
from mk_tracker.synthetic.scene_config import WarmObjectSpec  # noqa: E402

COLUMN = WarmObjectSpec(box=(560.0, 150.0, 30.0, 110.0), temperature=310.0)


def count(scene, enabled: bool) -> tuple[int, int, int]:
    det = ThermalDetector(ThermalDetectorConfig(still_people=StillPeopleConfig(enabled=enabled)))
    total = off_person = on_object = 0
    for k in range(scene.config.frames):
        fr = scene.frame(k)
        found = det.process(fr.thermal, fr.stamp)
        people = scene.boxes_thermal(k)
        for d in found:
            total += 1
            off_person += not any(iou(d.box, p) > 0.1 for p in people)
            on_object += any(iou(d.box, w.box) > 0.3 for w in scene.config.warm_objects)
    return total, off_person, on_object


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=150)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    base = static_warm_objects_scene(args.seed, args.frames)
    column = make_scene(dataclasses.replace(
        base.config, warm_objects=base.config.warm_objects + (COLUMN,)))
    print("| scene | still_people | detections | not on the person | on a warm object |")
    print("|---|---|---:|---:|---:|")
    for name, scene in (("radiators and lamp", base), ("... and an upright column", column)):
        for enabled in (False, True):
            total, off, on = count(scene, enabled)
            print(f"| {name} | {'on' if enabled else 'off'} | {total} | {off} | {on} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
