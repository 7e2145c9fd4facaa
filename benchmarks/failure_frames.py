"""Failure analysis (issue #16 item 4): where our trackers still fail, counted, with pictures.

Multi-object: our tracker with the shipped defaults (``MultiObjectTrackerConfig()``) on the
development sequences, fed exactly as ``benchmarks/bench_multi_object.py`` feeds them (its
loading functions are imported: TUD-Campus / TUD-Stadtmitte public detections, the generator
scenes ``crowd-15`` and ``far-7fps`` with detections from the ground truth).  Every frame is
scored with motmetrics (IoU >= 0.5, :func:`mk_tracker.evaluation.metrics.mot_accumulator`)
and the events are grouped:

* **ID switches**: whether the person was within half a box width of another person (centre
  distance) in the frames just before, whether the person had been unmatched just before
  (an id reborn after a gap), and whether the old id went on with another person;
* **long misses**: runs of at least ``--long`` seconds in which a person has no reported box;
  per missed frame, whether a detection of that person existed (IoU >= 0.5: the tracker
  dropped it) and whether another person covered more than 30% of the person's box;
* **persistent false positives**: runs of at least ``--long`` seconds of one reported id
  matching nobody; per frame, whether the box lies on a person matched by another id
  (a duplicate), near a person (IoU 0.1-0.5: a drifted box) or on no person.

Single target: the hand-started tracker (``bench_single_target.py``'s
``full_tracker_factory``, its sequences and its per-clip held-out settings) on OTB Woman and
TUD-Stadtmitte person 3, the worst clips of ``docs/benchmark_single_target.md``.

For each sequence the failure that costs the most MOTA (for single target: the loss of the
person) is shown on three frames, drawn with :mod:`mk_tracker.drawing.debug_image` (ground
truth thin white, the person of the failure in thick white; our boxes in their id colour),
downscaled to 320 px high, into one strip per sequence in ``--images``.  The figures are
printed as markdown; docs/failure_analysis.md is written by hand from them.

    nice -n 10 .venv/bin/python benchmarks/failure_frames.py > /tmp/failure_frames.txt
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench_multi_object as bmo  # noqa: E402
import bench_single_target as bst  # noqa: E402
from mk_tracker.boxes import iou_matrix  # noqa: E402
from mk_tracker.drawing.debug_image import (TrackDrawing, draw_detections,  # noqa: E402
                                            draw_text_lines, draw_tracks)
from mk_tracker.evaluation.metrics import (center_errors, mot_accumulator,  # noqa: E402
                                           single_target_metrics)
from mk_tracker.tracking.multi_object_tracker import MultiObjectTrackerConfig  # noqa: E402

GT_COLOR = (255, 255, 255)
PANEL_HEIGHT = 320
MAX_BYTES = 250_000

#: (clip, held-out setting) of each single-target sequence (docs/benchmark_single_target.md,
#: "Setting chosen per held-out clip"); the shipped defaults are run as well
SINGLE_TARGET = {
    "OTB Woman": ("OTB Woman", {"max_coast_position_std": 0.0}),
    "TUD-Stadtmitte person 3": ("TUD-Stadtmitte", {}),
}


# ------------------------------------------------------------------------------------------
# helpers

def _centre(box) -> np.ndarray:
    x, y, w, h = box
    return np.array([x + w / 2.0, y + h / 2.0])


def _runs(frames: list[int]) -> list[list[int]]:
    """Consecutive runs of sorted frame numbers."""
    out: list[list[int]] = []
    for f in sorted(frames):
        if out and f == out[-1][-1] + 1:
            out[-1].append(f)
        else:
            out.append([f])
    return out


def _covered(box, others) -> float:
    """Largest share of ``box``'s area covered by one box of ``others``."""
    x, y, w, h = box
    best = 0.0
    for ox, oy, ow, oh in others:
        iw = max(0.0, min(x + w, ox + ow) - max(x, ox))
        ih = max(0.0, min(y + h, oy + oh) - max(y, oy))
        best = max(best, iw * ih / max(w * h, 1e-9))
    return best


