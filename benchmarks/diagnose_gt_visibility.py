"""Which people does a ground truth count?  The real TUD clips against the generated
development sequences of bench_multi_object.py, measured without any tracker (issue #16).

Real clips (MOTChallenge ``gt/gt.txt``, read by :func:`mk_tracker.bags.datasets.read_mot_sequence`):
per annotated box its *box visibility*, the share of the box inside the image and not
covered by the annotated boxes nearer to the camera (lower bottom edge;
:mod:`mk_tracker.evaluation.annotation_occlusion`), the runs of frames in which an identity
stays annotated while (almost) fully covered, whether its box is then interpolated (second
differences of the box ~0 px), and the frames in which an identity is missing between its
first and last frame (gaps: a person dropped while passing behind someone).

Generated sequences (crowd-15 and far-7fps of bench_multi_object.py, seed 1): the same box
visibility over the people in the RGB frame, the generator's silhouette
``visible_fraction`` of the people whose box is covered, and, for each ground-truth
convention ``--gt-min-visible V`` of bench_multi_object.py (a person enters when
``visible_fraction >= V``; 1e-6: any visible pixel, the convention until 2026-11-27), the
annotated boxes, the gap frames and the box visibility of the annotated boxes.

The threshold that matches the real convention is the largest V whose generated ground truth
has no more gap frames per annotated box than the real clips (none): a statistic of the
annotations alone, not of any tracking score.

``--coasting NAME=VALUE ...`` adds one section that does run our tracker (at those settings,
as ``benchmarks/diagnose_mot_loss.py --set``) on the development sequences: its reported
coasting boxes (state ``occluded``), matched or not (motmetrics, IoU >= 0.5), split by the
box visibility of the annotated person they overlap most (none: IoU < 0.1 with everyone):
whether the coasting false positives are people the ground truth leaves out or boxes off
people it counts.

    .venv/bin/python benchmarks/diagnose_gt_visibility.py [--data ../shared/data] \
        [--coasting min_detection_score=0.2 lifecycle.min_hits=2 ...]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from mk_tracker.bags.datasets import read_mot_sequence  # noqa: E402
from mk_tracker.evaluation.annotation_occlusion import (frame_visibilities,  # noqa: E402
                                                        identity_gaps)
from mk_tracker.synthetic.presets import crowd_scene, far_view_scene  # noqa: E402

REAL = ("TUD-Campus", "TUD-Stadtmitte")
#: ground-truth conventions of the generated sequences (visible_fraction >= V); 1e-6 is any
#: visible pixel, bench_multi_object's convention until 2026-11-27
CONVENTIONS = (0.0, 1e-6, 0.01, 0.05, 0.1, 0.25, 0.5)
QUANTILES = (0.01, 0.05, 0.1, 0.25, 0.5)
HIDDEN = 0.05   # box visibility below which a box counts as (almost) fully covered


def _quantiles(values) -> str:
    return " / ".join(f"{q:.3f}" for q in np.quantile(np.asarray(values), QUANTILES))


def _shares(values) -> str:
    v = np.asarray(values)
    return " / ".join(f"{(v < t).mean():.1%}" for t in (HIDDEN, 0.25, 0.5))


def _hidden_runs(flags: list[bool]) -> list[int]:
    """Lengths of the runs of True in ``flags``."""
    runs, n = [], 0
    for f in flags:
        if f:
            n += 1
        elif n:
            runs.append(n)
            n = 0
    return runs + ([n] if n else [])


def real_rows(data: Path) -> list[str]:
    lines = ["| clip | boxes | ids | gap frames | box visibility q01 / q05 / q10 / q25 / q50 "
             f"| share < {HIDDEN} / 0.25 / 0.5 | runs covered < {HIDDEN} (frames) "
             "| box 2nd difference covered / visible (px) |",
             "|---|---|---|---|---|---|---|---|"]
    for name in REAL:
        folder = data / "mot" / name
        if not folder.is_dir():
            print(f"{folder} is absent: {name} skipped", file=sys.stderr)
            continue
        seq = read_mot_sequence(folder)
        size = seq.image_size or (640, 480)
        per = [frame_visibilities(f, size) for f in seq.ground_truth]
        vis = [v for f in per for v in f.values()]
        ids = sorted({i for f in seq.ground_truth for i in f})
        runs, d2_hidden, d2_visible = [], [], []
        for i in ids:
            ks = [k for k, f in enumerate(seq.ground_truth) if i in f]
            hidden = [per[k][i] < HIDDEN for k in ks]
            runs += _hidden_runs(hidden)
            if len(ks) < 3:
                continue
            boxes = np.array([seq.ground_truth[k][i] for k in ks])
            d2 = np.abs(np.diff(boxes, 2, axis=0)).sum(axis=1)
            inner = np.array(hidden[1:-1])
            d2_hidden += list(d2[inner])
            d2_visible += list(d2[~inner])
        gaps = identity_gaps(seq.ground_truth)
        lines.append(
            f"| {name} | {len(vis)} | {len(ids)} | {len(gaps)} | {_quantiles(vis)} | "
            f"{_shares(vis)} | {len(runs)} runs, longest {max(runs, default=0)} | "
            f"{np.mean(d2_hidden) if d2_hidden else float('nan'):.2f} / "
            f"{np.mean(d2_visible):.2f} |")
    return lines


def generated_scenes() -> dict:
    """The generated development sequences of bench_multi_object.py (``--seed 1``)."""
    return {"crowd-15": crowd_scene(15, seed=1, frames=300), "far-7fps": far_view_scene(seed=1)}


def generated_rows(scenes: dict) -> list[str]:
    head = ["| sequence | convention | boxes | gap frames | ids with gaps | box visibility "
            f"q01 / q05 / q10 / q25 / q50 | share < {HIDDEN} / 0.25 / 0.5 |",
            "|---|---|---|---|---|---|---|"]
    silhouette = ["| sequence | people in frame | visible_fraction 0 | box visibility "
                  f"< {HIDDEN}: n, their visible_fraction q50 / max | box visibility < 0.25:"
                  " n, q50 / max |", "|---|---|---|---|---|"]
    for name, scene in scenes.items():
        width, height = scene.config.width, scene.config.height
        people = []
        for k in range(len(scene)):
            objs = [o for o in scene.ground_truth(k) if o.kind == "person" and o.in_frame_rgb]
            people.append(objs)
        every = [(o.visible_fraction, v) for objs in people for o, v in zip(
            objs, frame_visibilities({o.id: o.box_rgb for o in objs}, (width, height)).values())]
        fractions = np.array([f for f, _ in every])
        boxes_vis = np.array([v for _, v in every])
        cells = []
        for level in (HIDDEN, 0.25):
            sel = fractions[boxes_vis < level]
            cells.append(f"{len(sel)}, " + (f"{np.median(sel):.3f} / {sel.max():.3f}"
                                            if len(sel) else "-"))
        silhouette.append(f"| {name} | {len(fractions)} | {int((fractions == 0).sum())} | "
                          + " | ".join(cells) + " |")
        for v in CONVENTIONS:
            gt = [{o.id: o.box_rgb for o in objs if o.visible_fraction >= v}
                  for objs in people]
            vis = [x for f in gt for x in frame_visibilities(f, (width, height)).values()]
            gaps = identity_gaps(gt)
            label = "> 0 (until 2026-11-27)" if v == 1e-6 else f">= {v:g}"
            head.append(f"| {name} | {label} | {len(vis)} | {len(gaps)} | "
                        f"{len({g.id for g in gaps})} | {_quantiles(vis)} | {_shares(vis)} |")
    return head + [""] + silhouette


#: box visibility bins of the annotated person under a coasting box
BINS = ((0.0, 0.25), (0.25, 0.75), (0.75, 1.01))


def coasting_rows(data: Path, changes: dict) -> list[str]:
    """Our reported coasting boxes per development sequence, matched / not, by the box
    visibility of the annotated person they overlap most (see the module docstring)."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import bench_multi_object as bench
    import diagnose_mot_loss as loss
    from mk_tracker.parameters import updated
    from mk_tracker.tracking.multi_object_tracker import MultiObjectTrackerConfig

    sequences = {n: bench.tud_frames(data / "mot" / n)[0] for n in REAL
                 if (data / "mot" / n).is_dir()}
    sequences["crowd-15"] = bench.crowd_frames(15, 1, 300, 0.5, 0.1, 0.3, 2.0)[0]
    sequences["far-7fps"] = bench.far_frames(1, 0.5, 0.1, 0.3, 2.0)[0]
    config = updated(MultiObjectTrackerConfig(), changes)
    labels = [f"{a:g}-{min(b, 1):g}" for a, b in BINS]
    lines = ["| sequence | coasting boxes matched / not | not matched, nearest person's box "
             "visibility " + " / ".join(labels) + " / no person (IoU < 0.1) | matched, "
             "person's box visibility " + " / ".join(labels) + " |", "|---|---|---|---|"]
    for name, frames in sequences.items():
        hyp, states = loss.run_ours(config, frames)
        _, match, _ = loss.events(frames, hyp)
        matched = {(f, h): o for (f, o), h in match.items()}
        miss, hit = [0] * (len(BINS) + 1), [0] * len(BINS)
        for k, info in enumerate(states):
            gts = {g.id: g.box for g in frames[k][3]}
            if not gts:
                continue
            vis = frame_visibilities(gts, (frames[k][0].shape[1], frames[k][0].shape[0]))
            for h, v in info.items():
                if not (v[4] and v[0] == "occluded"):
                    continue
                if (k + 1, h) in matched:
                    who = matched[(k + 1, h)]
                    bins = hit
                else:
                    ids = list(gts)
                    ious = loss._iou(v[1], [gts[i] for i in ids])
                    if ious.max() < 0.1:
                        miss[-1] += 1
                        continue
                    who = ids[int(np.argmax(ious))]
                    bins = miss
                bins[next(j for j, (a, b) in enumerate(BINS) if a <= vis[who] < b)] += 1
        lines.append(f"| {name} | {sum(hit)} / {sum(miss)} | "
                     + " / ".join(map(str, miss)) + " | " + " / ".join(map(str, hit)) + " |")
    return lines


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data",
                        help="shared data folder (default ../shared/data)")
    parser.add_argument("--coasting", nargs="*", default=None, metavar="NAME=VALUE",
                        help="also run our tracker with these settings and split its "
                             "coasting boxes by the visibility of the person under them")
    args = parser.parse_args(argv)
    print("Real clips (box visibility: share of an annotated box inside the image and not "
          "covered by nearer annotated boxes):\n")
    print("\n".join(real_rows(args.data)))
    print("\nGenerated sequences, per ground-truth convention (visible_fraction of the "
          "generator):\n")
    print("\n".join(generated_rows(generated_scenes())))
    if args.coasting is not None:
        sys.path.insert(0, str(ROOT / "benchmarks"))
        from setting_values import setting_changes
        print(f"\nOur coasting boxes at {args.coasting or 'the defaults'}:\n")
        print("\n".join(coasting_rows(args.data, setting_changes(args.coasting))))
    return 0


if __name__ == "__main__":
    sys.exit(main())
