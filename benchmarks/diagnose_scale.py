"""Why a multiple-kernel box grows on a grey image and does not follow an approaching person
(issues #19 / #16): per-frame log of every scale update (eqs. (9)-(11),
:mod:`mk_tracker.tracking.scale_estimation`).

    .venv/bin/python benchmarks/diagnose_scale.py lab [--cache out/lab_inputs.pkl] [--set ...]
    .venv/bin/python benchmarks/diagnose_scale.py single --sequences 'TUD-Stadtmitte person 10'

``lab`` replays the tracker on the captured BU-TIV-lab inputs of
``benchmarks/diagnose_reacquire.py`` (``--cache``; built there on the first run) and logs,
for every track whose refined box grew past ``--growth`` times its last detected height,
each frame's refinement: detected or not, the gate statistic, ``r(h)``, ``Delta s``, the
weighted cost (7) at the old and the proposed scale and what the acceptance did.  ``single``
runs the hand-started tracker (``bench_single_target.full_tracker_factory``) on the named
single-target sequences and logs the same with the truth box height.  Both print a summary
of the scale decisions: how many steps were kept on an exact tie of the cost, kept with a
decrease, refused, or gated.
"""

from __future__ import annotations

import argparse
import pickle
import sys
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from mk_tracker.parameters import updated  # noqa: E402
from mk_tracker.tracking.multi_object_tracker import MultiObjectTracker  # noqa: E402
from mk_tracker.tracking.tracker_config import MultiObjectTrackerConfig  # noqa: E402
from setting_values import setting_changes  # noqa: E402