def _best_iou(box, others) -> float:
    if not others:
        return 0.0
    return float(iou_matrix(np.array([box], float), np.array(others, float)).max())


# ------------------------------------------------------------------------------------------
# multi-object

def analyse_multi(name, frames, fps, long_s):
    """Runs our tracker at the shipped defaults on ``frames`` (bench_multi_object's format)
    and groups the per-frame motmetrics events.  Returns a dict of counts and examples."""
    hyp, _, _ = bmo.run_tracker(bmo.OursAdapter(MultiObjectTrackerConfig()), frames)
    gt_rows = [r for _, _, _, g in frames for r in g]
    summary = bmo.score(name, bmo.OURS, frames, hyp, with_hota=False)
    acc = mot_accumulator(gt_rows, hyp)
    ev = acc.mot_events.reset_index()
    gt_at = {k + 1: {r.id: r.box for r in g} for k, (_, _, _, g) in enumerate(frames)}
    hyp_at: dict[int, dict] = {}
    for r in hyp:
        hyp_at.setdefault(r.frame, {})[r.id] = r.box
    det_at = {k + 1: [d[:4] for d in dets] for k, (_, _, dets, _) in enumerate(frames)}
    long_n = max(3, int(round(long_s * fps)))

    # who carries which person in every frame
    match = {}                                     # (frame, oid) -> hid
    for _, e in ev[ev.Type.isin(["MATCH", "SWITCH", "TRANSFER", "ASCEND", "MIGRATE"])].iterrows():
        match[(int(e.FrameId), int(e.OId))] = int(e.HId)
    carried = {}                                   # (frame, hid) -> oid
    for (f, o), h in match.items():
        carried[(f, h)] = o

    switches = []
    for _, e in ev[ev.Type == "SWITCH"].iterrows():
        f, o, h = int(e.FrameId), int(e.OId), int(e.HId)
        prev = [g for g in range(f - 1, 0, -1) if (g, o) in match]
        last = prev[0] if prev else None
        old = match[(last, o)] if last else None
        gap = f - last - 1 if last else None
        box = gt_at[f][o]
        near = min((np.linalg.norm(_centre(box) - _centre(b)) / box[2]
                    for g in range(max(1, f - 5), f + 1)
                    for oid, b in gt_at.get(g, {}).items() if oid != o), default=np.inf)
        old_on_other = old is not None and any(
            carried.get((g, old), o) != o for g in range(f - 5, f + 6))
        switches.append(dict(frame=f, oid=o, new=h, old=old, gap=gap, near=float(near),
                             old_on_other=old_on_other))

    misses = ev[ev.Type == "MISS"]
    miss_frames: dict[int, list[int]] = {}
    for _, e in misses.iterrows():
        miss_frames.setdefault(int(e.OId), []).append(int(e.FrameId))
    long_misses = []
    miss_detected = miss_covered = 0
    miss_kind = {"off": 0, "neighbour": 0, "unreported": 0, "undetected": 0}
    life = {}                                      # gt id -> (first frame, last frame)
    for f, boxes in gt_at.items():
        for o in boxes:
            a, b = life.get(o, (f, f))
            life[o] = (min(a, f), max(b, f))
    for o, fs in miss_frames.items():
        for f in fs:
            box = gt_at[f][o]
            det = _best_iou(box, det_at[f]) >= 0.5
            miss_detected += det
            miss_covered += _covered(box, [b for oid, b in gt_at[f].items() if oid != o]) > 0.3
            near = {h: _best_iou(box, [b]) for h, b in hyp_at.get(f, {}).items()}
            top = max(near, key=near.get) if near else None
            if top is not None and near[top] >= 0.1:
                miss_kind["neighbour" if (f, top) in carried else "off"] += 1
            else:
                miss_kind["unreported" if det else "undetected"] += 1
        for run in _runs(fs):
            if len(run) < long_n:
                continue
            det = sum(_best_iou(gt_at[f][o], det_at[f]) >= 0.5 for f in run)
            cov = sum(_covered(gt_at[f][o], [b for oid, b in gt_at[f].items() if oid != o])
                      > 0.3 for f in run)
            off = sum(_best_iou(gt_at[f][o], list(hyp_at.get(f, {}).values())) >= 0.1
                      for f in run)
            where = ("entry" if run[0] == life[o][0] else
                     "exit" if run[-1] == life[o][1] else "middle")
            long_misses.append(dict(oid=o, start=run[0], end=run[-1], n=len(run),
                                    detected=det, covered=cov, off=off, where=where))

    fps_ = ev[ev.Type == "FP"]
    fp_frames: dict[int, list[int]] = {}
    for _, e in fps_.iterrows():
        fp_frames.setdefault(int(e.HId), []).append(int(e.FrameId))
    fp_kind = {"duplicate": 0, "off a missed person": 0, "near a matched person": 0,
               "on no person": 0}
    for h, fs in fp_frames.items():
        for f in fs:
            box = hyp_at[f][h]
            ious = {oid: _best_iou(box, [b]) for oid, b in gt_at[f].items()}
            top = max(ious, key=ious.get) if ious else None
            if top is None or ious[top] < 0.1:
                fp_kind["on no person"] += 1
            elif (f, top) not in match:
                fp_kind["off a missed person"] += 1
            elif ious[top] >= 0.5:
                fp_kind["duplicate"] += 1
            else:
                fp_kind["near a matched person"] += 1
    long_fps = []
    for h, fs in fp_frames.items():
        for run in _runs(fs):
            if len(run) < long_n:
                continue
            dup = drift = nowhere = detected = 0
            for f in run:
                box = hyp_at[f][h]
                ious = {oid: _best_iou(box, [b]) for oid, b in gt_at[f].items()}
                top = max(ious, key=ious.get) if ious else None
                if top is not None and ious[top] >= 0.5 and (f, top) in match:
                    dup += 1
                elif top is not None and ious[top] >= 0.1:
                    drift += 1
                else:
                    nowhere += 1
                detected += _best_iou(box, det_at[f]) >= 0.5
            long_fps.append(dict(hid=h, start=run[0], end=run[-1], n=len(run), duplicate=dup,
                                 drifted=drift, nowhere=nowhere, detected=detected))
    return dict(name=name, fps=fps, frames=frames, gt_at=gt_at, hyp_at=hyp_at,
                summary=summary, n_gt=len(gt_rows), n_miss=len(misses), n_fp=len(fps_),
                miss_kind=miss_kind, fp_kind=fp_kind, miss_detected=miss_detected, miss_covered=miss_covered, long_n=long_n,
                switches=switches, long_misses=long_misses, long_fps=long_fps)


