"""The leave-one-sequence-out protocol of bench_multi_object.py for our tracker alone, fast
for grids whose extra dimensions are only reporting bounds.

``FrameResult.reported()`` filters the tracks after the tracker has run and feeds nothing
back, so settings that differ only in the reporting bounds (:data:`REPORTING`) track the
same way.  This script runs the tracker once per setting of the other grid parameters and
sequence, keeps every frame's ``FrameResult``, and applies each reporting setting to the
kept results with the real ``FrameResult.reported()``.  The scores, the choices (the same
setting order, so ties break the same way) and the held-out rows are those of
``bench_multi_object.py --grid ...`` (checked: ``--check`` runs one setting both ways);
the peers are not run (their held-out rows are those of docs/benchmark_multi_object.md).

    nice -n 10 .venv/bin/python benchmarks/coast_rule_grid.py \\
        --grid min_reported_coast_match_iou=0,0.5,0.7 --out /tmp/coast_grid.json \\
        --views 'min_reported_coast_match_iou=0'

(At commit ecc72d9 it also replayed the one-level rule ``min_reported_coast_expected_iou``
and its calibration, ``--calibration``; the rule lost held out and was deleted:
docs/benchmark_multi_object.md.)

Single core: BLAS/OpenMP/OpenCV pinned to one thread before numpy is imported.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench_multi_object as bench  # noqa: E402
from mk_tracker.evaluation.metrics import MotRow  # noqa: E402
from mk_tracker.parameters import updated  # noqa: E402
from mk_tracker.tracking.multi_object_tracker import (FrameDetection,  # noqa: E402
                                                      MultiObjectTracker,
                                                      MultiObjectTrackerConfig)
from setting_values import setting_changes, setting_value  # noqa: E402

#: The parameters that only FrameResult.reported() reads.
REPORTING = ("max_reported_coast_time", "max_reported_coast_std",
             "min_reported_coast_match_iou")


def track_sequence(config: MultiObjectTrackerConfig, frames) -> list:
    """Every frame's FrameResult of one tracker run."""
    tracker = MultiObjectTracker(config)
    return [tracker.step(image, stamp, [FrameDetection((x, y, w, h), s, stamp)
                                        for x, y, w, h, s in dets])
            for image, stamp, dets, _ in frames]


def hypothesis(results: list, setting: dict) -> list[MotRow]:
    """The MOTChallenge rows the reporting bounds of ``setting`` give on kept results."""
    bounds = {k: float(v) for k, v in setting.items() if k in REPORTING}
    rows = []
    for k, result in enumerate(results):
        view = dataclasses.replace(result, **bounds)
        rows.extend(MotRow(k + 1, t.id, tuple(t.box)) for t in view.reported())
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data")
    parser.add_argument("--grid", nargs="*", default=[], metavar="NAME=V1,V2",
                        help="replace or add a dimension of bench_multi_object.GRID")
    parser.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE",
                        help="fixed parameters of our tracker (YAML values)")
    parser.add_argument("--gt-min-visible", type=bench._fraction,
                        default=bench.GT_MIN_VISIBLE, metavar="V",
                        help="ground-truth convention of the generated sequences, as "
                             "bench_multi_object.py's option")
    parser.add_argument("--real-motion", action="store_true",
                        help="generated sequences as bench_multi_object.py --real-motion")
    parser.add_argument("--real-detection-noise", action="store_true",
                        help="generated detections as bench_multi_object.py "
                             "--real-detection-noise")
    parser.add_argument("--out", type=Path, default=None, help="JSON of every score")
    parser.add_argument("--views", nargs="*", default=[], metavar="NAME=V1,V2;NAME=V",
                        help="also report the protocol on these sub-grids (settings whose "
                             "values are among those listed)")
    parser.add_argument("--check", action="store_true",
                        help="also run the first setting as bench_multi_object does, and "
                             "fail if its scores differ")
    args = parser.parse_args(argv)
    base = setting_changes(args.set)
    grid = dict(bench.GRID)
    for item in args.grid:
        name, _, values = item.partition("=")
        grid[name] = tuple(setting_value(v) for v in values.split(","))
    settings = bench.grid_settings(grid)
    sequences = _sequences(args.data, args.gt_min_visible,
                           bench.REAL_MOTION if args.real_motion else None,
                           bench.REAL_DETECTION_NOISE if args.real_detection_noise else None)

    runs: dict = {}
    memo: dict = {}
    scores = []
    for i, setting in enumerate(settings):
        tracking = tuple(sorted((k, v) for k, v in setting.items() if k not in REPORTING))
        per = {}
        for name, (frames, _fps) in sequences.items():
            if (tracking, name) not in runs:
                config = updated(MultiObjectTrackerConfig(), {**base, **dict(tracking)})
                runs[(tracking, name)] = track_sequence(config, frames)
            hyp = hypothesis(runs[(tracking, name)], setting)
            key = (name, tuple(hyp))
            if key not in memo:
                memo[key] = bench.score(name, bench.OURS, frames, hyp, with_hota=False)
            per[name] = memo[key]
        scores.append(per)
        print(f"grid {i + 1}/{len(settings)} {setting}: " + "  ".join(
            f"{n} {r['MOTA']:.3f}/{r['IDF1']:.3f}" for n, r in per.items()), flush=True)
    if args.check:
        config = updated(MultiObjectTrackerConfig(), {**base, **settings[0]})
        for name, (frames, _fps) in sequences.items():
            hyp, _, _ = bench.run_tracker(bench.OursAdapter(config), frames)
            direct = bench.score(name, bench.OURS, frames, hyp, with_hota=False)
            if (direct["MOTA"], direct["IDF1"]) != (scores[0][name]["MOTA"],
                                                    scores[0][name]["IDF1"]):
                print(f"check failed on {name}: {direct} vs {scores[0][name]}")
                return 1
        print("check: the replay equals bench_multi_object's run on the first setting")
    names = list(sequences)
    report = {}
    for view in [""] + list(args.views):
        keep = [i for i, st in enumerate(settings) if _in_view(st, view)]
        print(f"== sub-grid {view or 'all'}: {len(keep)} settings")
        report[view or "all"] = _held_out(keep, settings, scores, names, sequences, runs)
    if args.out is not None:
        args.out.write_text(json.dumps({"grid": {k: list(v) for k, v in grid.items()},
                                        "base": base, "held_out": report,
                                        "scores": [{"setting": st, "scores": sc}
                                                   for st, sc in zip(settings, scores)]},
                                       default=float))
    return 0


