"""Why the background detector misses people and reports false boxes (issue #13, real video
with people in view from the first frame): every miss and every false box of
benchmarks/bench_background_detector.py's runs, by cause and by frame range.

A detector box not matched to a person (one-to-one at IoU >= 0.5, the benchmark's rule) is:

* ``ghost``: no person at IoU >= 0.3 now, but it overlaps (IoU >= 0.3) where a person
  stood in the bootstrap frames (the first ``max(bootstrap_frames, 1)`` frames): the model
  learnt that person as background and the uncovered ground is foreground;
* ``merged``: it holds two or more people (at least half of each person's box inside it);
* ``fragment``: its area is under half of the person it lies on (at least half of the box
  inside one person's box);
* ``loose``: a person at IoU 0.3-0.5 (the right person, a poor box);
* ``other``: none of these (clutter, a shadow, a person not in the ground truth).

A person not matched is:

* ``start-up``: the detector reported nothing yet (``last_mode == "startup"``);
* ``no foreground``: under ``--fg`` (0.15) of the person's box is foreground (after the
  shadow test): the model holds the person (learnt from the first frames or standing);
* ``in a merged box``: at least half of the person's box lies in a box holding two or more
  people, matched to one of the others or not (the group stayed one foreground mass);
* ``fragmented``, ``loose box``: covered by such a false box;
* ``foreground, no box``: enough foreground, but every box was filtered out or went to
  someone else.

Frame ranges: ``start-up`` = the first ``--early`` frames (default: 1 s, 25 frames at
25 fps), ``later`` = the rest.  ``--low-fps`` diagnoses the benchmark's real 6.25-fps checks
instead (every 4th frame of the TUD clips, offsets 0-3, ``datasets.subsampled``).

    nice -n 10 .venv/bin/python benchmarks/diagnose_background.py
    nice -n 10 .venv/bin/python benchmarks/diagnose_background.py --set bootstrap_frames=0
    nice -n 10 .venv/bin/python benchmarks/diagnose_background.py --low-fps --set counts_fps=25
    nice -n 10 .venv/bin/python benchmarks/diagnose_background.py --real-only --rows
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from collections import Counter
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_background_detector import (load_low_fps_checks, load_sequences,  # noqa: E402
                                       matches)
from mk_tracker.boxes import iou  # noqa: E402
from mk_tracker.detection.background_detector import (BackgroundDetector,  # noqa: E402
                                                      BackgroundDetectorConfig)

FALSE = ("ghost", "merged", "fragment", "loose", "other")
MISSED = ("start-up", "no foreground", "in a merged box", "fragmented", "loose box",
          "foreground, no box")


class RecordingDetector(BackgroundDetector):
    """The detector with its last foreground mask (working scale) kept."""

    mask: np.ndarray | None = None

    def _foreground(self, small, raw):
        self.mask = super()._foreground(small, raw)
        return self.mask


def _inside(inner, outer) -> float:
    """Share of ``inner``'s area inside ``outer`` (boxes x, y, w, h)."""
    w = min(inner[0] + inner[2], outer[0] + outer[2]) - max(inner[0], outer[0])
    h = min(inner[1] + inner[3], outer[1] + outer[3]) - max(inner[1], outer[1])
    return max(w, 0.0) * max(h, 0.0) / max(inner[2] * inner[3], 1e-9)


def false_cause(box, gt, first_people) -> str:
    best = max((iou(box, g) for g in gt), default=0.0)
    if holds_people(box, gt) >= 2:
        return "merged"
    for g in gt:
        if _inside(box, g) >= 0.5 and box[2] * box[3] < 0.5 * g[2] * g[3]:
            return "fragment"
    if best >= 0.3:
        return "loose"
    if any(iou(box, p) >= 0.3 for p in first_people):
        return "ghost"
    return "other"


def holds_people(box, gt) -> int:
    """How many people have at least half of their box inside ``box``."""
    return sum(_inside(g, box) >= 0.5 for g in gt)


def miss_cause(person, det, scale, false_boxes, group_boxes, fg_share) -> str:
    if det.last_mode != "tracking" or det.mask is None:
        return "start-up"
    x0, y0 = int(person[0] * scale), int(person[1] * scale)
    x1, y1 = int(np.ceil((person[0] + person[2]) * scale)), int(np.ceil(
        (person[1] + person[3]) * scale))
    patch = det.mask[max(y0, 0):max(y1, 0), max(x0, 0):max(x1, 0)]
    if patch.size == 0 or patch.mean() < fg_share:
        return "no foreground"
    if any(_inside(person, box) >= 0.5 for box in group_boxes):
        return "in a merged box"
    for cause, box in false_boxes:
        if cause == "fragment" and _inside(box, person) >= 0.5:
            return "fragmented"
        if cause == "loose" and iou(box, person) >= 0.3:
            return "loose box"
    return "foreground, no box"


