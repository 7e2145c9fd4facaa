"""Why extra ids are born on BU-TIV-lab (issues #19 / #15): for every reported track id born
after the first second, the old track nearest to it at birth and the check of the
re-acquisition stage (``MultiObjectTracker._reacquire``, step 4c) that refused the old id.

    .venv/bin/python benchmarks/diagnose_reacquire.py [--set NAME=VALUE ...]

The clip is imported and run through ``mk_tracker process``'s code once (counter masked, as
``bench_real_thermal.py``) while the tracker's inputs (image, stamp, detections) are kept in
memory; then the tracker is replayed on those inputs with ``--set`` overrides, so a setting
costs a tracker run, not a detector run.  The replay reports the same figures as the
pipeline (checked below: it prints both for the defaults).

For each new id: ``old`` is the nearest older track that was occluded, lost or deleted
within ``max_lost_time`` at the birth, by the distance from the new track's first box to the
old track's last *detected* box in old box heights (``dist_h``); ``lost_s`` how long it had
been unseen (no detection); ``pred_h`` the distance from its Kalman prediction.  ``reason``:

* ``deleted`` -- the old track was already deleted (``max_lost_time`` passed; tracks merged
  into another by the duplicate rule are no candidates: their person kept the other id);
* ``active`` -- it was still occluded / confirmed: step 4b (not re-acquisition) would have
  had to give it the detection;
* ``gate``, ``size``, ``appearance`` -- the first check of ``_reacquire`` that failed in the
  attempt that came closest, over the frames the new track was tentative;
* ``assigned-elsewhere`` -- every check passed but the assignment gave the pair away;
* ``not-tried`` -- the lost track met no detection of the new track in step 4c;
* ``none-near`` -- no old track within ``--near`` heights (a person entering).
"""

from __future__ import annotations

import argparse
import math
import pickle
import sys
import tempfile
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import mk_tracker.tools.pipeline as pipeline_module  # noqa: E402
from mk_tracker.bags.recording_import import import_recording, open_recording  # noqa: E402
from mk_tracker.evaluation.identity_figures import identity_figures  # noqa: E402
from mk_tracker.parameters import updated  # noqa: E402
from mk_tracker.tools.pipeline import PipelineOptions, process_bag  # noqa: E402
from mk_tracker.tools.pipeline_config import load_pipeline_config  # noqa: E402
from mk_tracker.tracking.multi_object_tracker import MultiObjectTracker  # noqa: E402
from mk_tracker.tracking.track import TrackState  # noqa: E402
from setting_values import setting_changes  # noqa: E402

DEFAULT_CLIP = ROOT.parent / "shared" / "data" / "thermal" / "BU-TIV-lab" / "BU-TIV-lab.mp4"
COUNTER_REGION = (0.0, 0.0, 110.0, 50.0)
ORDER = ("gate", "size", "appearance", "assigned-elsewhere")


def capture(clip: Path, masked: bool = True, params: Sequence[Path] = ()
            ) -> tuple[list, dict]:
    """The tracker's inputs of the pipeline run on ``clip`` (the counter masked unless
    ``masked`` is false; ``params`` are more parameter files) and its figures."""
    inputs: list = []

    class Recording(MultiObjectTracker):
        def step(self, image_bgr, stamp, detections=()):
            dets = list(detections)
            inputs.append((image_bgr[..., 0].copy() if _grey(image_bgr) else image_bgr.copy(),
                           stamp, dets))
            return super().step(image_bgr, stamp, dets)

    original = pipeline_module.MultiObjectTracker
    pipeline_module.MultiObjectTracker = Recording
    try:
        with tempfile.TemporaryDirectory() as tmp:
            tmp = Path(tmp)
            import_recording(open_recording(clip, None), tmp / "bag", thermal=True)
            files = []
            if masked:
                mask = tmp / "mask.yaml"
                mask.write_text("detector_node:\n  ros__parameters:\n    ignore_regions: ["
                                + ", ".join(map(str, COUNTER_REGION)) + "]\n")
                files.append(mask)
            result = process_bag(tmp / "bag", tmp / "out",
                                 config=load_pipeline_config(files + list(params)),
                                 options=PipelineOptions(progress=False, write_video=False,
                                                         write_plots=False, write_bag=False))
    finally:
        pipeline_module.MultiObjectTracker = original
    stamps = sorted(result.frame_stamps)
    return inputs, identity_figures([list(result.tracks.get(ns, [])) for ns in stamps])


def _grey(image: np.ndarray) -> bool:
    return image.ndim == 3 and image.shape[2] == 3 and \
        np.array_equal(image[..., 0], image[..., 1]) and \
        np.array_equal(image[..., 0], image[..., 2])


@dataclass
class Attempt:
    """One lost track vs one detection in one call of ``_reacquire``."""
    frame: int
    lost_id: int
    box: np.ndarray
    maha: float
    ratio: float
    similarity: float
    failed: str | None = None        # first failing check, None = passed them all


