"""Where our multi-object MOTA goes, next to SORT's (issue #16 item 2).

MOTA = 1 - (FN + FP + IDSW) / GT.  This script runs our tracker (the shipped defaults, or
``--set name=value`` overrides), the SORT-style peer and (with the peers' requirements
installed) ByteTrack on the same detections as
``benchmarks/bench_multi_object.py`` (its loading functions), scores every frame with
motmetrics (IoU >= 0.5, ``acc.mot_events``) and splits each of our errors by its cause,
read from the tracker's own state in that frame:

False positives (a reported box of ours matched to nobody):

* ``coasting``: the track had no detection this frame (state ``occluded``, reported for
  ``max_reported_coast_time``) -- split into ``person gone`` (IoU < 0.1 with every person)
  and ``off a person`` (IoU 0.1-0.5);
* ``refinement only``: ``confirmed`` without a detection (the multiple-kernel refinement
  saw it), same split;
* ``detected, box off, detection on``: the track got a detection this frame that matches
  a missed person at IoU >= 0.5, but the reported (Kalman-filtered) box does not;
* ``detected, detection off too``: the detection itself overlaps the person by < 0.5;
* ``detected, on a false detection``: the detection lies on no person (IoU < 0.1);
* ``duplicate``: IoU >= 0.5 with a person matched by another id.

Misses (a person matched to no box of ours):

* with a detection of that person (IoU >= 0.5) that frame: ``our box off`` (a reported box
  of ours at IoU 0.1-0.5, counted again among the false positives), ``tentative`` (our
  track on it is not confirmed yet), ``covered by a neighbour's box`` (the nearest reported
  box is matched to another person), ``detection unused`` (none of the above);
* without one: ``coast dropped, would match`` (a live track of ours, not reported -- coasting
  beyond ``max_reported_coast_time`` or lost -- has a box at IoU >= 0.5), ``coast dropped,
  off`` (such a box at 0.1-0.5), ``neighbour's box``, ``nothing`` (no box near).

Every reported box is also counted as matched / unmatched by its kind (detected, group
member, refinement only, coasting by the std of its centre per box side, the quantity of
``max_reported_coast_std``), which says which kind of box is worth reporting at all: an
unmatched box costs one false positive, a matched one saves one miss.

ID switches are split by whether the person was matched in the frame before (a hand-over
between neighbours) or came back after a gap, and by what the new id was the frame before
(a lost track re-acquiring, a new track, another person's track, an unmatched live
track).  The peers' FP / FN / IDSW are split only by "a detection of the person existed".

    nice -n 10 .venv/bin/python benchmarks/diagnose_mot_loss.py [--sequences TUD-Campus ...] \
        [--set lifecycle.min_hits=2 ...]

``--detections background`` replaces each frame's detections by those of the project's
background-subtraction detector (shipped defaults, run once over the clip at the clip's
stamps): the RGB-only chain of ``bench_background_detector.py`` (issue #13), whose chain
``mk_tracker process --detections background`` runs the same detector and tracker.

``--background-benchmark`` runs the six sequences of ``bench_background_detector.py`` (the
TUD clips and the generated crowd-3 and static-camera scenes) on that detector's boxes, as
``background_tracker_profile.py`` does.  Each sequence ends with the errors against SORT
person by person: people SORT matched and we missed, by our cause, and our false positives
beyond SORT's in the same frame.

A real clip at a lower frame rate is named ``CLIP/STEP+OFFSET``: ``TUD-Stadtmitte/4+2`` keeps
every 4th frame from frame 2 (0-based) at 25 / 4 = 6.25 fps, the copy of
``bench_multi_object.py --low-fps-checks`` (``tud_frames(folder, step, offset)``).

A thermal -> RGB crowd scene of ``benchmarks/bench_groups.py`` is named
``groups-PEOPLE-SEED-WxH`` (``groups-8-101-640x480``): the crowd preset, the thermal detector
(``config/detector.yaml`` with ``--set-detector`` overrides, e.g.
``split_by_person_size=true``) run over its thermal frames, its boxes mapped into the RGB
image by the scene's homography (what the tracker does with thermal-plane detections), the
tracker configured by ``config/tracker.yaml`` (+ ``--set``) and scored, as the pipeline is,
against every person at all visible in the RGB image (:func:`groups_frames`).  Its MOTA is
the ``bench_groups.py`` row's.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
from collections import Counter  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench_multi_object as bmo  # noqa: E402
from mk_tracker.boxes import iou_matrix  # noqa: E402
from mk_tracker.evaluation.metrics import MotRow, mot_accumulator  # noqa: E402
from mk_tracker.parameters import updated  # noqa: E402
from mk_tracker.tracking.multi_object_tracker import (FrameDetection,  # noqa: E402
                                                      MultiObjectTracker,
                                                      MultiObjectTrackerConfig,
                                                      coast_position_std)
from setting_values import setting_changes  # noqa: E402

MATCHED = ["MATCH", "SWITCH", "TRANSFER", "ASCEND", "MIGRATE"]


def _iou(box, others) -> np.ndarray:
    if not len(others):
        return np.zeros(0)
    return iou_matrix(np.array([box], float), np.array(others, float))[0]


def run_ours(config, frames):
    """Our tracker over ``frames``; returns the reported rows and, per frame, every live
    track as ``{id: (state, box, detected this frame, detection box or None, reported)}``."""
    tracker = MultiObjectTracker(config)
    hyp, states = [], []
    seen_det: dict[int, int] = {}
    for k, (image, stamp, dets, _) in enumerate(frames):
        res = tracker.step(image, stamp, [FrameDetection(tuple(d[:4]), d[4], stamp)
                                          for d in dets])
        reported = {t.id for t in res.reported()}
        by_id = {t.id: t for t in tracker.tracks}
        info = {}
        for t in res.tracks:
            tr = by_id.get(t.id)
            detected = t.time_since_detection == 0.0 and t.hits > 0
            det_box = None
            if detected and tr is not None and id(tr.detected_box) != seen_det.get(t.id):
                det_box = tuple(float(v) for v in tr.detected_box)   # not a group member
            if tr is not None:
                seen_det[t.id] = id(tr.detected_box)
            info[t.id] = (t.state, t.box, detected, det_box, t.id in reported,
                          coast_position_std(t), t.time_since_detection)
            if t.id in reported:
                hyp.append(MotRow(k + 1, t.id, tuple(t.box)))
        states.append(info)
    return hyp, states


def events(frames, hyp):
    gt_rows = [r for _, _, _, g in frames for r in g]
    ev = mot_accumulator(gt_rows, hyp).mot_events.reset_index()
    match = {(int(e.FrameId), int(e.OId)): int(e.HId)
             for _, e in ev[ev.Type.isin(MATCHED)].iterrows()}
    return ev, match, len(gt_rows)


def diagnose_ours(frames, hyp, states):
    ev, match, n_gt = events(frames, hyp)
    carried = {(f, h) for (f, _), h in match.items()}
    fp, fn, sw = Counter(), Counter(), Counter()
    causes: dict = {}       # ("FP", frame, hypothesis id) / ("FN", frame, person id) -> cause
    for _, e in ev[ev.Type == "FP"].iterrows():
        f, h = int(e.FrameId), int(e.HId)
        before = Counter(fp)
        gts = frames[f - 1][3]
        state, box, detected, det_box = states[f - 1][h][:4]
        ious = _iou(box, [g.box for g in gts])
        top = int(np.argmax(ious)) if len(ious) else None
        best = float(ious[top]) if top is not None else 0.0
        if best >= 0.5 and (f, gts[top].id) in match:
            fp["duplicate"] += 1
        elif not detected:
            kind = "coasting" if state == "occluded" else "refinement only"
            fp[f"{kind}, {'person gone' if best < 0.1 else 'off a person'}"] += 1
        elif det_box is None:
            fp["detected (group member), box off"] += 1
        else:
            dious = _iou(det_box, [g.box for g in gts])
            dtop = int(np.argmax(dious)) if len(dious) else None
            dbest = float(dious[dtop]) if dtop is not None else 0.0
            if dbest >= 0.5 and (f, gts[dtop].id) not in match:
                fp["detected, box off, detection on"] += 1
            elif dbest < 0.1:
                fp["detected, on a false detection"] += 1
            else:
                fp["detected, detection off too"] += 1
        causes["FP", f, h] = next(iter(fp - before))
    for _, e in ev[ev.Type == "MISS"].iterrows():
        f, o = int(e.FrameId), int(e.OId)
        before = Counter(fn)
        gts = {g.id: g.box for g in frames[f - 1][3]}
        box = gts[o]
        dets = [d[:4] for d in frames[f - 1][2]]
        detected = len(dets) and _iou(box, dets).max() >= 0.5
        info = states[f - 1]
        rep = {h: v[1] for h, v in info.items() if v[4]}
        rep_iou = {h: float(_iou(box, [b])[0]) for h, b in rep.items()}
        near = max(rep_iou, key=rep_iou.get) if rep_iou else None
        near_v = rep_iou[near] if near is not None else 0.0
        hidden = {h: float(_iou(box, [v[1]])[0]) for h, v in info.items()
                  if not v[4] and v[0] in ("occluded", "lost", "confirmed")}
        tent = [h for h, v in info.items() if v[0] == "tentative"
                and float(_iou(box, [v[1]])[0]) >= 0.3]
        if detected:
            if near is not None and near_v >= 0.1 and (f, near) not in carried:
                fn["detected: our box off"] += 1
            elif tent:
                fn["detected: tentative"] += 1
            elif near is not None and near_v >= 0.1:
                fn["detected: covered by a neighbour's box"] += 1
            else:
                fn["detected: detection unused"] += 1
        else:
            best_hidden = max(hidden.values(), default=0.0)
            if best_hidden >= 0.5:
                fn["undetected: coast dropped, would match"] += 1
            elif near is not None and near_v >= 0.1 and (f, near) not in carried:
                fn["undetected: our box off"] += 1
            elif best_hidden >= 0.1:
                fn["undetected: coast dropped, off"] += 1
            elif near is not None and near_v >= 0.1:
                fn["undetected: neighbour's box"] += 1
            else:
                fn["undetected: nothing"] += 1
        causes["FN", f, o] = next(iter(fn - before))
    kinds = Counter()
    matched_h = {(f, h) for (f, _), h in match.items()}
    for k, info in enumerate(states):
        for h, v in info.items():
            if not v[4]:
                continue
            if v[0] == "occluded":
                kind = f"coasting, std {min(int(v[5] / 0.1), 5) / 10:.1f}+ w"
            elif not v[2]:
                kind = "refinement only"
            elif v[3] is None:
                kind = "group member"
            else:
                kind = "detected"
            kinds[(kind, (k + 1, h) in matched_h)] += 1
    for kind in sorted({k for k, _ in kinds}):
        print(f"  reported {kind:28s}: {kinds[(kind, True)]:4d} matched, "
              f"{kinds[(kind, False)]:4d} unmatched")
    took = {(f, h) for (f, _), h in match.items()}
    for _, e in ev[ev.Type == "SWITCH"].iterrows():
        f, o, h = int(e.FrameId), int(e.OId), int(e.HId)
        # what the new id was the frame before: a lost track that took this person back
        # (re-acquisition), a track on another person, a new (tentative) track, or another
        # live track of ours that matched nobody
        before = states[f - 2].get(h) if f >= 2 else None
        if before is None or before[0] == "tentative":
            new_id = "a new track"
        elif before[0] == "lost":
            new_id = "a lost track re-acquiring"
        elif (f - 1, h) in took:
            new_id = "another person's track"
        else:
            new_id = "an unmatched live track"
        sw[("hand-over (matched the frame before)" if (f - 1, o) in match
            else "after a gap") + f"; new id: {new_id}"] += 1
    return n_gt, fp, fn, sw, causes


def diagnose_peer(frames, hyp):
    ev, match, n_gt = events(frames, hyp)
    fn = Counter()
    for _, e in ev[ev.Type == "MISS"].iterrows():
        f, o = int(e.FrameId), int(e.OId)
        box = {g.id: g.box for g in frames[f - 1][3]}[o]
        dets = [d[:4] for d in frames[f - 1][2]]
        fn["detected" if len(dets) and _iou(box, dets).max() >= 0.5 else "undetected"] += 1
    return n_gt, int((ev.Type == "FP").sum()), fn, int((ev.Type == "SWITCH").sum())


def peer_hypotheses(frames, fps) -> dict:
    """SORT-style and, when the ``trackers`` package is installed
    (benchmarks/requirements-peers.txt), ByteTrack on the same detections."""
    peers = {"SORT": bmo.SortTracker()}
    try:
        from peers.trackers_peers import TrackersPeer
        peers["ByteTrack"] = TrackersPeer("bytetrack", fps)
    except ImportError as exc:
        print(f"ByteTrack left out ({exc})", file=sys.stderr)
    return {name: bmo.run_tracker(peer, frames)[0] for name, peer in peers.items()}


def groups_frames(name: str, detector_changes: dict, frames: int = 150):
    """``(frames, fps)`` of the bench_groups scene ``groups-PEOPLE-SEED-WxH`` (module
    docstring): per frame the BGR image, its stamp, the thermal detector's boxes in RGB
    pixels with their scores, and the ground truth of ``mk_tracker process`` (every person
    with ``visible_fraction > 0``, box clipped to the image: ``ground_truth_detections``)."""
    from mk_tracker.boxes import transform_box
    from mk_tracker.detection.thermal_detector import ThermalDetector
    from mk_tracker.synthetic.scene_bag import build_preset, ground_truth_detections
    from mk_tracker.tools.pipeline_config import load_pipeline_config
    try:
        _, people, seed, size = name.split("-")
        width, height = (int(v) for v in size.split("x"))
        people, seed = int(people), int(seed)
    except ValueError:
        raise SystemExit(f"{name}: expected groups-PEOPLE-SEED-WxH") from None
    scene = build_preset("crowd", seed=seed, people=people, frames=frames, width=width,
                         height=height)
    detector = ThermalDetector(updated(load_pipeline_config().detector, detector_changes))
    out = []
    for k in range(len(scene)):
        f = scene.frame(k)
        dets = [(*transform_box(d.box, scene.homography), d.score)
                for d in detector.process(f.thermal, f.stamp)]
        gt = [MotRow(k + 1, int(d.id), tuple(d.box))
              for d in ground_truth_detections(scene, f, "rgb")]
        out.append((f.rgb, f.stamp, dets, gt))
    return out, float(scene.config.fps)


def background_frames(frames):
    """``frames`` with each frame's detections replaced by the background detector's (its
    shipped defaults, fed the frames in order at their stamps)."""
    from mk_tracker.detection.background_detector import BackgroundDetector
    det = BackgroundDetector()
    return [(image, stamp, [(*d.box, d.score) for d in det.process(image, stamp,
                                                                    encoding="bgr8")], gt)
            for image, stamp, _dets, gt in frames]


def report(name, frames, config, fps=25.0) -> list[str]:
    hyp, states = run_ours(config, frames)
    n_gt, fp, fn, sw, causes = diagnose_ours(frames, hyp, states)
    peer_hyp = peer_hypotheses(frames, fps)
    peers = {p: diagnose_peer(frames, h) for p, h in peer_hyp.items()}
    o_fp, o_fn, o_sw = sum(fp.values()), sum(fn.values()), sum(sw.values())
    names = list(peers)
    head = " | ".join(names)
    cells = {p: (v[1], sum(v[2].values()), v[2]["detected"], v[3]) for p, v in peers.items()}

    def row(label, ours, idx, points=True):
        vals = " | ".join(str(cells[p][idx]) for p in names)
        diff = f"{-(ours - cells['SORT'][idx]) / n_gt:+.3f}" if points else ""
        return f"| {label} | {ours} | {vals} | {diff} |"

    mota = " | ".join(f"{1 - (c[0] + c[1] + c[3]) / n_gt:.3f}" for c in cells.values())
    lines = [f"## {name} ({n_gt} gt boxes)", "",
             f"| | ours | {head} | ours - SORT (MOTA points) |",
             "|---|---|" + "---|" * len(names) + "---|",
             f"| MOTA | {1 - (o_fp + o_fn + o_sw) / n_gt:.3f} | {mota} | |",
             row("FP", o_fp, 0), row("FN", o_fn, 1),
             row("FN with a detection",
                 sum(v for k, v in fn.items() if k.startswith('detected')), 2, points=False),
             row("ID switches", o_sw, 3), "",
             "| our error | cause | count | MOTA points |", "|---|---|---|---|"]
    for label, counter in (("FP", fp), ("FN", fn), ("IDSW", sw)):
        for cause, n in counter.most_common():
            lines.append(f"| {label} | {cause} | {n} | {n / n_gt:.3f} |")
    return lines + [""] + versus_sort(frames, hyp, peer_hyp["SORT"], causes, n_gt)


def versus_sort(frames, ours, sort, causes, n_gt) -> list[str]:
    """Our errors that SORT does not make, by our cause, and SORT's that we do not make.

    A person in a frame missed by us and matched by SORT ("SORT only") costs us one miss
    against SORT; a false positive of ours in a frame counts against SORT's false positives
    of that frame (a false positive has no identity to pair, so the two are compared by
    count per frame: ``max(0, ours - SORT)`` of our false positives of the frame are "ours
    beyond SORT's", attributed to our causes in proportion)."""
    _ev_o, match_o, _ = events(frames, ours)
    ev_s, match_s, _ = events(frames, sort)
    persons = {(f, o) for f, (_, _, _, g) in enumerate(frames, 1) for o in
               (r.id for r in g)}
    only_sort = Counter(causes.get(("FN", f, o), "?") for f, o in persons
                        if (f, o) in match_s and (f, o) not in match_o)
    only_ours = sum(1 for k in persons if k in match_o and k not in match_s)
    fp_s = Counter(int(e.FrameId) for _, e in ev_s[ev_s.Type == "FP"].iterrows())
    fp_o_frames: dict[int, list[str]] = {}
    for (kind, f, _h), cause in causes.items():
        if kind == "FP":
            fp_o_frames.setdefault(f, []).append(cause)
    beyond, fewer = Counter(), 0
    for f in set(fp_o_frames) | set(fp_s):
        mine = fp_o_frames.get(f, [])
        extra = len(mine) - fp_s.get(f, 0)
        if extra > 0:
            for cause in mine:
                beyond[cause] += extra / len(mine)
        else:
            fewer -= extra
    lines = ["Against SORT, person by person (IoU >= 0.5 matches of each tracker): "
             f"matched by SORT only {sum(only_sort.values())}, by ours only {only_ours}; "
             f"false positives of ours beyond SORT's in the same frame "
             f"{sum(beyond.values()):.0f}, fewer than SORT's {fewer}.", "",
             "| against SORT | our cause | count | MOTA points |", "|---|---|---|---|"]
    for cause, n in only_sort.most_common():
        lines.append(f"| FN, SORT matched | {cause} | {n} | {n / n_gt:.3f} |")
    for cause, n in beyond.most_common():
        lines.append(f"| FP beyond SORT's | {cause} | {n:.0f} | {n / n_gt:.3f} |")
    return lines + [""]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data")
    parser.add_argument("--sequences", nargs="+", default=["TUD-Campus", "TUD-Stadtmitte"])
    parser.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE")
    parser.add_argument("--real-motion", action="store_true",
                        help="generated sequences as bench_multi_object.py --real-motion")
    parser.add_argument("--real-detection-noise", action="store_true",
                        help="generated detections as bench_multi_object.py "
                             "--real-detection-noise")
    parser.add_argument("--detections", choices=("public", "background"), default="public",
                        help="the clips' own detections, or the background-subtraction "
                             "detector's (shipped defaults)")
    parser.add_argument("--set-detector", nargs="*", default=[], metavar="NAME=VALUE",
                        help="detector overrides for groups-* scenes, e.g. "
                             "split_by_person_size=true")
    parser.add_argument("--background-benchmark", action="store_true",
                        help="the six sequences of bench_background_detector.py (TUD clips, "
                             "generated crowd-3 and static-camera 7 / 25 fps scenes) with the "
                             "background detector's boxes (shipped defaults), as "
                             "background_tracker_profile.py runs them; --sequences ignored")
    args = parser.parse_args(argv)
    motion = bmo.REAL_MOTION if args.real_motion else None
    box_error = bmo.REAL_DETECTION_NOISE if args.real_detection_noise else None
    changes = setting_changes(args.set)
    config = updated(MultiObjectTrackerConfig(), changes)
    print(f"# Our errors by cause, next to the peers'\n\ndetections: {args.detections}; "
          f"setting: defaults"
          f"{' + ' + str(changes) if changes else ''}\n")
    if args.background_benchmark:
        import tempfile

        import bench_background_detector as bbd
        from background_tracker_profile import chain_frames
        with tempfile.TemporaryDirectory() as tmp:
            for name, bag, images, _truth, fps, _public in bbd.load_sequences(Path(tmp)):
                chain, _ref = chain_frames(name, bag, images, fps, Path(tmp))
                print("\n".join(report(name, chain, config, fps)), flush=True)
        return 0
    for name in args.sequences:
        if name.startswith("groups-"):
            from mk_tracker.tools.pipeline_config import load_pipeline_config
            frames, fps = groups_frames(name, setting_changes(args.set_detector))
            print("\n".join(report(name, frames,
                                    updated(load_pipeline_config().tracker, changes), fps)),
                  flush=True)
            continue
        if name.startswith("TUD"):
            clip, _, rate = name.partition("/")
            step, _, offset = rate.partition("+")
            try:
                frames, fps = bmo.tud_frames(args.data / "mot" / clip, int(step or 1),
                                             int(offset or 0))
            except ValueError as exc:
                raise SystemExit(f"{name}: expected CLIP or CLIP/STEP+OFFSET ({exc})") from None
        elif name.startswith("crowd-"):
            frames, fps = bmo.crowd_frames(int(name.split("-")[1]), 1, 300, 0.5, 0.1, 0.3,
                                           2.0, motion=motion, box_error=box_error)
        elif name.startswith("small-far-"):   # issue #16 proxy: small-far-SEED-PEOPLE[-alike]
            import bench_small_far
            seed, _, people = name[len("small-far-"):].removesuffix("-alike").partition("-")
            frames, fps = bench_small_far.small_far_frames(
                int(seed), int(people or 22), 795, (40.0, 60.0), argparse.Namespace(
                    min_visible=0.5, miss=0.1, false_positives=0.3, noise=2.0,
                    scale_speed=True, alike=name.endswith("-alike")))
        else:
            frames, fps = bmo.far_frames(1, 0.5, 0.1, 0.3, 2.0, motion=motion,
                                         box_error=box_error)
        if args.detections == "background":
            frames = background_frames(frames)
        print("\n".join(report(name, frames, config, fps)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