def dominant(a) -> str:
    """The failure kind that costs the most MOTA: ID switches, frames of long misses or
    frames of persistent false positives (each such event costs 1 / number of gt boxes)."""
    costs = {"switch": len(a["switches"]),
             "miss": sum(m["n"] for m in a["long_misses"]),
             "fp": sum(p["n"] for p in a["long_fps"])}
    return max(costs, key=costs.get)


def pick_multi(a, kind: str, count: int = 3) -> list[tuple[int, int, str]]:
    """``(frame, gt id to emphasise or -1, caption)`` of up to ``count`` frames showing
    ``kind``: different switches, or the middle of the longest runs."""
    out = []
    if kind == "switch":
        chosen = sorted(a["switches"], key=lambda s: s["near"])
        used: list[int] = []
        for s in chosen:
            if any(abs(s["frame"] - u) < 3 for u in used):
                continue
            used.append(s["frame"])
            out.append((s["frame"], s["oid"],
                        f"gt {s['oid']}: #{s['old']} -> #{s['new']}"))
            if len(out) == count:
                break
    elif kind == "miss":
        for m in sorted(a["long_misses"], key=lambda m: -m["n"])[:count]:
            f = (m["start"] + m["end"]) // 2
            out.append((f, m["oid"], f"gt {m['oid']} missed f{m['start']}-{m['end']}"))
    else:
        for p in sorted(a["long_fps"], key=lambda p: -p["n"])[:count]:
            f = (p["start"] + p["end"]) // 2
            out.append((f, -1, f"#{p['hid']} false f{p['start']}-{p['end']}"))
    return sorted(out)


