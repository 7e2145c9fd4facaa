"""Where the hand-started tracker fails on the real sequences of the single-target benchmark.

For every real sequence of :func:`bench_single_target.development_set` (or those named with
``--sequences``) it runs our tracker (``MultiObjectTracker``, one track started by hand, the
shipped ``manual_track`` defaults) and OpenCV CSRT (when opencv-contrib is installed) on the
same frames, and prints one row per sequence: both mean centre errors, the **failure frame**
(the first frame whose centre error exceeds one ground-truth box width), the track's state
and score there, the ground truth's motion in that frame (px and box widths), whether the
error ever came back under half a box width afterwards, and the share of frames the track
reported "occluded".  The cause column of docs/failure_analysis.md is read from these
figures and the frames (nothing here decides it)::

    nice -n 10 .venv/bin/python benchmarks/diagnose_single_target.py --sequences Woman

``--separation`` measures instead how well a failure test tells a search that ended on the
person from one that did not (issue #16 item 3): in every frame the track's own search and
two more searches of a copy of its target state, started 1.5 box widths left and right of
the truth (Algorithm 1 only), are labelled on (IoU with the truth >= 0.5) or off (< 0.1),
and for each test the area under the ROC curve of on against off is printed, pooled and per
sequence: the absolute level (the weighted statistic (7)-(8) of exp(-J_i)), the contrast of
the peak to a ring of displaced copies of its layout at several distances (the
peak-to-sidelobe idea of MOSSE, Bolme et al. CVPR 2010:
:func:`mk_tracker.tracking.peak_contrast.kernel_contrasts`), and the
geometric mean of level and contrast per kernel.  (The contrast as the failure test of
hand-started tracks, ``manual_track.failure_test``, lost held out and was deleted; commit
e43c509 has it, docs/benchmark_single_target.md "Findings".)::

    nice -n 10 .venv/bin/python benchmarks/diagnose_single_target.py --separation \
        --sequences 'Woman,TUD-Stadtmitte person 3,TUD-Stadtmitte person 6'
"""
from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

from bench_single_target import (_contrib, _names, _selected, development_set,  # noqa: E402
                                 opencv_tracker_factory, run)
from mk_tracker.tracking.multi_object_tracker import (MultiObjectTracker,  # noqa: E402
                                                      MultiObjectTrackerConfig)
from setting_values import setting_changes  # noqa: E402
from mk_tracker.boxes import iou  # noqa: E402
from mk_tracker.tracking.multi_kernel import (MultiKernelTracker,  # noqa: E402
                                              visibility_similarity)
from mk_tracker.tracking.peak_contrast import kernel_contrasts, ring_costs  # noqa: E402

#: ring distances (box sizes) whose contrast --separation measures
SEPARATION_DISTANCES = (0.5, 0.75, 1.0)
#: starts of the extra searches of --separation, box widths left / right of the truth
SEPARATION_STARTS = (-1.5, 1.5)


def _centre(box) -> np.ndarray:
    return np.array([box[0] + box[2] / 2.0, box[1] + box[3] / 2.0])


def trace(seq, config: MultiObjectTrackerConfig) -> list[tuple]:
    """Per frame after the first: (box, state, score) of the hand-started track."""
    tracker = MultiObjectTracker(config)
    frames = seq.frames()
    first = next(frames)
    tid = tracker.start_track(first, 0.0, seq.init_box)
    tracker.step(first, 0.0)
    out, last = [], (tuple(seq.init_box), "deleted", 0.0)
    for i, frame in enumerate(frames, start=1):
        res = tracker.step(frame, i / seq.fps)
        mine = [t for t in res.tracks if t.id == tid]
        if mine:
            last = (tuple(mine[0].box), mine[0].state, float(mine[0].score))
        else:
            last = (last[0], "deleted", 0.0)
        out.append(last)
    return out