class LoggingTracker(MultiObjectTracker):
    """Keeps, per frame and track, the box and scale record of each refinement."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.frame = 0
        self.log: dict[int, dict[int, dict]] = {}      # track id -> frame -> entry

    def _refine(self, t, refiner, image):
        found = super()._refine(t, refiner, image)
        step = getattr(t.target, "scale_step", None)
        entry = {"refined": None if found is None else found[0].copy(),
                 "visible": found is not None and found[2], "step": step,
                 "scale": float(t.target.scale)}
        self.log.setdefault(t.id, {})[self.frame] = entry
        return found


def _classify(step) -> str:
    if step is None:
        return "none"
    if step.reason == "kept":
        if step.new_cost == step.old_cost:
            return "kept on a tie"
        return "kept, cost lower" if step.new_cost < step.old_cost else "kept"
    return step.reason


def _row(k, e, extra: str) -> str:
    s = e["step"]
    h = "-" if e["refined"] is None else f"{e['refined'][3]:.0f}"
    if s is None:
        return f"| {k} | {extra} | {h} | {e['scale']:.3f} | | | | | | none |"
    rel = (s.new_cost - s.old_cost) / s.old_cost if np.isfinite(s.new_cost) and \
        s.old_cost > 0 else float("nan")
    return (f"| {k} | {extra} | {h} | {e['scale']:.3f} | {s.statistic:.3f} | {s.r:+.2e} | "
            f"{s.ds:+.3f} | {s.old_cost:.4f} | {s.new_cost:.4f} ({rel:+.1e}) | "
            f"{_classify(s)} |")


HEADER = ("| frame | detected / truth h | refined h | scale | gate stat. | r(h) | Delta s | "
          "cost (7) old | cost new (rel.) | decision |\n|---|---|---|---|---|---|---|---|---|---|")


def summary(logs: list[dict]) -> str:
    c = Counter()
    ups = []
    for log in logs:
        for e in log.values():
            s = e["step"]
            c[_classify(s)] += 1
            if s is not None and s.reason == "kept" and np.isfinite(s.new_cost) \
                    and s.old_cost > 0:
                ups.append((s.ds > 0, (s.new_cost - s.old_cost) / s.old_cost))
    lines = ["Scale decisions: " + ", ".join(f"{k} {v}" for k, v in c.most_common())]
    if ups:
        grow = [g for up, g in ups if up]
        shrink = [g for up, g in ups if not up]
        for name, vals in (("growing", grow), ("shrinking", shrink)):
            if vals:
                v = np.array(vals)
                lines.append(f"kept {name} steps {len(v)}: relative cost change median "
                             f"{np.median(v):+.2e}, share within -1e-3 of a tie "
                             f"{np.mean(v > -1e-3):.2f}")
    return "\n".join(lines)


def lab(args, changes) -> int:
    if not args.cache.is_file():
        print(f"{args.cache} not found: run benchmarks/diagnose_reacquire.py --cache "
              f"{args.cache} first", file=sys.stderr)
        return 1
    with open(args.cache, "rb") as fh:
        inputs, _ = pickle.load(fh)
    trk = LoggingTracker(updated(MultiObjectTrackerConfig(), changes))
    detected: dict[int, dict[int, float]] = {}
    heights = []
    for k, (image, stamp, dets) in enumerate(inputs):
        if image.ndim == 2:
            image = np.repeat(image[..., None], 3, axis=2)
        trk.frame = k
        frame_height = image.shape[0]
        heights += [float(t.box[3]) for t in trk.step(image, stamp, dets).reported()]
        for t in trk.tracks:
            if t.last_detection == stamp and t.detected_box is not None:
                detected.setdefault(t.id, {})[k] = float(t.detected_box[3])
    growing = []
    for tid, log in trk.log.items():
        det = detected.get(tid, {})
        last, worst = None, 1.0
        for k in sorted(log):
            last = det.get(k, last)
            r = log[k]["refined"]
            if last and r is not None:
                worst = max(worst, r[3] / last)
        if worst >= args.growth:
            growing.append((tid, worst))
    print(summary(list(trk.log.values())))
    h = np.array(heights)
    print(f"Reported boxes: {h.size}, median height {np.median(h):.0f} px, taller than the "
          f"frame ({frame_height} px) {int(np.sum(h > frame_height))}, taller than half of it "
          f"{int(np.sum(h > frame_height / 2))}, largest {h.max():.0f} px")
    print(f"\nTracks whose refined box grew past {args.growth:g} x the last detected height: "
          + ", ".join(f"{tid} ({g:.1f} x)" for tid, g in growing))
    for tid, g in growing[:args.max_tracks]:
        det = detected.get(tid, {})
        print(f"\n### track {tid} (refined height up to {g:.1f} x the last detected one)\n")
        print(HEADER)
        rows = 0
        for k in sorted(trk.log[tid]):
            e = trk.log[tid][k]
            extra = f"{det[k]:.0f}" if k in det else "-"
            print(_row(k, e, extra))
            rows += 1
            if rows >= args.max_rows:
                break
    return 0


def single(args, changes) -> int:
    import bench_single_target as bst
    seqs = [s for _, s in bst.development_set()
            if any(n.strip() and n.strip() in s.name for n in args.sequences.split(","))]
    if not seqs:
        print(f"no sequence matches {args.sequences!r}", file=sys.stderr)
        return 1
    logs = []
    for seq in seqs:
        trk = LoggingTracker(updated(MultiObjectTrackerConfig(), changes))
        frames = seq.frames()
        first = next(frames)
        tid = trk.start_track(first, 0.0, seq.init_box)
        trk.step(first, 0.0)
        for k, frame in enumerate(frames, start=1):
            trk.frame = k
            trk.step(frame, k / seq.fps)
        log = trk.log.get(tid, {})
        logs.append(log)
        print(f"\n### {seq.name} ({seq.fps:g} fps)\n")
        print(HEADER)
        for k in sorted(log)[:args.max_rows]:
            truth = seq.truth[k] if k < len(seq.truth) else None
            extra = "-" if truth is None else f"{truth[3]:.0f}"
            print(_row(k, log[k], extra))
        print("\n" + summary([log]))
    print("\nAll: " + summary(logs))
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("mode", choices=("lab", "single"))
    parser.add_argument("--cache", type=Path, default=ROOT / "out" / "lab_inputs.pkl")
    parser.add_argument("--sequences", default="TUD-Stadtmitte person 10",
                        help="single: comma-separated substrings of sequence names")
    parser.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE")
    parser.add_argument("--growth", type=float, default=1.5)
    parser.add_argument("--max-tracks", type=int, default=3)
    parser.add_argument("--max-rows", type=int, default=400)
    args = parser.parse_args(argv)
    changes = setting_changes(args.set)
    return lab(args, changes) if args.mode == "lab" else single(args, changes)


if __name__ == "__main__":
    raise SystemExit(main())
