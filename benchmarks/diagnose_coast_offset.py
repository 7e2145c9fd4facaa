"""Why a reported coasting box sits off its person (issue #16 item 2).

``diagnose_mot_loss.py`` counts the false positives of reported coasting boxes (state
``occluded``: no detection, the multiple-kernel refinement not visible this frame) that
overlap a person by IoU 0.1-0.5 ("off a person").  This script splits those by cause,
from the track's own history since its last detection (``last_detection``: a detection
or a group-member update):

* ``neighbour before coasting``: the track's last detection did not lie on this person
  (its best ground-truth match at IoU >= 0.5 in that frame was another person, or none);
* ``size``: the box's centre is right -- the box with the person's own size at the
  track's centre would overlap the person at IoU >= 0.5 -- so the track's size is wrong;
* ``refinement pulled``: the centre is off, but the pure Kalman prediction from the
  filter right after the last detection (no correction since) has it right (IoU >= 0.5
  with the person's size), and visible refinements corrected the track since that
  detection: the multiple-kernel search moved the box (Chu et al. 2013, Sec. IV-D);
* ``prediction drift``: the pure prediction (4.2) is off too: the constant-velocity
  extrapolation from the last detection's filter went elsewhere.

Also counted: how many of them lie on a person whom another of our tracks matches in that
frame (a stale second box beside a tracked person).

For the last two it also says which other predictions from the last detection would have
been on the person (IoU >= 0.5 with the person's size at that centre): ``hold`` (the last
detected centre, velocity 0), ``observed velocity k`` (the last detected centre moved on
with the velocity between the last detection and the one ``k`` detections before it,
OC-SORT's observation-centric momentum, Cao et al. 2023, Sec. 4.2) and how much the
track's Kalman velocity differs from the person's true one (ground-truth centres over
the same interval).

    nice -n 10 .venv/bin/python benchmarks/diagnose_coast_offset.py \
        --sequences TUD-Stadtmitte TUD-Stadtmitte/4+0 ... --set NAME=VALUE ...

Sequence names as in ``diagnose_mot_loss.py`` (``CLIP/STEP+OFFSET`` for a lower rate).
``--alternatives`` also counts, over all reported coasting boxes, how many other coasting
predictions would have put on a person (:func:`alternatives`).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import copy  # noqa: E402
import sys  # noqa: E402
from collections import Counter  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench_multi_object as bmo  # noqa: E402
from diagnose_mot_loss import events  # noqa: E402
from mk_tracker.boxes import center_to_xywh, iou_matrix  # noqa: E402
from mk_tracker.evaluation.metrics import MotRow  # noqa: E402
from mk_tracker.parameters import updated  # noqa: E402
from mk_tracker.tracking.multi_object_tracker import (FrameDetection,  # noqa: E402
                                                      MultiObjectTracker,
                                                      MultiObjectTrackerConfig)
from setting_values import setting_changes  # noqa: E402

MOMENTUM_LAGS = (1, 3)
NEIGHBOUR = "before coasting: last detection on a neighbour"
NOBODY = "before coasting: last detection on nobody (IoU < 0.5 with every person)"
SIZE = "size (centre right, size wrong)"
PULLED = "refinement pulled (pure prediction on)"
OTHER = "other (pure prediction on, no refinement)"
DRIFT = "prediction drift (pure prediction off too)"
CAUSES = (NOBODY, NEIGHBOUR, DRIFT, SIZE, PULLED, OTHER)


def _iou1(a, b) -> float:
    return float(iou_matrix(np.array([a], float), np.array([b], float))[0, 0])


def _centre(box) -> np.ndarray:
    b = np.asarray(box, float)
    return b[:2] + b[2:] / 2.0


def _on(centre, person_box) -> bool:
    """The person's own size at ``centre`` overlaps the person at IoU >= 0.5."""
    w, h = float(person_box[2]), float(person_box[3])
    return _iou1(center_to_xywh(float(centre[0]), float(centre[1]), w, h), person_box) >= 0.5


