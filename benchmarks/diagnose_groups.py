"""Where the thermal detector's missed people go in generated crowds (issue #15 item 1).

The detector alone (:class:`mk_tracker.detection.thermal_detector.ThermalDetector` with the
shipped ``config/detector.yaml``, plus ``--set`` overrides) runs over crowd-preset scenes,
matched per frame as in ``benchmarks/bench_thermal_detector.py`` (a detection matches a
person at least half visible when its centroid lies inside the person's box; Hungarian on
the distance to the box centre).  Each person it misses is put under one cause, the first
that holds:

* ``merged, centre in box``: a detection's centroid lies in the person's box but the
  assignment gave it to another person (one detection for two or more people);
* ``merged, box covers``: a detection's box covers more than half of the person's box and
  its centroid lies elsewhere (the person is inside someone else's detection);
* ``partial overlap``: detection boxes touch the person's box, none of the two above;
* ``no detection near``: no detection box touches it (no support, dropped by a size or
  score filter, or its object was dropped after ``max_missed`` frames).

Each unmatched detection is put under ``duplicate`` (its centroid lies in a person's box
that another detection took: one person reported twice, or a group's part), ``merged
group`` (its box covers more than 30% of two or more people), ``offset`` (of one) or
``ghost`` (of nobody).  Counts are split by pass: full-frame (start-up, reconfiguration)
and tracking.  Not a test: nothing is asserted.

    nice -n 10 .venv/bin/python benchmarks/diagnose_groups.py --people 3 8 15 \\
        --sizes 320x240 --seeds 101 102 103
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_thermal_detector import MIN_VISIBLE  # noqa: E402

from mk_tracker.detection.thermal_detector import ThermalDetector  # noqa: E402
from mk_tracker.parameters import updated  # noqa: E402
from mk_tracker.synthetic.scene_bag import build_preset  # noqa: E402
from mk_tracker.tools.pipeline_config import load_pipeline_config  # noqa: E402
from mk_tracker.tracking.association import assign  # noqa: E402
from setting_values import setting_changes  # noqa: E402

MISS_CAUSES = ("merged, centre in box", "merged, box covers", "partial overlap",
               "no detection near")
EXTRA_CAUSES = ("duplicate", "merged group", "offset", "ghost")


def _inside(point, box) -> bool:
    x, y, w, h = box
    return x <= point[0] <= x + w and y <= point[1] <= y + h


def _common_area(a, b) -> float:
    w = min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0])
    h = min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1])
    return max(w, 0.0) * max(h, 0.0)


def frame_causes(detections, objects) -> tuple[int, int, list[str], list[str]]:
    """``(people counted, people matched, cause of each miss, cause of each unmatched
    detection)`` of one frame."""
    gts = [o for o in objects if o.in_frame]
    cost = np.full((len(detections), len(gts)), np.inf)
    for i, d in enumerate(detections):
        for j, o in enumerate(gts):
            if _inside(d.centroid, o.box_thermal):
                x, y, w, h = o.box_thermal
                cost[i, j] = np.hypot(d.centroid[0] - x - w / 2, d.centroid[1] - y - h / 2)
    pairs = assign(cost, max_cost=float("inf")).matches if detections and gts else []
    person_of = {i: j for i, j in pairs}
    taken = set(person_of.values())
    counted = matched = 0
    misses: list[str] = []
    for j, o in enumerate(gts):
        if o.visible_fraction < MIN_VISIBLE:
            continue
        counted += 1
        if j in taken:
            matched += 1
            continue
        box = o.box_thermal
        touching = [d for d in detections if _common_area(d.box, box) > 0]
        if any(_inside(d.centroid, box) for d in touching):
            misses.append(MISS_CAUSES[0])
        elif any(_common_area(d.box, box) > 0.5 * box[2] * box[3] for d in touching):
            misses.append(MISS_CAUSES[1])
        else:
            misses.append(MISS_CAUSES[2] if touching else MISS_CAUSES[3])
    extras: list[str] = []
    for i, d in enumerate(detections):
        if i in person_of:
            continue
        if any(_inside(d.centroid, o.box_thermal) for o in gts):
            extras.append(EXTRA_CAUSES[0])
            continue
        covered = sum(1 for o in gts if _common_area(d.box, o.box_thermal)
                      > 0.3 * o.box_thermal[2] * o.box_thermal[3])
        extras.append(EXTRA_CAUSES[1] if covered >= 2 else
                      EXTRA_CAUSES[2] if covered == 1 else EXTRA_CAUSES[3])
    return counted, matched, misses, extras


def diagnose(scene, config) -> Counter:
    """Counts keyed ``(pass, what)``: ``people``, ``matched`` and each cause."""
    detector = ThermalDetector(config)
    counts: Counter = Counter()
    for i in range(len(scene)):
        fr = scene.frame(i)
        dets = detector.process(fr.thermal, fr.stamp)
        if detector.last_mode == "warming_up":
            continue
        mode = "tracking" if detector.last_mode == "tracking" else "full"
        counted, matched, misses, extras = frame_causes(dets, fr.objects)
        counts[mode, "people"] += counted
        counts[mode, "matched"] += matched
        counts.update((mode, c) for c in misses + extras)
    return counts


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--people", type=int, nargs="+", default=[3, 8, 15])
    parser.add_argument("--sizes", nargs="+", default=["320x240"])
    parser.add_argument("--seeds", type=int, nargs="+", default=[101, 102, 103])
    parser.add_argument("--frames", type=int, default=150)
    parser.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE",
                        help="override a detector parameter (YAML value), e.g. "
                             "split_by_person_size=true")
    args = parser.parse_args(argv)
    config = load_pipeline_config().detector
    if args.set:
        config = updated(config, setting_changes(args.set))
    print("| size | people | recall | precision | pass | " + " | ".join(MISS_CAUSES)
          + " | " + " | ".join(f"extra: {c}" for c in EXTRA_CAUSES) + " |")
    print("|---|---:|---:|---:|---|" + "---:|" * (len(MISS_CAUSES) + len(EXTRA_CAUSES)))
    for size in args.sizes:
        width, height = (int(v) for v in size.split("x"))
        for people in args.people:
            total: Counter = Counter()
            for seed in args.seeds:
                total += diagnose(build_preset("crowd", seed=seed, people=people,
                                               frames=args.frames, width=width,
                                               height=height), config)
            matched = total["full", "matched"] + total["tracking", "matched"]
            counted = total["full", "people"] + total["tracking", "people"]
            # as the thermal benchmark: a detection on a less visible person is neither
            found = matched + sum(total[m, c] for m in ("full", "tracking")
                                  for c in EXTRA_CAUSES)
            for mode in ("full", "tracking"):
                figures = " | ".join(str(total[mode, c]) for c in MISS_CAUSES + EXTRA_CAUSES)
                print(f"| {size} | {people} | {matched / max(counted, 1):.3f} | "
                      f"{matched / max(found, 1):.3f} | {mode} "
                      f"({total[mode, 'matched']}/{total[mode, 'people']}) | {figures} |",
                      flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
