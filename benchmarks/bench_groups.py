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
* ``truth``: ground-truth boxes as detections, the tracker's ceiling;
* ``truth, half visible``: only the boxes of people at least half visible, the most a
  detector can be asked for (the ground truth scored against still counts everyone);
* ``truth, touching merged``: those boxes with people who overlap joined into one box, a
  detector that finds every person but merges neighbours (:data:`TOUCHING`).

Reported per cell: detection recall / precision of the detector alone, by two rules: a
detection matches a person at least half visible when its centroid is inside the person's box
(as in benchmarks/bench_thermal_detector.py), and, stricter, when its box overlaps the
person's thermal box at IoU >= 0.5 (the rule MOTA applies to the tracks); and MOTA, IDF1, ID
switches of the pipeline.  ``kernel -> SORT-style`` and ``kernel -> norfair (IoU)`` feed the
default detector's boxes, mapped to the RGB image through the scene's homography, to the peer
trackers of benchmarks/peers, scored against the same RGB ground truth: whether our tracker
adds to what the detections give.  Not a test: nothing is asserted.

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

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_pipeline import with_truth_as_detections  # noqa: E402
from bench_thermal_detector import MIN_VISIBLE, match_frame  # noqa: E402
from peers.norfair_peer import NorfairPeer  # noqa: E402
from peers.sort_tracker import SortTracker  # noqa: E402
from setting_values import setting_changes  # noqa: E402

from mk_tracker.boxes import iou, transform_box  # noqa: E402
from mk_tracker.evaluation.metrics import MotRow, mot_metrics  # noqa: E402
from mk_tracker.synthetic.scene_bag import ground_truth_detections  # noqa: E402
from mk_tracker.tracking.association import assign  # noqa: E402

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
            ("truth", base, "topic:/detections"),
            ("truth, half visible", base, "topic:/detections"),
            ("truth, touching merged", base, "topic:/detections")]


# The ground-truth rows between the tracker's ceiling and the detectors: which part of the
# pipeline's loss is the tracker's.  "half visible": only people at least MIN_VISIBLE
# visible (what a detector can be asked to find; the ground truth still counts everyone);
# "touching merged": the same, and people whose boxes overlap by more than TOUCHING of the
# smaller one reported as one box (a detector that merges neighbours).
TOUCHING = 0.15
TRUTH_ROWS = {"truth": {}, "truth, half visible": {"min_visible": MIN_VISIBLE},
              "truth, touching merged": {"min_visible": MIN_VISIBLE,
                                         "merge_overlap": TOUCHING}}


PEERS = {"SORT-style": SortTracker, "norfair (IoU)": NorfairPeer}


def iou_matches(detections, objects, threshold: float = 0.5) -> tuple[int, int, int]:
    """``(true positives, false positives, false negatives)`` of one frame when a detection
    must overlap a person's thermal box at IoU >= ``threshold`` (one to one, Hungarian).  As
    in :func:`bench_thermal_detector.match_frame`, a person less than half visible is neither
    missed nor found, and a detection matched to one is not a false positive."""
    gts = [o for o in objects if o.in_frame]
    cost = np.array([[1.0 - iou(d.box, o.box_thermal) for o in gts] for d in detections]
                    ).reshape(len(detections), len(gts))
    result = assign(cost, max_cost=1.0 - threshold + 1e-12)
    matched = {j for _, j in result.matches}
    tp = sum(1 for _, j in result.matches if gts[j].visible_fraction >= MIN_VISIBLE)
    fn = sum(1 for j, o in enumerate(gts) if o.visible_fraction >= MIN_VISIBLE
             and j not in matched)
    return tp, len(result.unmatched_rows), fn


def detector_pass(scene, method: str, config, step: int = 1
                  ) -> tuple[tuple[float, ...], list]:
    """The detector alone over every ``step``-th frame of ``scene``: ``((recall, precision,
    IoU recall, IoU precision), per frame (stamp, detections))``; warm-up frames are not
    scored."""
    detector = ThermalDetector(config) if method == "kernel" else ThresholdDetector(config)
    counts = np.zeros(6)
    frames = []
    for i in range(0, len(scene), step):
        fr = scene.frame(i)
        dets = detector.process(fr.thermal, fr.stamp)
        frames.append((fr.stamp, dets))
        if getattr(detector, "last_mode", "frame") == "warming_up":
            continue
        counts += (*match_frame(dets, fr.objects)[:3], *iou_matches(dets, fr.objects))
    tp, fp, fn, itp, ifp, ifn = counts
    return ((tp / max(tp + fn, 1), tp / max(tp + fp, 1),
             itp / max(itp + ifn, 1), itp / max(itp + ifp, 1)), frames)