def panel(image, gt_boxes: dict, emphasise, tracks: list[TrackDrawing], lines: list[str]):
    """One downscaled frame: ground truth white (thin; the person of the failure thick),
    our tracks in their colours, a caption."""
    scale = PANEL_HEIGHT / image.shape[0]
    small = cv2.resize(image, (int(round(image.shape[1] * scale)), PANEL_HEIGHT),
                       interpolation=cv2.INTER_AREA)

    def sc(b):
        return tuple(float(v) * scale for v in b)
    canvas = draw_detections(small, [sc(b) for k, b in gt_boxes.items() if k != emphasise],
                             color=GT_COLOR, thickness=1)
    if emphasise in gt_boxes:
        canvas = draw_detections(canvas, [sc(gt_boxes[emphasise])], color=GT_COLOR,
                                 thickness=3)
    canvas = draw_tracks(canvas, [replace(t, box=sc(t.box)) for t in tracks], thickness=2)
    return draw_text_lines(canvas, lines)


def write_strip(panels, path: Path) -> Path:
    """Panels side by side (2 px gap) as PNG, or JPEG quality 80 if the PNG is too big."""
    gap = np.zeros((PANEL_HEIGHT, 2, 3), np.uint8)
    parts = []
    for p in panels:
        parts += [p, gap]
    strip = np.hstack(parts[:-1])
    path.parent.mkdir(parents=True, exist_ok=True)
    ok, png = cv2.imencode(".png", strip, [cv2.IMWRITE_PNG_COMPRESSION, 9])
    if ok and len(png) <= MAX_BYTES:
        path = path.with_suffix(".png")
        path.write_bytes(png.tobytes())
    else:
        path = path.with_suffix(".jpg")
        cv2.imwrite(str(path), strip, [cv2.IMWRITE_JPEG_QUALITY, 80])
    for other in (".png", ".jpg"):
        stale = path.with_suffix(other)
        if other != path.suffix and stale.exists():
            stale.unlink()
    return path