def diagnose(seq, rows: list[tuple]) -> dict:
    errs, widths = [], []
    for (box, _, _), truth in zip(rows, seq.truth[1:]):
        if truth is None:
            errs.append(np.nan)
            widths.append(np.nan)
            continue
        errs.append(float(np.linalg.norm(_centre(box) - _centre(truth))))
        widths.append(float(truth[2]))
    errs, widths = np.array(errs), np.array(widths)
    fail = np.flatnonzero(errs > widths)
    occluded = float(np.mean([r[1] != "confirmed" for r in rows]))
    out = {"err": float(np.nanmean(errs)), "occluded": occluded, "fail": None}
    if fail.size:
        f = int(fail[0])
        truths = seq.truth
        motion = np.nan
        if truths[f] is not None and truths[f + 1] is not None:
            motion = float(np.linalg.norm(_centre(truths[f + 1]) - _centre(truths[f])))
        later = errs[f + 1:] < widths[f + 1:] / 2.0
        back = np.flatnonzero(later)
        first_w = float(seq.truth[0][2])
        out["fail"] = {"frame": f + 2,             # 1-based frame number of the sequence
                       "state": rows[f][1], "score": rows[f][2],
                       "motion_px": motion, "motion_w": motion / widths[f],
                       "scale": widths[f] / first_w,
                       "back": None if not back.size else int(back[0]) + f + 3,
                       "within_half_w_after": float(np.mean(later)) if later.size else 0.0,
                       "state_before": rows[max(0, f - 3)][1]}
    return out


def _auc(on: list[float], off: list[float]) -> float:
    """P(score of an on sample > score of an off sample), ties counting half (Mann-Whitney)."""
    if not on or not off:
        return float("nan")
    a, b = np.asarray(on)[:, None], np.asarray(off)[None, :]
    return float(np.mean((a > b) + 0.5 * (a == b)))


def _scores(refiner: MultiKernelTracker, image, state, res) -> list[float]:
    """[absolute level, contrast at each SEPARATION_DISTANCES] of one search result."""
    x = np.asarray(res.kernel_centres, dtype=np.float64)
    ev = ring_costs(refiner, image, state, x, 1e-6)      # the layout itself (no offset)
    out = [visibility_similarity(res.kernel_similarities, None, "weighted")]
    contrasts = np.zeros(len(res.kernel_similarities))
    for d in SEPARATION_DISTANCES:
        ring = ring_costs(refiner, image, state, x, d)
        contrasts = np.zeros_like(contrasts) if ev is None or ring is None else \
            kernel_contrasts(ev[0], ring)
        out.append(visibility_similarity(contrasts, None, "weighted"))
    # the two together: per kernel sqrt(rho_i c_i) at the widest ring
    both = np.sqrt(np.clip(res.kernel_similarities, 0.0, 1.0) * contrasts)
    out.append(visibility_similarity(both, None, "weighted"))
    return out


def separation(seq, config: MultiObjectTrackerConfig) -> list[tuple[bool, list[float]]]:
    """(on target, scores) of every labelled search of the hand-started track on ``seq``."""
    import copy
    tracker = MultiObjectTracker(config)
    refiner = tracker.manual_refiner
    plain = MultiKernelTracker(replace(refiner.config, multi_start_radius=0.0,
                                       recovery_similarity=0.0))
    samples: list[tuple[bool, list[float]]] = []
    current: dict = {}
    original = refiner.refine

    def recording(image, state, predicted_center=None):
        res = original(image, state, predicted_center=predicted_center)
        if res.reason in ("", "low_similarity") and current.get("truth") is not None:
            current["own"] = (res, state, image)
        return res

    refiner.refine = recording
    frames = seq.frames()
    first = next(frames)
    tracker.start_track(first, 0.0, seq.init_box)
    tracker.step(first, 0.0)
    for i, frame in enumerate(frames, start=1):
        truth = seq.truth[i] if i < len(seq.truth) else None
        current.clear()
        current["truth"] = truth
        tracker.step(frame, i / seq.fps)
        if truth is None or "own" not in current:
            continue
        res, state, image = current["own"]
        found = [(res, state)]
        cx, cy = truth[0] + truth[2] / 2.0, truth[1] + truth[3] / 2.0
        for shift in SEPARATION_STARTS:
            moved = copy.deepcopy(state)
            alt = plain.refine(image, moved, predicted_center=(cx + shift * truth[2], cy))
            if alt.reason in ("", "low_similarity"):
                found.append((alt, moved))
        for r, st in found:
            overlap = iou(r.box, truth)
            if 0.1 <= overlap < 0.5:
                continue
            samples.append((overlap >= 0.5, _scores(refiner, image, st, r)))
    return samples