def peer_scores(scene, frames) -> dict[str, tuple[float, float, int]]:
    """MOTA, IDF1, ID switches of each peer fed ``frames``' detections in RGB pixels, against
    the RGB ground truth the pipeline is scored on (IoU 0.5)."""
    truth = [MotRow(i + 1, int(d.id), tuple(d.box))
             for i in range(len(scene))
             for d in ground_truth_detections(scene, scene.frame(i), "rgb")]
    out = {}
    for name, factory in PEERS.items():
        tracker = factory()
        hyp = []
        for i, (stamp, dets) in enumerate(frames):
            boxes = [(*transform_box(d.box, scene.homography), d.score) for d in dets]
            hyp += [MotRow(i + 1, int(k), tuple(b)) for k, b in tracker.update(stamp, boxes)]
        m = mot_metrics(truth, hyp)
        out[name] = (m["mota"], m["idf1"], m["num_switches"])
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--people", type=int, nargs="+", default=[1, 3, 8, 15, 30])
    parser.add_argument("--sizes", nargs="+", default=["320x240", "640x480"])
    parser.add_argument("--seeds", type=int, nargs="+", default=[201])
    parser.add_argument("--frames", type=int, default=150)
    parser.add_argument("--configs", nargs="+", default=None,
                        help="names of the configurations to run (default: all)")
    parser.add_argument("--thermal-step", type=int, default=1,
                        help="write the thermal image of every N-th frame only (a slower "
                        "thermal camera beside the RGB one)")
    parser.add_argument("--out", type=Path, default=None)
    parser.add_argument("--no-peers", dest="peers", action="store_false",
                        help="leave out the peer trackers fed the default detector's boxes")
    parser.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE",
                        help="override a parameter of the tracker (YAML value), e.g. "
                             "duplicates.enabled=false")
    parser.add_argument("--set-detector", nargs="*", default=[], metavar="NAME=VALUE",
                        help="override a parameter of the detector (YAML value), e.g. "
                             "size_max_residual=0.25")
    args = parser.parse_args(argv)

    base = load_pipeline_config()

    if args.set:
        base = replace(base, tracker=updated(base.tracker, setting_changes(args.set)))
    if args.set_detector:
        base = replace(base, detector=updated(base.detector,
                                              setting_changes(args.set_detector)))
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
                    write_scene_bag(scene, bag, preset="crowd",
                                    thermal_step=args.thermal_step)
                    truth = {}
                    for name, kwargs in TRUTH_ROWS.items():
                        if any(c[0] == name for c in configs):
                            truth[name] = tmp / f"{len(truth)}_{size}_{people}_{seed}"
                            with_truth_as_detections(bag, truth[name], **kwargs)
                    detectors = {"kernel": ("kernel", base.detector),
                                 "kernel + size split": ("kernel", replace(
                                     base.detector, split_by_person_size=True)),
                                 "kernel + cluster split": ("kernel", replace(
                                     base.detector, split_clusters=True)),
                                 "kernel + join stacked": ("kernel",
                                                           _joining(base.detector)),
                                 "threshold": ("threshold", base.threshold)}
                    # the detector alone, for the configurations that run
                    passes = {name: detector_pass(scene, *detectors[name],
                                                  step=args.thermal_step)
                              for name in {c[0].split(",")[0] for c in configs}
                              if name in detectors}
                    det = {name: scores for name, (scores, _) in passes.items()}
                    if "kernel" in passes and args.peers and args.thermal_step == 1:
                        for peer, (mota, idf1, sw) in peer_scores(
                                scene, passes["kernel"][1]).items():
                            rows.append((size, people, seed, f"kernel -> {peer}",
                                         *det["kernel"], mota, idf1, sw, float("nan")))
                            print(rows[-1], flush=True)
                    for name, config, source in configs:
                        result = process_bag(truth[name] if source.startswith("topic:") else bag,
                                             tmp / f"run_{size}_{people}_{seed}_{name}", config,
                                             PipelineOptions(detections=source, progress=False,
                                                             # the same tracker as the
                                                             # thermal rows (no overlay)
                                                             tracker_profile="own",
                                                             write_video=False,
                                                             write_plots=False,
                                                             write_bag=False))
                        m = result.metrics
                        scores = det.get(name.split(",")[0], (float("nan"),) * 4)
                        row = (size, people, seed, name, *scores, m["mota"],
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
        "the person's box; IoU: its box overlaps the person's at IoU >= 0.5.  `kernel -> "
        "peer`: the default detector's boxes fed to a peer tracker.  frames/s: the whole "
        "offline pipeline, no video.", "",
        "| size | people | seed | configuration | det. recall / precision (centroid) | det. "
        "recall / precision (IoU 0.5) | MOTA | IDF1 | ID sw. | frames/s |",
        "|---|---:|---:|---|---:|---:|---:|---:|---:|---:|",
    ]

    def pair(a, b):
        return "" if a != a else f"{a:.2f} / {b:.2f}"
    for size, people, seed, name, rec, prec, irec, iprec, mota, idf1, sw, fps in rows:
        rate = "" if fps != fps else f"{fps:.1f}"
        lines.append(f"| {size} | {people} | {seed} | {name} | {pair(rec, prec)} | "
                     f"{pair(irec, iprec)} | {mota:.3f} | {idf1:.3f} | {sw} | {rate} |")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
