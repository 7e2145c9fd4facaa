"""Where the duplicate pairs on BU-TIV-lab come from (issues #19 / #15): every run of frames
in which two reported tracks overlap at IoU > 0.5 (the figure of
:func:`mk_tracker.evaluation.identity_figures.duplicate_pairs`), with what each track was
doing, how the pair came to be stacked and why the duplicate rule (``duplicates.*``,
:mod:`mk_tracker.tracking.duplicate_tracks`) did not merge it.

    .venv/bin/python benchmarks/diagnose_duplicates.py --cache out/lab_inputs.pkl [--set NAME=VALUE ...]

The tracker's inputs are captured (or read from ``--cache``) as in
``benchmarks/diagnose_reacquire.py`` and the tracker is replayed on them.  Per episode
(a pair stacked in consecutive frames):

* ``modes``: frames of the episode in which each track was *matched* (a detection of its
  own, ``M``), a *group member* (``G``), seen by its *refinement only* (``R``) or
  *coasting* (``C``), e.g. ``M3 R7`` for the older, then the younger track;
* ``formed``: ``born on`` -- the younger track was born (tentative) on a box overlapping the
  older one at IoU > ``--born-iou`` (0.3); ``drifted (id)`` -- it was born apart, and the
  pair became stacked while the named track was not matched (its refinement or prediction
  moved it onto the other); ``both matched`` -- both were matched when they became stacked;
* ``rule``: what the duplicate rule said at the last frame of the episode: ``young`` (stacked
  for less than ``min_time``), ``apart`` (both given distinct detections in one frame of the
  episode, which restarts the clock), ``looks`` (the appearance test failed: the smaller of
  the two similarities), ``merged``;
* ``end``: ``merged``, ``apart`` (IoU fell to 0.5 or below), ``lost`` / ``deleted`` (one track
  stopped being reported), ``clip end``.
"""

from __future__ import annotations

import argparse
import math
import pickle
import sys
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from diagnose_reacquire import DEFAULT_CLIP, capture  # noqa: E402
from mk_tracker.boxes import iou  # noqa: E402
from mk_tracker.evaluation.identity_figures import identity_figures  # noqa: E402
from mk_tracker.parameters import updated  # noqa: E402
from mk_tracker.tracking.duplicate_tracks import stacked_pairs  # noqa: E402
from mk_tracker.tracking.multi_object_tracker import MultiObjectTracker  # noqa: E402
from mk_tracker.tracking.track import OUTPUT_STATES  # noqa: E402
from mk_tracker.tracking.tracker_config import MultiObjectTrackerConfig  # noqa: E402
from setting_values import setting_changes  # noqa: E402