def run(config, frames):
    """Run the tracker; returns the reported rows and, per (frame, id) of a reported
    coasting box, what the causes need."""
    tracker = MultiObjectTracker(config)
    hyp, coast = [], {}
    snap: dict[int, dict] = {}           # id -> the track right after its last detection
    history: dict[int, list] = {}        # id -> [(frame index, stamp, detected centre)]
    refined_since: Counter = Counter()   # id -> visible refinements since that detection
    for k, (image, stamp, dets, _) in enumerate(frames):
        res = tracker.step(image, stamp, [FrameDetection(tuple(d[:4]), d[4], stamp)
                                          for d in dets])
        reported = {t.id for t in res.reported()}
        out = {t.id: t for t in res.tracks}
        for t in tracker.tracks:
            if t.last_detection == stamp:
                own = t.detected_stamp == stamp        # not a group member's update
                snap[t.id] = {"kf": copy.deepcopy(t.kf), "stamp": stamp, "frame": k,
                              "box": np.array(t.detected_box if own else t.box, float),
                              "group": not own,
                              "earlier": snap[t.id]["earlier"] + [snap[t.id]]
                              if t.id in snap else []}
                refined_since[t.id] = 0
                if own:
                    history.setdefault(t.id, []).append((k, stamp, _centre(t.detected_box)))
            elif t.state.value == "confirmed":
                refined_since[t.id] += 1
            if t.id in reported:
                o = out[t.id]
                hyp.append(MotRow(k + 1, t.id, tuple(o.box)))
                if o.state == "occluded" and t.id in snap:
                    kf = copy.deepcopy(snap[t.id]["kf"])
                    dt = stamp - snap[t.id]["stamp"]
                    if dt > 0:
                        kf.predict(dt)
                    coast[(k + 1, t.id)] = {
                        "box": np.array(o.box, float), "pred": np.array(kf.center, float),
                        "snap": snap[t.id], "refined": refined_since[t.id],
                        "history": list(history.get(t.id, [])), "stamp": stamp,
                        "velocity": np.array(t.kf.velocity, float)}
    return hyp, coast


def alternatives(frames, coast) -> Counter:
    """Over every reported coasting box (matched or not): how many would lie on some person
    (IoU >= 0.5 with the box's own size) if the coasting centre came from another
    prediction from the track's last detection(s).  ``actual`` is the tracker's;
    ``rewind k`` predicts from the filter k detections before the last (the last k-1
    discarded); ``decay tau`` moves the last detection's filter by tau (1 - exp(-dt/tau)) v
    (an Ornstein-Uhlenbeck velocity); ``observed velocity k``: the last detected centre's
    filter moved with the velocity between the last detection and the one k before it;
    ``no vertical velocity``: the filter's horizontal velocity only."""
    n = Counter()
    for (f, _), c in coast.items():
        people = np.array([g.box for g in frames[f - 1][3]], float).reshape(-1, 4)
        if not len(people):
            continue
        w, h = c["box"][2:]

        def on(centre):
            box = center_to_xywh(float(centre[0]), float(centre[1]), w, h)
            return bool(iou_matrix(np.array([box]), people)[0].max() >= 0.5)

        s = c["snap"]
        dt = c["stamp"] - s["stamp"]
        c0, v = np.array(s["kf"].center), np.array(s["kf"].velocity)
        n["boxes"] += 1
        n["actual"] += on(_centre(c["box"]))
        chain = s["earlier"] + [s]
        for back in (2, 3, 5):
            old = chain[-back] if len(chain) >= back else chain[0]
            kf = copy.deepcopy(old["kf"])
            if c["stamp"] > old["stamp"]:
                kf.predict(c["stamp"] - old["stamp"])
            n[f"rewind {back - 1}"] += on(kf.center)
        for tau in (0.25, 0.5, 1.0):
            n[f"decay tau {tau}"] += on(c0 + v * tau * (1.0 - np.exp(-dt / tau)))
        hist = c["history"]
        for lag in MOMENTUM_LAGS:
            if len(hist) > lag:
                (_, t0, p0), (_, t1, p1) = hist[-1 - lag], hist[-1]
                n[f"observed velocity {lag}"] += on(c0 + (p1 - p0) / max(t1 - t0, 1e-9) * dt)
            else:
                n[f"observed velocity {lag}"] += on(c0 + v * dt)
        n["no vertical velocity"] += on(c0 + np.array([v[0], 0.0]) * dt)
    return n


def _gt_centre(frames, frame_index, pid):
    for g in frames[frame_index][3]:
        if g.id == pid:
            return _centre(g.box)
    return None