def report_multi(a, kind, picks, image_path) -> list[str]:
    s = a["summary"]
    sw = a["switches"]
    lines = [f"### {a['name']} (shipped defaults)", "",
             f"MOTA {s['MOTA']:.3f}, IDF1 {s['IDF1']:.3f}; {a['n_gt']} gt boxes, "
             f"{a['n_miss']} misses, {a['n_fp']} false positives, {len(sw)} ID switches; "
             f"long = at least {a['long_n']} frames.", "",
             f"* misses: {a['miss_detected']} of {a['n_miss']} with a detection of the person "
             f"(IoU >= 0.5) that frame; {a['miss_covered']} of {a['n_miss']} with > 30% of "
             "the box covered by another person; nearest box of ours (IoU 0.1-0.5) on a "
             f"neighbour {a['miss_kind']['neighbour']}, "
             f"unmatched (off the person) {a['miss_kind']['off']}, none near although detected "
             f"{a['miss_kind']['unreported']}, none near and not detected "
             f"{a['miss_kind']['undetected']}",
             "* false positives: " + ", ".join(f"{k} {v}" for k, v in a["fp_kind"].items())]
    lm = a["long_misses"]
    lines.append(f"* long misses: {len(lm)} runs, {sum(m['n'] for m in lm)} frames; "
                 f"detected in {sum(m['detected'] for m in lm)}, covered in "
                 f"{sum(m['covered'] for m in lm)}: " + ", ".join(
                     f"gt {m['oid']} f{m['start']}-{m['end']} {m['where']} (det "
                     f"{m['detected']}, cov {m['covered']}, our box off {m['off']})"
                     for m in sorted(lm, key=lambda m: -m["n"])[:8]))
    lines.append("  long misses at entry / exit / middle of a person's presence: " + " / ".join(
        str(sum(m["n"] for m in lm if m["where"] == w)) + " frames"
        for w in ("entry", "exit", "middle")))
    lf = a["long_fps"]
    lines.append(f"* persistent false positives: {len(lf)} runs, {sum(p['n'] for p in lf)} "
                 f"frames; duplicate {sum(p['duplicate'] for p in lf)}, drifted "
                 f"{sum(p['drifted'] for p in lf)}, on no person "
                 f"{sum(p['nowhere'] for p in lf)}; with a detection under the box "
                 f"{sum(p['detected'] for p in lf)}: " + ", ".join(
                     f"#{p['hid']} f{p['start']}-{p['end']}"
                     for p in sorted(lf, key=lambda p: -p["n"])[:6]))
    near = sum(x["near"] < 0.5 for x in sw)
    gap = sum((x["gap"] or 0) >= 2 for x in sw)
    swap = sum(x["old_on_other"] for x in sw)
    lines.append(f"* ID switches: {near} of {len(sw)} within 0.5 box widths of another "
                 f"person (f-5..f), {gap} after >= 2 unmatched frames, {swap} with the old id "
                 "on another person within 5 frames: " + ", ".join(
                     f"f{x['frame']} gt {x['oid']} #{x['old']}->#{x['new']} "
                     f"(near {x['near']:.2f}, gap {x['gap']})" for x in sw))
    lines += [f"* dominant: {kind}; frames " + ", ".join(str(f) for f, _, _ in picks)
              + f"; picture `{image_path}`", ""]
    return lines


def multi_object(args) -> list[str]:
    seqs = {}
    for name in ("TUD-Campus", "TUD-Stadtmitte"):
        folder = args.data / "mot" / name
        if folder.is_dir():
            seqs[name] = bmo.tud_frames(folder)
    seqs["crowd-15"] = bmo.crowd_frames(15, 1, 300, 0.5, 0.1, 0.3, 2.0)
    seqs["far-7fps"] = bmo.far_frames(1, 0.5, 0.1, 0.3, 2.0)
    out = []
    for name, (frames, fps) in seqs.items():
        a = analyse_multi(name, frames, fps, args.long)
        kind = dominant(a)
        picks = pick_multi(a, kind)
        panels = []
        for f, oid, caption in picks:
            image = frames[f - 1][0]
            tracks = [TrackDrawing(b, h) for h, b in a["hyp_at"].get(f, {}).items()]
            panels.append(panel(image, a["gt_at"][f], oid, tracks, [f"{name} f{f}", caption]))
        path = write_strip(panels, args.images / f"failure_{name.lower().replace('-', '_')}")
        print(f"{name}: wrote {path} ({path.stat().st_size} bytes)", file=sys.stderr)
        out += report_multi(a, kind, picks, path.relative_to(ROOT))
    return out


# ------------------------------------------------------------------------------------------
# single target

def run_single(seq, config):
    """The hand-started tracker on ``seq`` (bench_single_target's factory): per frame the
    box and whether the tracker said it does not see the person."""
    init, update = bst.full_tracker_factory(config)(seq)
    frames = seq.frames()
    images = [next(frames)]
    init(images[0], seq.init_box)
    steps = [bst.Step(seq.init_box)]
    for frame in frames:
        images.append(frame)
        steps.append(update(frame))
    return images, steps


