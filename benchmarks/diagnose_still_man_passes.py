"""Why ``detector.still_people`` reports the man at the back left of BU-TIV-lab only from
frame 366 (issue #19): at every full-frame pass, the warm region that holds most of his
box's warm pixels and the first test of the rule it fails.

    .venv/bin/python benchmarks/diagnose_still_man_passes.py [--params FILE ...]

Runs the pipeline of ``mk_tracker process`` on the clip (counter masked, as
``diagnose_reacquire.capture``) with :meth:`StillPeople._find` wrapped: before the rule
looks at a full pass, the wrapper labels the same mask (this pass's warm pixels, or with
``persistent_passes`` the pixels warm at this and the previous passes) and explains the
region on the man (:func:`explain`); after it, it prints the rule's region on him and the
time it has been found in place (reported once that reaches ``min_time``).  Reasons, in
the rule's order: ``border``, ``shape`` (not an upright person: the man's warm pixels join
a neighbour's), ``height``, ``overlap`` (a detection of this frame covers the region at
``max_iou``), ``warmth``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from diagnose_reacquire import DEFAULT_CLIP, capture  # noqa: E402
from diagnose_still_man import MAN  # noqa: E402
from mk_tracker.boxes import iou  # noqa: E402
from mk_tracker.detection import still_people as sp  # noqa: E402
from mk_tracker.detection.person_size import is_person_shaped  # noqa: E402


def explain(mask: np.ndarray, frame: np.ndarray, background: float, target, boxes,
            people: float, tall: float, config, aspect: float):
    """The connected region (8-neighbours) of ``mask`` holding most of ``target``'s mask
    pixels, as ``(box, reasons)``: the tests of :meth:`StillPeople._find` it fails, in
    that order (empty: a candidate).  ``(None, ["no warm pixel"])`` if the box has none."""
    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8),
                                                           connectivity=8)
    x, y, w, h = (int(v) for v in target)
    inside = labels[y:y + h, x:x + w]
    ks, counts = np.unique(inside[inside > 0], return_counts=True)
    if not len(ks):
        return None, ["no warm pixel"]
    k = int(ks[np.argmax(counts)])
    bx, by, bw, bh, _ = (int(v) for v in stats[k])
    box = (float(bx), float(by), float(bw), float(bh))
    rows, cols = mask.shape
    reasons = []
    if bx <= 0 or by <= 0 or bx + bw >= cols or by + bh >= rows:
        reasons.append("border")
    if not is_person_shaped(bw, bh, aspect):
        reasons.append(f"shape (w/h {bw / bh:.2f})")
    if not config.min_height_ratio * tall <= bh <= config.max_height_ratio * tall:
        reasons.append(f"height ({bh} px, people {tall:.0f})")
    overlap = max((iou(box, b) for b in boxes), default=0.0)
    if overlap >= config.max_iou:
        reasons.append(f"overlap ({overlap:.2f})")
    warmth = float(frame[labels == k].mean()) - background
    if warmth < config.min_warmth * people:
        reasons.append(f"warmth ({warmth:.0f} < {config.min_warmth * people:.0f})")
    return box, reasons


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clip", type=Path, default=DEFAULT_CLIP)
    parser.add_argument("--params", type=Path, nargs="*", default=[])
    parser.add_argument("--fps", type=float, default=30.0)
    args = parser.parse_args(argv)
    rows: list[tuple] = []
    original = sp.StillPeople._find

    def find(self, frame, background, radius, boxes, stamp):
        people, tall = self.people_warmth, self.people_height
        masks = list(self._warm_masks)            # before the rule appends this pass's
        mask = frame > background + radius
        for m in masks if all(m.shape == mask.shape for m in masks) else []:
            mask = mask & m
        box, reasons = (None, ["no person learnt yet"]) if people is None or tall is None \
            else explain(mask, frame, background, MAN, boxes, people, tall, self.config,
                         self.person_aspect)
        original(self, frame, background, radius, boxes, stamp)
        mine = max(self._regions, key=lambda r: iou(r.box, MAN), default=None)
        held = None if mine is None or iou(mine.box, MAN) < 0.3 else stamp - mine.since
        rows.append((stamp, box, reasons, held))

    sp.StillPeople._find = find
    try:
        inputs, figures = capture(args.clip, True, args.params)
    finally:
        sp.StillPeople._find = original
    t0 = inputs[0][1]
    print("| frame | region on the man | IoU with him | fails | "
          "rule's region on him: s in place |")
    print("|---:|---|---:|---|---:|")
    for stamp, box, reasons, held in rows:
        where = "-" if box is None else "({:.0f}, {:.0f}, {:.0f}, {:.0f})".format(*box)
        print(f"| {round((stamp - t0) * args.fps)} | {where} | "
              f"{0.0 if box is None else iou(box, MAN):.2f} | {', '.join(reasons) or '-'} | "
              f"{'-' if held is None else f'{held:.1f}'} |")
    print(f"\npipeline: {figures['ids']} ids, {figures['duplicates']:.2f} duplicate pairs and "
          f"{figures['tracks']:.2f} tracks per frame")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