def _sequences(data: Path, gt_min_visible: float = bench.GT_MIN_VISIBLE,
               motion: dict | None = None, box_error: dict | None = None) -> dict:
    """The development sequences, as bench_multi_object builds them (``--people 15``;
    ``motion``: its ``--real-motion``; ``box_error``: its ``--real-detection-noise``)."""
    sequences = {}
    for name in ("TUD-Campus", "TUD-Stadtmitte"):
        sequences[name] = bench.tud_frames(data / "mot" / name)
    sequences["crowd-15"] = bench.crowd_frames(15, 1, 300, 0.5, 0.1, 0.3, 2.0, gt_min_visible,
                                               motion, box_error)
    sequences["far-7fps"] = bench.far_frames(1, 0.5, 0.1, 0.3, 2.0, gt_min_visible, motion,
                                             box_error)
    return sequences


def _in_view(setting: dict, view: str) -> bool:
    """Whether ``setting`` lies in the sub-grid ``"NAME=V1,V2;NAME=V"`` ("" = all)."""
    for item in filter(None, view.split(";")):
        name, _, values = item.partition("=")
        if setting[name] not in [setting_value(v) for v in values.split(",")]:
            return False
    return True


def _held_out(keep, settings, scores, names, sequences, runs) -> list:
    """The held-out rows (with HOTA) of the protocol restricted to the settings ``keep``
    (their order kept, so ties break as in the full grid's order)."""
    held = []
    for out in names:
        others = [n for n in names if n != out]
        means = [np.mean([scores[i][n]["MOTA"] + scores[i][n]["IDF1"] for n in others])
                 for i in keep]
        best = keep[int(np.argmax(means))]
        tracking = tuple(sorted((k, v) for k, v in settings[best].items()
                                if k not in REPORTING))
        frames = sequences[out][0]
        row = bench.score(out, bench.OURS, frames,
                          hypothesis(runs[(tracking, out)], settings[best]))
        held.append({"sequence": out, "setting": settings[best], **row})
        print(f"held out {out:16s} chosen {settings[best]} MOTA {row['MOTA']:.3f} "
              f"IDF1 {row['IDF1']:.3f} HOTA {row['HOTA']:.3f}", flush=True)
    print("mean held out MOTA {:.3f} IDF1 {:.3f} HOTA {:.3f}".format(
        *(np.mean([r[k] for r in held]) for k in ("MOTA", "IDF1", "HOTA"))))
    every = [np.mean([scores[i][n]["MOTA"] + scores[i][n]["IDF1"] for n in names])
             for i in keep]
    print(f"best over all sequences: {settings[keep[int(np.argmax(every))]]} "
          f"(mean MOTA + IDF1 {max(every):.3f})", flush=True)
    return held


if __name__ == "__main__":
    sys.exit(main())