def diagnose(frames, truth, fps, config, early: int, fg_share: float):
    det = RecordingDetector(config)
    bootstrap = max(config.bootstrap_frames, 1)
    if config.counts_fps > 0:                  # the bootstrap frames at this frame rate
        bootstrap = max(1, int(np.floor(bootstrap * fps / config.counts_fps + 0.5)))
    first = [p for k in range(min(bootstrap, len(truth))) for p in truth[k]]
    false = {r: Counter() for r in ("start-up", "later")}
    missed = {r: Counter() for r in ("start-up", "later")}
    people = Counter()
    rows = []           # (matched, cause, above / inside / below, box h, expected h, person h)
    for k, img in enumerate(frames):
        det.mask = None
        seen = det.heights.rows
        boxes = [d.box for d in det.process(img, k / fps, encoding="bgr8")]
        scale = min(1.0, config.max_width / float(img.shape[1]))
        gt = truth[k]
        pairs = matches(gt, boxes)
        hit_gt, hit_box = {i for i, _ in pairs}, {j for _, j in pairs}
        span = "start-up" if k < early else "later"
        people[span] += len(gt)
        bad = [(false_cause(b, gt, first), b) for j, b in enumerate(boxes)
               if j not in hit_box]
        false[span].update(c for c, _ in bad)
        if seen is not None:
            causes = dict(enumerate(false_cause(b, gt, first) if j not in hit_box
                                    else "(matched)" for j, b in enumerate(boxes)))
            for j, b in enumerate(boxes):
                rows.append(_row_record(b, gt, seen, det, causes[j]))
        false[span]["(matched)"] += len(hit_box)
        groups = [b for b in boxes if holds_people(b, gt) >= 2]
        missed[span].update(miss_cause(g, det, scale, bad, groups, fg_share)
                            for i, g in enumerate(gt) if i not in hit_gt)
        missed[span]["(matched)"] += len(hit_gt)
    return false, missed, people, rows


def _row_record(box, gt, seen, det, cause):
    """Where ``box``'s bottom row lies against the feet rows of the size samples learnt
    before this frame (``seen``: their min and max), the height the model expects there,
    and the height of the person the box lies most inside."""
    bottom = box[1] + box[3]
    where = "above" if bottom < seen[0] else "below" if bottom > seen[1] else "inside"
    expected = det.heights.height_at(bottom)
    host = max(gt, key=lambda g: _inside(box, g), default=None)
    person = host[3] if host is not None and _inside(box, host) >= 0.5 else float("nan")
    return cause, where, box[3], float("nan") if expected is None else expected, person


def row_lines(name, rows) -> list[str]:
    """Boxes by cause and by where their bottom row lies against the learnt feet rows."""
    out = []
    for cause in ("(matched)",) + FALSE:
        for where in ("above", "inside", "below"):
            sel = [r for r in rows if r[0] == cause and r[1] == where]
            if not sel:
                continue
            box_h, exp_h, person_h = (np.array([r[k] for r in sel]) for k in (2, 3, 4))
            ratio = box_h / person_h
            out.append(f"| {name} | {cause} | {where} | {len(sel)} | {np.median(box_h):.0f} | "
                       f"{np.nanmedian(exp_h):.0f} | "
                       + (f"{np.nanmedian(person_h):.0f} | {np.nanmedian(ratio):.2f}"
                          if np.isfinite(person_h).any() else "- | -") + " |")
    return out


def _row(counter: Counter, keys) -> str:
    return " | ".join(str(counter[k]) for k in keys)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE",
                        help="background.* settings changed from the defaults")
    parser.add_argument("--early", type=int, default=None,
                        help="start-up frames counted apart (default: 1 s of frames)")
    parser.add_argument("--low-fps", action="store_true",
                        help="the real 6.25-fps checks instead of the benchmark's sequences")
    parser.add_argument("--fg", type=float, default=0.15)
    parser.add_argument("--real-only", action="store_true")
    parser.add_argument("--rows", action="store_true",
                        help="also every box by where its bottom row lies against the feet "
                        "rows the height model was fitted on")
    args = parser.parse_args(argv)
    changes = {k: yaml.safe_load(v) for k, v in (s.split("=", 1) for s in args.set)}
    config = BackgroundDetectorConfig(**changes)
    with tempfile.TemporaryDirectory() as tmp:
        sequences = (load_low_fps_checks(Path(tmp)) if args.low_fps
                     else load_sequences(Path(tmp)))
    print(f"settings: defaults {changes or ''}\n")
    print("| sequence | frames | people | false boxes: matched | " + " | ".join(FALSE)
          + " || misses: matched | " + " | ".join(MISSED) + " |")
    print("|---|---|---|---|" + "---|" * len(FALSE) + "---|" + "---|" * len(MISSED))
    row_table = []
    for name, _bag, frames, truth, fps, real in sequences:
        if args.real_only and not real:
            continue
        early = args.early if args.early is not None else int(round(fps))
        false, missed, people, rows = diagnose(frames, truth, fps, config, early, args.fg)
        row_table += row_lines(name, rows)
        for span in ("start-up", "later"):
            n = early if span == "start-up" else len(frames) - early
            print(f"| {name} | {span} ({n}) | {people[span]} | "
                  f"{false[span]['(matched)']} | {_row(false[span], FALSE)} || "
                  f"{missed[span]['(matched)']} | {_row(missed[span], MISSED)} |", flush=True)
    if args.rows:
        print("\nBoxes after the first size samples, by where their bottom row lies against "
              "the feet rows learnt so far (min-max); medians: the box's height, the model's "
              "expected height at its bottom row, the height of the person it lies in (at "
              "least half inside) and the box over that person (px, full image)\n")
        print("| sequence | box | bottom row | boxes | box h | expected h | person h | "
              "box / person |\n|---|---|---|---|---|---|---|---|")
        print("\n".join(row_table))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