def diagnose(frames, hyp, coast):
    ev, match, _ = events(frames, hyp)
    causes, also, lines = Counter(), Counter(), []
    vel_err = []
    for _, e in ev[ev.Type == "FP"].iterrows():
        f, h = int(e.FrameId), int(e.HId)
        c = coast.get((f, h))
        if c is None:
            continue
        gts = frames[f - 1][3]
        ious = [_iou1(c["box"], g.box) for g in gts]
        if not ious:
            continue
        top = int(np.argmax(ious))
        if not 0.1 <= ious[top] < 0.5:
            continue                     # the person is gone
        person = gts[top]
        s = c["snap"]
        dgts = frames[s["frame"]][3]
        dious = [_iou1(s["box"], g.box) for g in dgts]
        dtop = int(np.argmax(dious)) if dious else None
        if dtop is None or dious[dtop] < 0.5:
            cause = NOBODY
        elif dgts[dtop].id != person.id:
            cause = NEIGHBOUR
        elif _on(_centre(c["box"]), person.box):
            cause = SIZE
        elif _on(c["pred"], person.box):
            cause = PULLED if c["refined"] else OTHER
        else:
            cause = DRIFT
        causes[cause] += 1
        if (f, person.id) in match:
            also["on a person matched by another of our tracks (any cause)"] += 1
        if cause in (PULLED, OTHER, DRIFT):
            last = _centre(s["box"])
            also["hold (last detected centre) on"] += _on(last, person.box)
            hist = c["history"]
            for lag in MOMENTUM_LAGS:
                if len(hist) > lag:
                    (_, t0, c0), (_, t1, c1) = hist[-1 - lag], hist[-1]
                    v = (c1 - c0) / max(t1 - t0, 1e-9)
                    also[f"observed velocity, lag {lag} detections, on"] += \
                        _on(c1 + v * (c["stamp"] - t1), person.box)
            g0 = _gt_centre(frames, s["frame"], person.id)
            g1 = _centre(person.box)
            if g0 is not None and c["stamp"] > s["stamp"]:
                true_v = (g1 - g0) / (c["stamp"] - s["stamp"])
                vel_err.append(float(np.hypot(*(c["velocity"] - true_v)) / person.box[3]))
            also["cases"] += 1
        lines.append((f, h, person.id, round(ious[top], 2), cause, c["refined"],
                      round(c["stamp"] - s["stamp"], 2),
                      None if dtop is None else (dgts[dtop].id, round(dious[dtop], 2)),
                      "group" if s["group"] else "det",
                      "person matched by another" if (f, person.id) in match else ""))
    return causes, also, vel_err, lines


def sequence_frames(data: Path, name: str):
    clip, _, rate = name.partition("/")
    step, _, offset = rate.partition("+")
    return bmo.tud_frames(data / "mot" / clip, int(step or 1), int(offset or 0))[0]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data")
    parser.add_argument("--sequences", nargs="+", default=["TUD-Stadtmitte"])
    parser.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE")
    parser.add_argument("--list", action="store_true", help="print every case")
    parser.add_argument("--alternatives", action="store_true",
                        help="also count the reported coasting boxes other predictions "
                             "would have put on a person (alternatives())")
    args = parser.parse_args(argv)
    changes = setting_changes(args.set)
    config = updated(MultiObjectTrackerConfig(), changes)
    print(f"# Off-person coasting boxes by cause\n\nsetting: defaults"
          f"{' + ' + str(changes) if changes else ''}\n")
    for name in args.sequences:
        frames = sequence_frames(args.data, name)
        hyp, coast = run(config, frames)
        causes, also, vel_err, lines = diagnose(frames, hyp, coast)
        print(f"## {name}: {sum(causes.values())} off-person coasting false positives\n")
        for cause in CAUSES:
            print(f"* {cause}: {causes[cause]}")
        n = also.pop("cases", 0)
        for what, v in sorted(also.items()):
            print(f"  - {what}: {v}" if what.startswith("on a person")
                  else f"  - of the {n} centre-off cases, {what}: {v}")
        if vel_err:
            print(f"  - |Kalman velocity - true velocity| (box heights / s): median "
                  f"{np.median(vel_err):.2f}, p90 {np.percentile(vel_err, 90):.2f}")
        if args.alternatives:
            alt = alternatives(frames, coast)
            print(f"  reported coasting boxes on a person (IoU >= 0.5), of {alt.pop('boxes')}: "
                  + ", ".join(f"{k} {v}" for k, v in alt.items()))
        if args.list:
            for row in lines:
                print("   ", row)
        print(flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
