"""Why a person who stands still loses the track (issue #19): frame by frame, what the
track a stopper had at the stop is doing in their still frames.

Runs the scenes of benchmarks/bench_still_people.py through ``mk_tracker process``'s code
with the tracker's every frame recorded (all states, not only the reported boxes), and
counts each still frame (at least half of the person visible) as one of:

* ``reported``: the stop id's reported box covers the person (IoU >= 0.5);
* ``reported, off``: reported, but at IoU < 0.5 (the box drifted or changed size);
* ``confirmed/occluded, not reported``: the track is alive but hidden by the report rules
  (``max_reported_coast_time``, ``max_reported_coast_std`` or a suppression), split by state;
* ``lost``: in the lost state (no box), e.g. after ``max_undetected_time`` or
  ``max_coast_time``;
* ``gone (deleted)``: the stop id ended (``max_lost_time`` or a merge);
* ``no id at the stop``: no reported box covered the person in the last frame before it;
* plus, among the frames not ``reported``, how many another id covers, and, in the frames
  the stop track was given a detection, whether that detection was the person's own (IoU
  >= 0.5), another person's (a larger IoU with them) or a part of the person; a member of a
  group measurement counts with its last single detection;
* for ``reported, off``, how many are a centre more than a quarter box off and how many a
  height outside 0.8-1.25 of the person's.

It also prints the transitions of each stop track (frame, state, similarity, speed in box
heights per second, seconds since its last detection), so the rule that ends it can be read.

    nice -n 10 .venv/bin/python benchmarks/diagnose_still_people.py --seeds 101 102 103
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_still_people import (MIN_VISIBLE, config_with, covering_id,  # noqa: E402
                                scene_bags)
from mk_tracker.boxes import iou  # noqa: E402
from mk_tracker.tools.pipeline import PipelineOptions, process_bag  # noqa: E402
from mk_tracker.tracking import multi_object_tracker as mot  # noqa: E402


def recorded_run(bag: Path, out: Path, config) -> list[dict]:
    """Per frame: ``{id: (state, box, score, time since detection, speed h/s, reported,
    detection box assigned this frame or None)}``."""
    frames: list[dict] = []
    step = mot.MultiObjectTracker.step

    def recording(self, image, stamp, detections=()):
        result = step(self, image, stamp, detections)
        shown = {o.id for o in result.reported()}
        speed = {t.id: float(np.hypot(*t.kf.velocity)) / max(float(t.size[1]), 1e-9)
                 for t in self.tracks}
        detected = {t.id: tuple(t.detected_box) for t in self.tracks
                    if t.last_detection == t.stamp}
        frames.append({o.id: (o.state, o.box, o.score, o.time_since_detection,
                              speed.get(o.id, 0.0), o.id in shown, detected.get(o.id))
                       for o in result.tracks})
        return result

    mot.MultiObjectTracker.step = recording
    try:
        process_bag(bag, out, config, PipelineOptions(
            detections="thermal", progress=False, write_video=False, write_plots=False,
            write_bag=False))
    finally:
        mot.MultiObjectTracker.step = step
    return frames


def classify(truth, frames, stills, verbose: bool) -> Counter:
    counts: Counter = Counter()
    for pid, still in stills.items():
        before = {o: b for o, b, _ in truth[still[0] - 1]}.get(pid)
        shown = [(tid, r[1]) for tid, r in frames[still[0] - 1].items() if r[5]]
        stop_id = covering_id(shown, before) if before is not None else None
        last = None
        for i in still:
            gt = {o: (b, v) for o, b, v in truth[i]}.get(pid)
            if gt is None or gt[1] < MIN_VISIBLE:
                continue
            rec = frames[i].get(stop_id) if stop_id is not None else None
            if stop_id is None:
                kind = "no id at the stop"
            elif rec is None:
                kind = "gone (deleted)"
            elif rec[5]:
                kind = "reported" if iou(rec[1], gt[0]) >= 0.5 else "reported, off"
            elif rec[0] == "lost":
                kind = "lost"
            else:
                kind = f"{rec[0]}, not reported"
            counts[kind] += 1
            if rec is not None and rec[6] is not None:   # a detection assigned this frame
                own = iou(rec[6], gt[0])
                other = max([iou(rec[6], b) for o, b, _ in truth[i] if o != pid], default=0.0)
                counts["detected: own (IoU >= 0.5)" if own >= 0.5 else
                       "detected: another person's (IoU more with them)" if other > own else
                       "detected: part of the person / off"] += 1
            if kind == "reported, off":
                b, g = np.asarray(rec[1]), np.asarray(gt[0])
                off = (b[:2] + b[2:] / 2 - g[:2] - g[2:] / 2) / g[2:]
                counts["off: centre > w/4 or h/4"] += bool(np.any(np.abs(off) > 0.25))
                counts["off: height ratio outside 0.8-1.25"] += not 0.8 <= b[3] / g[3] <= 1.25
            if kind != "reported":
                other = covering_id([(t, r[1]) for t, r in frames[i].items()
                                     if r[5] and t != stop_id], gt[0])
                counts["(not reported: another id covers)"] += other is not None
            if verbose and (rec[0] if rec else None) != last:
                desc = "none" if rec is None else (
                    f"{rec[0]} shown={rec[5]} sim={rec[2]:.2f} undet={rec[3]:.2f}s "
                    f"speed={rec[4]:.2f}h/s iou={iou(rec[1], gt[0]):.2f}")
                print(f"  person {pid} frame {i} stop id {stop_id}: {desc}")
                last = rec[0] if rec else None
    return counts


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[101, 102, 103])
    parser.add_argument("--people", type=int, default=6)
    parser.add_argument("--frames", type=int, default=250)
    parser.add_argument("--stop-fraction", type=float, default=0.5)
    parser.add_argument("--modes", nargs="+", default=["thermal+rgb", "thermal-only"])
    parser.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE")
    parser.add_argument("--verbose", action="store_true")
    args = parser.parse_args(argv)
    config = config_with(args.set)
    totals: dict[str, Counter] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for seed, mode, src, truth, stills in scene_bags(args, Path(tmp)):
            print(f"seed {seed} {mode}")
            frames = recorded_run(src, Path(tmp) / f"run_{seed}_{mode}", config)
            c = classify(truth, frames, stills, args.verbose)
            print(f"  {dict(c)}")
            totals.setdefault(mode, Counter()).update(c)
    for mode, c in totals.items():
        print(f"{mode}: {dict(c)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
