"""The thermal -> RGB pipeline in groups (issue #15): generate -> process -> score.

For each people count and image size, one crowd scene per seed (seeds not used for any
choice of defaults) is generated and processed by ``mk_tracker process`` with:

* ``kernel``: the default system (sparse kernel covariance detector of Schizas et al. 2018
  + the multi-object tracker with multiple-kernel refinement of Chu et al. 2013);
* ``kernel + size split``: the detector's ``split_by_person_size`` switched on (off by
  default: see docs/benchmark_groups.md);
* ``kernel + cluster split``: the detector's ``split_clusters`` switched on (off by default,
  the same page);
* ``kernel + join stacked``: the detector's ``body_extent.join_stacked`` switched on (a
  person's stacked parts reported as one box; off by default, the same page);
* ``kernel, no groups``: the default detector with the tracker's group measurements off
  (``tracker.group.enabled: false``), the tracker as it was before issue #15;
* ``threshold``: the threshold detector baseline driving the same tracker;
* ``truth``: ground-truth boxes as detections, the tracker's ceiling.

Reported per cell: detection recall / precision of the detector alone (a detection matches a
person at least half visible when its centroid is inside the person's box, as in
benchmarks/bench_thermal_detector.py), and MOTA, IDF1, ID switches of the pipeline.  Not a
test: nothing is asserted.

    .venv/bin/python benchmarks/bench_groups.py --out docs/benchmark_groups.md

``--set NAME=VALUE`` overrides a parameter of the tracker in every configuration (YAML value,
e.g. ``duplicates.enabled=false``), for ablations on the held-out seed; ``--set-detector``
does the same for the detector (e.g. ``size_max_residual=0.25``).
"""

from __future__ import annotations

import argparse
import platform
import shlex
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_pipeline import with_truth_as_detections  # noqa: E402
from bench_thermal_detector import run as run_detector  # noqa: E402

from mk_tracker.detection.thermal_detector import ThermalDetector  # noqa: E402
from mk_tracker.detection.threshold_detector import ThresholdDetector  # noqa: E402
from mk_tracker.synthetic.scene_bag import build_preset, write_scene_bag  # noqa: E402
from mk_tracker.parameters import updated  # noqa: E402
from mk_tracker.tools.pipeline import PipelineOptions, process_bag  # noqa: E402
from mk_tracker.tools.pipeline_config import load_pipeline_config  # noqa: E402


def _joining(detector):
    return replace(detector, body_extent=replace(detector.body_extent, join_stacked=True))


def configurations(base):
    no_groups = replace(base, tracker=replace(
        base.tracker, group=replace(base.tracker.group, enabled=False)))
    split = replace(base, detector=replace(base.detector, split_by_person_size=True))
    clusters = replace(base, detector=replace(base.detector, split_clusters=True))
    stacked = replace(base, detector=_joining(base.detector))
    return [("kernel", base, "thermal"),
            ("kernel + size split", split, "thermal"),
            ("kernel + cluster split", clusters, "thermal"),
            ("kernel + join stacked", stacked, "thermal"),
            ("kernel, no groups", no_groups, "thermal"),
            ("threshold", replace(base, method="threshold"), "thermal"),
            ("truth", base, "topic:/detections")]