def separation_main(args, config: MultiObjectTrackerConfig) -> int:
    names = ["level"] + [f"contrast {d:g}" for d in SEPARATION_DISTANCES] + \
        [f"sqrt(rho c) {SEPARATION_DISTANCES[-1]:g}"]
    print("| sequence | on / off searches | " + " | ".join(f"AUC {n}" for n in names) + " |")
    print("|---|---|" + "---|" * len(names))
    pooled: list[tuple[bool, list[float]]] = []
    for clip, seq in development_set():
        if (clip.startswith("generator") and not args.generator) or \
                not _selected(seq.name, _names(args.sequences)):
            continue
        samples = separation(seq, config)
        pooled += samples
        on = [s for o, s in samples if o]
        off = [s for o, s in samples if not o]
        aucs = [_auc([s[j] for s in on], [s[j] for s in off]) for j in range(len(names))]
        print(f"| {seq.name} | {len(on)} / {len(off)} | "
              + " | ".join(f"{a:.3f}" for a in aucs) + " |", flush=True)
    on = [s for o, s in pooled if o]
    off = [s for o, s in pooled if not o]
    aucs = [_auc([s[j] for s in on], [s[j] for s in off]) for j in range(len(names))]
    print(f"| **pooled** | {len(on)} / {len(off)} | "
          + " | ".join(f"{a:.3f}" for a in aucs) + " |")
    for j, n in enumerate(names):
        a, b = np.array([s[j] for s in on]), np.array([s[j] for s in off])
        if a.size and b.size:
            print(f"{n}: on median {np.median(a):.3f} (10% {np.quantile(a, 0.1):.3f}), "
                  f"off median {np.median(b):.3f} (90% {np.quantile(b, 0.9):.3f})")
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sequences", default="", help="substrings of sequence names")
    parser.add_argument("--all", action="store_true",
                        help="also sequences where we beat CSRT")
    parser.add_argument("--set", action="append", default=[],
                        help="a manual_track setting, e.g. --set recovery_growth=0")
    parser.add_argument("--generator", action="store_true",
                        help="also the generator sequences")
    parser.add_argument("--trace", action="store_true",
                        help="print every frame's error, state and score")
    parser.add_argument("--separation", action="store_true",
                        help="AUC of on- against off-target searches per failure test")
    args = parser.parse_args(argv)
    csrt = _contrib("CSRT")
    config = MultiObjectTrackerConfig()
    overrides = setting_changes(args.set)
    config = replace(config, manual_track=replace(config.manual_track, **overrides))
    if args.separation:
        return separation_main(args, config)
    print("| sequence | ours err | CSRT err | failure frame | state (3 frames before) | "
          "score | truth motion px (box widths) | width / first width | back under w/2 at | "
          "frames within w/2 after | occluded share |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for clip, seq in development_set():
        if (clip.startswith("generator") and not args.generator) or not _selected(seq.name, _names(args.sequences)):
            continue
        frames = list(seq.frames())
        seq = replace(seq, frames=lambda: iter(frames))
        rows = trace(seq, config)
        d = diagnose(seq, rows)
        if args.trace:
            for i, ((box, state, score), truth) in enumerate(zip(rows, seq.truth[1:]), 2):
                e = float("nan") if truth is None else \
                    float(np.linalg.norm(_centre(box) - _centre(truth)))
                print(f"  frame {i}: err {e:.1f} {state} {score:.2f} box "
                      f"{' '.join(f'{v:.0f}' for v in box)}")
        c_err = run(seq, opencv_tracker_factory(csrt))[0]["mean_center_error"] \
            if csrt is not None else float("nan")
        if not args.all and d["err"] <= c_err:
            continue
        f = d["fail"]
        if f is None:
            print(f"| {seq.name} | {d['err']:.1f} | {c_err:.1f} | none | | | | | | | "
                  f"{d['occluded']:.2f} |", flush=True)
            continue
        print(f"| {seq.name} | {d['err']:.1f} | {c_err:.1f} | {f['frame']} / {len(seq.truth)} | "
              f"{f['state']} ({f['state_before']}) | {f['score']:.2f} | "
              f"{f['motion_px']:.1f} ({f['motion_w']:.2f}) | {f['scale']:.2f} | "
              f"{f['back'] if f['back'] else 'never'} | {f['within_half_w_after']:.2f} | "
              f"{d['occluded']:.2f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