def single_target(args) -> list[str]:
    out = []
    by_name = {s.name: s for s in bst.otb_sequence("Woman")
               + bst.mot_person_sequences("TUD-Stadtmitte") if s.name in SINGLE_TARGET}
    for name, (_clip, fold) in SINGLE_TARGET.items():
        seq = by_name.get(name)
        if seq is None:
            print(f"{name}: data absent, skipped", file=sys.stderr)
            continue
        runs = {"held-out": bst.manual_config(fold)} if fold else {}
        runs["shipped"] = MultiObjectTrackerConfig()
        results = {}
        for label, config in runs.items():
            images, steps = run_single(seq, config)
            boxes = [s.box for s in steps]
            m = single_target_metrics(boxes[1:], seq.truth[1:])
            err = center_errors(boxes, seq.truth)
            results[label] = (images, steps, m, err)
        label = next(iter(runs))               # the reported (held-out) run picks the frames
        images, steps, m, err = results[label]
        lost = next((k for k in range(1, len(err)) if np.isfinite(err[k]) and err[k] > 50
                     and all(not np.isfinite(e) or e > 50 for e in err[k:k + 5])), None)
        unseen = [k for k in range(1, len(steps)) if steps[k].said_hidden]
        first_unseen = unseen[0] if unseen else None
        lines = [f"### {name} (single target; lost frame and error of the `{label}` run)", ""]
        for lab, (_, st, mm, e) in results.items():
            lines.append(f"* {lab}: mean centre error {mm['mean_center_error']:.1f} px, "
                         f"P@20 {mm['precision_at_20px']:.2f}, AUC {mm['success_auc']:.2f}; "
                         f"said unseen in {sum(s.said_hidden for s in st[1:])} of "
                         f"{len(st) - 1} frames")
        lines.append(f"* drawn run: first unseen frame "
                     f"{None if first_unseen is None else first_unseen + 1}, lost (error > "
                     f"50 px for 5 frames) from frame {None if lost is None else lost + 1}; "
                     f"frames with error <= 20 px: {int(np.sum(err[1:] <= 20))}")
        # the first frame it says it does not see her, the loss, and half-way to the end
        start = lost if first_unseen is None or lost is None else min(first_unseen, lost)
        if lost is None or start is None:
            picks = [len(images) // 3, 2 * len(images) // 3, len(images) - 1]
        else:
            picks = sorted({start, min(len(images) - 1, lost + 2),
                            min(len(images) - 1, lost + (len(images) - lost) // 2)})
        panels = []
        for k in picks:
            truth = seq.truth[k]
            gt = {1: truth} if truth is not None else {}
            tracks = [TrackDrawing(r[1][k].box, lab, "unseen" if r[1][k].said_hidden else "")
                      for lab, r in results.items()]
            e = err[k]
            panels.append(panel(images[k], gt, 1, tracks,
                                [f"{name} frame {k + 1}",
                                 f"error {e:.0f} px" if np.isfinite(e) else "no truth"]))
        path = write_strip(panels, args.images /
                           f"failure_{name.lower().replace('-', '_').replace(' ', '_')}")
        print(f"{name}: wrote {path} ({path.stat().st_size} bytes)", file=sys.stderr)
        lines += [f"* frames {', '.join(str(k + 1) for k in picks)}; picture "
                  f"`{path.relative_to(ROOT)}`", ""]
        out += lines
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data")
    parser.add_argument("--images", type=Path, default=ROOT / "docs" / "images")
    parser.add_argument("--long", type=float, default=0.4,
                        help="seconds for a miss or false-positive run to count as long")
    parser.add_argument("--only", choices=("multi", "single"), default=None)
    args = parser.parse_args(argv)
    cv2.setNumThreads(1)
    lines = []
    if args.only != "single":
        lines += multi_object(args)
    if args.only != "multi":
        lines += single_target(args)
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
