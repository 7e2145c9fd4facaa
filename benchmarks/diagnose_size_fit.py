"""Does the learnt person size hold in a scene?  The residual spread of the thermal
detector's height fit over time, on the generator's crowds and on BU-TIV-lab (issue #15).

:class:`mk_tracker.detection.person_size.PersonHeightModel` fits ``h = a + b * y_bottom`` to
the boxes of isolated people.  Under a camera looking at a ground plane (the generator) the
line should explain its samples; in a near indoor scene (BU-TIV-lab) half-body and
whole-body boxes end on the same rows and it should not.  For each detector path that
learns sizes (``split_by_person_size``, ``split_clusters``), the detector (the shipped
``config/detector.yaml`` with that path on and the validity check off) runs over each scene,
and after every frame the model's relative residual spread (weighted residual standard
deviation about the line / mean height) and its samples' total weight are read.  Reported
per scene and path: frames with a fit, the spread's 10th / 50th / 90th percentile and
maximum over the frames with at least ``--min-samples`` of weight, the first frame with
that weight, the spread at the end, the median share of the samples' height variance the
line explains (R^2), and how many frames and full-frame passes had a size the check
accepts (all of them without a check).  Not a test: nothing is asserted.

    nice -n 10 .venv/bin/python benchmarks/diagnose_size_fit.py --out out/size_fit.md

``--set NAME=VALUE`` overrides a detector parameter (YAML value) in every run, e.g.
``--sizes --set size_max_residual=0.25 size_min_samples=10`` (BU-TIV-lab only, with the
check on: the path runs only while the size is accepted).
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_real_thermal import COUNTER_REGION, DEFAULT_CLIP  # noqa: E402

from mk_tracker.bags.bag_io import open_bag  # noqa: E402
from mk_tracker.bags.recording_import import import_recording, open_recording  # noqa: E402
from mk_tracker.frame_processing import build_detector  # noqa: E402
from mk_tracker.messages.image_conversion import image_to_numpy  # noqa: E402
from mk_tracker.parameters import updated  # noqa: E402
from mk_tracker.synthetic.scene_bag import build_preset  # noqa: E402
from mk_tracker.tools.pipeline_config import load_pipeline_config  # noqa: E402
from setting_values import setting_changes  # noqa: E402

PATHS = {"size split": {"split_by_person_size": True},
         "cluster split": {"split_clusters": True}}


def trace(frames, detector, min_samples: float) -> dict:
    """Run ``detector`` over ``frames`` (iterable of ``(image, stamp, encoding)``); the
    spread figures of its height model."""
    spreads, explained, first, last = [], [], None, math.nan
    accepted, passes, passes_accepted = 0, 0, 0
    for k, (image, stamp, encoding) in enumerate(frames):
        detector.process(image, stamp, encoding=encoding)
        model = detector.heights
        accepted += model.valid()
        if detector.last_mode in ("startup", "reconfiguration"):
            passes += 1
            passes_accepted += model.valid()
        spread = model.relative_residual()
        if spread is None:
            continue
        last = spread
        if model.samples >= min_samples:
            first = k if first is None else first
            spreads.append(spread)
            explained.append(model.explained())
    s = np.asarray(spreads)
    pct = np.percentile(s, [10, 50, 90]) if s.size else [math.nan] * 3
    return {"frames": len(s), "first": first, "p10": pct[0], "p50": pct[1], "p90": pct[2],
            "max": float(s.max()) if s.size else math.nan, "end": last,
            "r2": float(np.median(explained)) if explained else math.nan,
            "accepted": accepted, "passes": f"{passes_accepted} / {passes}"}


def scene_frames(scene):
    for i in range(len(scene)):
        fr = scene.frame(i)
        yield fr.thermal, fr.stamp, None


def bag_frames(bag: Path):
    with open_bag(bag) as reader:
        for m in reader.messages(["/thermal/image_raw"]):
            msg = reader.deserialize(m)
            yield image_to_numpy(msg), m.timestamp_ns * 1e-9, msg.encoding


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--people", type=int, nargs="+", default=[3, 8, 15])
    parser.add_argument("--sizes", nargs="*", default=["320x240", "640x480"])
    parser.add_argument("--seeds", type=int, nargs="+", default=[101, 102, 103])
    parser.add_argument("--frames", type=int, default=150)
    parser.add_argument("--min-samples", type=float, default=10.0,
                        help="figures over the frames whose model has this much weight")
    parser.add_argument("--clip", type=Path, default=DEFAULT_CLIP)
    parser.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args(argv)
    cfg = load_pipeline_config()
    base = replace(cfg.detector, size_max_residual=100.0, size_min_samples=2.5)
    base = updated(base, setting_changes(args.set))
    rows = []

    def run(label: str, frames_of, regions=()) -> None:
        for path, change in PATHS.items():
            det = build_detector("kernel_covariance", updated(base, change), cfg.threshold,
                                 regions)
            f = trace(frames_of(), det, args.min_samples)
            rows.append((label, path, f))
            print(label, path, {k: round(v, 3) if isinstance(v, float) else v
                                for k, v in f.items()}, flush=True)

    for size in args.sizes:
        width, height = (int(v) for v in size.split("x"))
        for people in args.people:
            for seed in args.seeds:
                scene = build_preset("crowd", seed=seed, people=people, frames=args.frames,
                                     width=width, height=height)
                run(f"crowd {size}, {people} people, seed {seed}",
                    lambda scene=scene: scene_frames(scene))
    if args.clip.exists():
        with tempfile.TemporaryDirectory() as tmp:
            bag = Path(tmp) / "bag"
            import_recording(open_recording(args.clip, None), bag, thermal=True)
            run("BU-TIV-lab, counter masked", lambda: bag_frames(bag), COUNTER_REGION)
    else:
        print(f"{args.clip} not found: BU-TIV-lab left out", file=sys.stderr)
    lines = ["| scene | path | frames with >= %g samples | first such frame | spread p10 | "
             "p50 | p90 | max | at the end | explained (R^2) p50 | frames with an accepted size | "
             "full passes with one |" % args.min_samples,
             "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for label, path, f in rows:
        lines.append(f"| {label} | {path} | {f['frames']} | {f['first']} | {f['p10']:.3f} | "
                     f"{f['p50']:.3f} | {f['p90']:.3f} | {f['max']:.3f} | {f['end']:.3f} | "
                     f"{f['r2']:.2f} | {f['accepted']} | {f['passes']} |")
    table = "\n".join(lines)
    print(table)
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(table + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