class RecordingTracker(MultiObjectTracker):
    """The tracker, noting per frame each track's mode, births and the duplicate rule's view
    (same decisions)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.modes: dict[int, str] = {}
        self.births: dict[int, tuple[int, float]] = {}   # id -> (frame, max IoU with live)
        self.apart: set[tuple[int, int]] = set()
        self.looks: dict[tuple[int, int], float] = {}
        self.frame = 0

    def _update_track(self, t, stamp, image, det_box, det, refined, width, height, blockers,
                      hold=False, group=False, **kwargs):
        if group:
            mode = "G"
        elif det_box is not None:
            mode = "M"
        elif refined is not None and refined[2]:
            mode = "R"
        else:
            mode = "C"
        self.modes[t.id] = mode
        return super()._update_track(t, stamp, image, det_box, det, refined, width, height,
                                     blockers, hold=hold, group=group, **kwargs)

    def _new_track(self, box, stamp, score, state, kalman=None, lifecycle=None):
        others = [u.box for u in self.tracks if u.state in OUTPUT_STATES]
        best = max((float(iou(box, b)) for b in others), default=0.0)
        t = super()._new_track(box, stamp, score, state, kalman=kalman, lifecycle=lifecycle)
        self.births[t.id] = (self.frame, best)
        return t

    def _merge_duplicates(self, live, detected_ids, image, stamp, result):
        pool = [t for t in live if t.state in OUTPUT_STATES and not t.manual]
        stacked = stacked_pairs([t.id for t in pool], [t.box for t in pool],
                                self.config.duplicates.min_iou)
        self.apart = {p for p in stacked if p[0] in detected_ids and p[1] in detected_ids}
        by_id = {t.id: t for t in pool}
        self.looks = {}
        if self.refiner is not None:
            for a, b in stacked:
                ta, tb = by_id[a], by_id[b]
                if ta.target is None or tb.target is None:
                    self.looks[(a, b)] = math.nan
                    continue
                try:
                    self.looks[(a, b)] = min(
                        float(self.refiner.appearance_similarity(image, ta.target,
                                                                 tuple(tb.box))),
                        float(self.refiner.appearance_similarity(image, tb.target,
                                                                 tuple(ta.box))))
                except ValueError:
                    self.looks[(a, b)] = math.nan
        return super()._merge_duplicates(live, detected_ids, image, stamp, result)


@dataclass
class Episode:
    pair: tuple[int, int]
    first: int
    last: int = 0
    modes: tuple[Counter, Counter] = field(default_factory=lambda: (Counter(), Counter()))
    formed: str = ""
    apart: bool = False
    looks: list[float] = field(default_factory=list)
    end: str = "clip end"
    age_old: float = 0.0
    age_young: float = 0.0


def replay(inputs: list, changes: dict, born_iou: float = 0.3):
    config = updated(MultiObjectTrackerConfig(), changes)
    trk = RecordingTracker(config)
    reported_by_frame = []
    open_eps: dict[tuple[int, int], Episode] = {}
    episodes: list[Episode] = []
    for k, (image, stamp, dets) in enumerate(inputs):
        if image.ndim == 2:
            image = np.repeat(image[..., None], 3, axis=2)
        trk.frame = k
        trk.modes = {}
        result = trk.step(image, stamp, dets)
        rep = result.reported()
        reported_by_frame.append([(t.id, t.box) for t in rep])
        merged = {int(e.split()[1]) for e in result.events if "merged into" in e}
        by_id = {t.id: t for t in rep}
        now = set()
        for i, a in enumerate(rep):
            for b in rep[i + 1:]:
                if iou(a.box, b.box) > 0.5:
                    now.add((min(a.id, b.id), max(a.id, b.id)))
        for p in now:
            ep = open_eps.get(p)
            if ep is None:
                ep = Episode(p, k)
                old, young = p
                born_frame, born_best = trk.births.get(young, (-1, 0.0))
                ma, mb = trk.modes.get(old, "?"), trk.modes.get(young, "?")
                if born_best > born_iou and k - born_frame <= 10:
                    ep.formed = f"born on (IoU {born_best:.2f})"
                elif ma == "M" and mb == "M":
                    ep.formed = "both matched"
                else:
                    movers = [str(i) for i, m in ((old, ma), (young, mb)) if m != "M"]
                    ep.formed = f"drifted ({', '.join(movers)})"
                open_eps[p] = ep
            ep.last = k
            for n, tid in enumerate(p):
                ep.modes[n][trk.modes.get(tid, "?")] += 1
            if p in trk.apart:
                ep.apart = True
            if p in trk.looks:
                ep.looks.append(trk.looks[p])
            ep.age_old = by_id[p[0]].age
            ep.age_young = by_id[p[1]].age
        for p in list(open_eps):
            if p in now:
                continue
            ep = open_eps.pop(p)
            gone = [tid for tid in p if tid not in by_id]
            if any(tid in merged for tid in p):
                ep.end = "merged"
            elif gone:
                ep.end = ("deleted " if any(tid in result.deleted_ids for tid in gone)
                          else "unreported ") + ",".join(map(str, gone))
            else:
                ep.end = "apart"
            episodes.append(ep)
    episodes.extend(open_eps.values())
    return identity_figures(reported_by_frame), sorted(episodes, key=lambda e: e.first), trk


def table(episodes: list[Episode], min_time_frames: int) -> str:
    lines = ["| pair (older, younger) | frames | length | older: modes | younger: modes | "
             "ages at the end (s) | formed | rule | min. similarity | end |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for e in episodes:
        length = e.last - e.first + 1
        sims = [s for s in e.looks if math.isfinite(s)]
        if e.end == "merged":
            rule = "merged"
        elif e.apart:
            rule = "apart"
        elif length < min_time_frames:
            rule = "young"
        elif sims and sims[-1] < 0.3:
            rule = "looks"
        else:
            rule = "?"
        modes = [" ".join(f"{m}{n}" for m, n in sorted(c.items())) for c in e.modes]
        lines.append(f"| {e.pair[0]}, {e.pair[1]} | {e.first}-{e.last} | {length} | "
                     f"{modes[0]} | {modes[1]} | {e.age_old:.1f}, {e.age_young:.1f} | "
                     f"{e.formed} | {rule} | "
                     f"{(min(sims) if sims else math.nan):.2f} | {e.end} |")
    frames = sum(e.last - e.first + 1 for e in episodes)
    lines.append("")
    lines.append(f"{len(episodes)} episodes, {frames} pair-frames")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clip", type=Path, default=DEFAULT_CLIP)
    parser.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE")
    parser.add_argument("--cache", type=Path, default=None,
                        help="captured tracker inputs (as diagnose_reacquire.py --cache)")
    parser.add_argument("--born-iou", type=float, default=0.3)
    args = parser.parse_args(argv)
    changes = setting_changes(args.set)
    if args.cache is not None and args.cache.is_file():
        with open(args.cache, "rb") as fh:
            inputs, _ = pickle.load(fh)
    else:
        if not args.clip.exists():
            print(f"{args.clip} not found", file=sys.stderr)
            return 1
        inputs, piped = capture(args.clip)
        if args.cache is not None:
            with open(args.cache, "wb") as fh:
                pickle.dump((inputs, piped), fh)
    figures, episodes, trk = replay(inputs, changes, args.born_iou)
    print(f"replay {changes}: ids {figures['ids']} dup {figures['duplicates']:.2f} "
          f"tracks {figures['tracks']:.2f}", flush=True)
    fps = (len(inputs) - 1) / max(inputs[-1][1] - inputs[0][1], 1e-9)
    print(table(episodes, int(math.ceil(trk.config.duplicates.min_time * fps))), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