@dataclass
class Diagnosis:
    frame: int = 0
    attempts: list[Attempt] = field(default_factory=list)


class DiagnosticTracker(MultiObjectTracker):
    """The tracker, recording every pair ``_reacquire`` looks at (same decisions)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.diag = Diagnosis()

    def _reacquire(self, lost, dets, image):
        first = len(self.diag.attempts)
        matches, contested = super()._reacquire(lost, dets, image)
        won = {(lost[i].id, tuple(dets[j].box)) for i, j in matches}
        for a in self.diag.attempts[first:]:
            if a.failed is None and (a.lost_id, tuple(a.box)) not in won:
                a.failed = "assigned-elsewhere"
        return matches, contested

    def _reacquire_check(self, t, d, maha, image):
        refused, sim, k = super()._reacquire_check(t, d, maha, image)
        ratio = d.box[3] / max(t.size[1], 1e-9)
        self.diag.attempts.append(Attempt(self.diag.frame, t.id, d.box.copy(), maha,
                                          float(ratio), sim, refused))
        return refused, sim, k


def _centre(box) -> np.ndarray:
    return np.array([box[0] + box[2] / 2.0, box[1] + box[3] / 2.0])


def _iou(a, b) -> float:
    from mk_tracker.boxes import iou
    return float(iou(a, b))


def replay(inputs: list, changes: dict, diagnose: bool = False, near: float = 3.0):
    """Run the tracker on the captured inputs; figures, and the birth table when asked."""
    from mk_tracker.tracking.tracker_config import MultiObjectTrackerConfig
    config = updated(MultiObjectTrackerConfig(), changes)
    trk = DiagnosticTracker(config) if diagnose else MultiObjectTracker(config)
    reported_by_frame = []
    history: list[dict] = []     # per frame: id -> (state, box, last detected box, lost for)
    last_det_box: dict[int, np.ndarray] = {}
    created: dict[int, tuple[int, float, np.ndarray]] = {}
    deleted_at: dict[int, tuple[float, str]] = {}
    last_det_time: dict[int, float] = {}
    for k, (image, stamp, dets) in enumerate(inputs):
        if image.ndim == 2:
            image = np.repeat(image[..., None], 3, axis=2)
        if diagnose:
            trk.diag.frame = k
        result = trk.step(image, stamp, dets)
        reported_by_frame.append([(t.id, t.box) for t in result.reported()])
        if not diagnose:
            continue
        merged = {int(e.split()[1]) for e in result.events if "merged into" in e}
        for tid in result.deleted_ids:
            deleted_at.setdefault(tid, (stamp, "merged" if tid in merged else "deleted"))
        snap = {}
        for t in trk.tracks:
            if t.id not in created:
                created[t.id] = (k, stamp, t.box.copy())
            if t.last_detection == stamp:
                last_det_box[t.id] = t.box.copy()
                last_det_time[t.id] = stamp
            snap[t.id] = (t.state, t.box.copy(), t.last_detection)
        history.append(snap)
    figures = identity_figures(reported_by_frame)
    figures.update(box_figures(inputs, reported_by_frame))
    if not diagnose:
        return figures, None
    first_reported = {}
    for k, frame in enumerate(reported_by_frame):
        for tid, _ in frame:
            first_reported.setdefault(tid, k)
    t0 = inputs[0][1]
    rows = []
    for tid, (kb, sb, box) in sorted(created.items()):
        if tid not in first_reported or sb - t0 < 1.0:
            continue
        kc = first_reported[tid]
        # candidates: older tracks not reported at the birth frame (occluded, lost, deleted
        # less than max_lost_time ago) with a detected box
        before = history[kb - 1] if kb > 0 else {}
        best = None
        for oid, obox in last_det_box.items():
            if oid >= tid or first_reported.get(oid, kb) >= kb:
                continue                    # never reported before: no id to keep
            if oid in before:
                state, pbox, last_det = before[oid]
                if state in (TrackState.CONFIRMED,) and sb - last_det < 0.1:
                    continue                # detected just now: a different person
            elif oid in deleted_at and deleted_at[oid][1] == "merged":
                continue                    # its person kept the other track's id
            elif oid in deleted_at and deleted_at[oid][0] <= sb:
                state, pbox, last_det = TrackState.DELETED, obox, last_det_time[oid]
            else:
                continue
            d = float(np.linalg.norm(_centre(box) - _centre(obox))) / max(obox[3], 1e-9)
            if best is None or d < best[1]:
                best = (oid, d, state, pbox, last_det)
        if best is None or best[1] > near:
            rows.append((tid, kb, kc, None, best[1] if best else math.nan, math.nan,
                         math.nan, "none-near", None))
            continue
        oid, d, state, pbox, last_det = best
        lost_s = sb - last_det if last_det is not None else math.nan
        pred_h = float(np.linalg.norm(_centre(box) - _centre(pbox))) / max(pbox[3], 1e-9)
        if state is TrackState.DELETED:
            when, how = deleted_at[oid]
            reason, att = f"{how} {sb - when:.1f} s before", None
        elif state is not TrackState.LOST:
            reason, att = f"active ({state.value})", None
        else:
            tried = [a for a in trk.diag.attempts if a.lost_id == oid and kb <= a.frame <= kc
                     and tid in history[a.frame]
                     and _iou(a.box, history[a.frame][tid][1]) > 0.5]
            if not tried:
                reason, att = "not-tried", None
            else:
                att = max(tried, key=lambda a: (ORDER.index(a.failed) if a.failed else 9))
                reason = att.failed or "matched?"
        rows.append((tid, kb, kc, oid, d, lost_s, pred_h, reason, att))
    return figures, rows


def box_figures(inputs: list, reported_by_frame: list) -> dict[str, float]:
    """``tall``: reported boxes taller than the frame; ``max_h``: the tallest (px);
    ``covered``: fraction of the detections that some reported box overlaps at IoU >= 0.3
    (no ground truth: a detected person without a track is a miss of the tracker);
    ``alone``: reported boxes per frame that no detection overlaps so (people kept while
    undetected, e.g. standing still, or boxes on nobody)."""
    from mk_tracker.boxes import iou_matrix
    tall, max_h, n_det, n_cov, alone = 0, 0.0, 0, 0, 0
    for (image, _, dets), frame in zip(inputs, reported_by_frame):
        heights = [float(b[3]) for _, b in frame]
        tall += sum(h > image.shape[0] for h in heights)
        max_h = max([max_h] + heights)
        boxes = np.array([d.box for d in dets], dtype=np.float64).reshape(-1, 4)
        n_det += len(boxes)
        if len(boxes) and frame:
            ious = iou_matrix(boxes, np.array([b for _, b in frame], dtype=np.float64))
            n_cov += int(np.sum(ious.max(axis=1) >= 0.3))
            alone += int(np.sum(ious.max(axis=0) < 0.3))
        elif frame:
            alone += len(frame)
    return {"tall": tall, "max_h": max_h, "covered": n_cov / max(n_det, 1),
            "alone": alone / max(len(reported_by_frame), 1)}


def _line(name: str, f: dict) -> str:
    return (f"replay {name}: ids {f['ids']} dup {f['duplicates']:.2f} tracks {f['tracks']:.2f}"
            f" | boxes > frame {f['tall']} (tallest {f['max_h']:.0f} px) | detections "
            f"covered {f['covered']:.2f} | undetected boxes / frame {f['alone']:.2f}")


def table(rows) -> str:
    lines = ["| new id | born (frame) | reported (frame) | nearest old id | old state / refused "
             "by | unseen (s) | dist. to last detection (h) | dist. to prediction (h) | "
             "d2 / size ratio / appearance of the closest attempt |",
             "|---|---|---|---|---|---|---|---|---|"]
    for tid, kb, kc, oid, d, lost_s, pred_h, reason, att in rows:
        detail = "" if att is None else \
            f"{att.maha:.1f} / {att.ratio:.2f} / {att.similarity:.2f}"
        lines.append(f"| {tid} | {kb} | {kc} | {oid if oid is not None else '-'} | {reason} | "
                     f"{lost_s:.2f} | {d:.2f} | {pred_h:.2f} | {detail} |")
    counts = Counter(r[7].split(" ")[0] for r in rows)
    lines.append("")
    lines.append("Reasons: " + ", ".join(f"{k} {v}" for k, v in counts.most_common()))
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clip", type=Path, default=DEFAULT_CLIP)
    parser.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE")
    parser.add_argument("--sweep", nargs="*", default=[], metavar="NAME=VALUE[;NAME=VALUE]",
                        help="further settings to replay (figures only), one per argument")
    parser.add_argument("--near", type=float, default=3.0,
                        help="largest distance (old box heights) of a candidate old track")
    parser.add_argument("--cache", type=Path, default=None,
                        help="keep the captured tracker inputs in this file (out/...) and "
                             "reuse them when it exists")
    parser.add_argument("--no-table", action="store_true")
    args = parser.parse_args(argv)
    if not args.clip.exists():
        print(f"{args.clip} not found", file=sys.stderr)
        return 1
    changes = setting_changes(args.set)
    if args.cache is not None and args.cache.is_file():
        with open(args.cache, "rb") as fh:
            inputs, piped = pickle.load(fh)
    else:
        inputs, piped = capture(args.clip)
        if args.cache is not None:
            with open(args.cache, "wb") as fh:
                pickle.dump((inputs, piped), fh)
    print(f"pipeline run at capture (the defaults then): ids {piped['ids']} "
          f"dup {piped['duplicates']:.2f} tracks {piped['tracks']:.2f}", flush=True)
    figures, rows = replay(inputs, changes, diagnose=not args.no_table, near=args.near)
    print(_line(str(changes), figures), flush=True)
    if rows is not None:
        print(table(rows), flush=True)
    for item in args.sweep:
        extra = setting_changes(item.split(";"))
        f, _ = replay(inputs, {**changes, **extra})
        print(_line(item, f), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