def detector_scores(scene, method: str, config) -> tuple[float, float]:
    detector = ThermalDetector(config) if method == "kernel" else ThresholdDetector(config)
    _, _, tp, fp, fn, _ = run_detector(detector, scene)
    return tp / max(tp + fn, 1), tp / max(tp + fp, 1)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--people", type=int, nargs="+", default=[1, 3, 8, 15, 30])
    parser.add_argument("--sizes", nargs="+", default=["320x240", "640x480"])
    parser.add_argument("--seeds", type=int, nargs="+", default=[201])
    parser.add_argument("--frames", type=int, default=150)
    parser.add_argument("--configs", nargs="+", default=None,
                        help="names of the configurations to run (default: all)")
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE",
                        help="override a parameter of the tracker (YAML value), e.g. "
                             "duplicates.enabled=false")
    parser.add_argument("--set-detector", nargs="*", default=[], metavar="NAME=VALUE",
                        help="override a parameter of the detector (YAML value), e.g. "
                             "size_max_residual=0.25")
    args = parser.parse_args(argv)

    base = load_pipeline_config()

    def changes(items):
        return {n: yaml.safe_load(v) for n, _, v in (i.partition("=") for i in items)}
    if args.set:
        base = replace(base, tracker=updated(base.tracker, changes(args.set)))
    if args.set_detector:
        base = replace(base, detector=updated(base.detector, changes(args.set_detector)))
    configs = [c for c in configurations(base) if args.configs is None or c[0] in args.configs]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for size in args.sizes:
            width, height = (int(v) for v in size.split("x"))
            for people in args.people:
                for seed in args.seeds:
                    scene = build_preset("crowd", seed=seed, people=people,
                                         frames=args.frames, width=width, height=height)
                    bag = tmp / f"scene_{size}_{people}_{seed}"
                    write_scene_bag(scene, bag, preset="crowd")
                    truth = tmp / f"truth_{size}_{people}_{seed}"
                    with_truth_as_detections(bag, truth)
                    detectors = {"kernel": ("kernel", base.detector),
                                 "kernel + size split": ("kernel", replace(
                                     base.detector, split_by_person_size=True)),
                                 "kernel + cluster split": ("kernel", replace(
                                     base.detector, split_clusters=True)),
                                 "kernel + join stacked": ("kernel",
                                                           _joining(base.detector)),
                                 "threshold": ("threshold", base.threshold)}
                    # the detector alone, for the configurations that run
                    det = {name: detector_scores(scene, *detectors[name])
                           for name in {c[0].split(",")[0] for c in configs}
                           if name in detectors}
                    for name, config, source in configs:
                        result = process_bag(truth if source.startswith("topic:") else bag,
                                             tmp / f"run_{size}_{people}_{seed}_{name}", config,
                                             PipelineOptions(detections=source, progress=False,
                                                             write_video=False,
                                                             write_plots=False,
                                                             write_bag=False))
                        m = result.metrics
                        recall, precision = det.get(name.split(",")[0],
                                                    (float("nan"),) * 2)
                        row = (size, people, seed, name, recall, precision, m["mota"],
                               m["idf1"], m["num_switches"], result.frames / result.seconds)
                        rows.append(row)
                        print(" | ".join(str(v) if not isinstance(v, float) else f"{v:.3f}"
                                         for v in row), flush=True)
    if args.out is None:
        return 0
    command = ".venv/bin/python benchmarks/bench_groups.py " + shlex.join(
        argv if argv is not None else sys.argv[1:])
    lines = [
        "# Thermal -> RGB pipeline in groups (issue #15)", "",
        "Produced by:", "", "```", command.rstrip(), "```", "",
        f"Crowd preset, {args.frames} frames, seeds {', '.join(map(str, args.seeds))} (not "
        f"used for any choice).  Machine: {platform.machine()}, Python "
        f"{platform.python_version()}.  Detector recall/precision: the detector alone, a "
        "detection matching a person at least half visible when its centroid is inside "
        "the person's box.  frames/s: the whole offline pipeline, no video.", "",
        "| size | people | seed | configuration | det. recall | det. precision | MOTA | IDF1 "
        "| ID sw. | frames/s |",
        "|---|---:|---:|---|---:|---:|---:|---:|---:|---:|",
    ]
    for size, people, seed, name, rec, prec, mota, idf1, sw, fps in rows:
        det = "" if rec != rec else f"{rec:.2f}"
        detp = "" if prec != prec else f"{prec:.2f}"
        lines.append(f"| {size} | {people} | {seed} | {name} | {det} | {detp} | {mota:.3f} "
                     f"| {idf1:.3f} | {sw} | {fps:.1f} |")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
