"""Where every distinct id of a BU-TIV-lab run comes from (issue #19, identity): one row per
reported id with its lifetime, how it was seen, where it was born and whether it is the
re-birth of a person who already had an id.

    .venv/bin/python benchmarks/diagnose_ids.py --cache out/lab_inputs.pkl [--set NAME=VALUE ...]
    .venv/bin/python benchmarks/diagnose_ids.py --unmasked --cache out/lab_inputs_unmasked.pkl
    .venv/bin/python benchmarks/diagnose_ids.py --params split.yaml --cache out/lab_split.pkl

The tracker's inputs are captured once (the pipeline of ``mk_tracker process``, counter
masked unless ``--unmasked``, plus any ``--params`` files, e.g. a detector split) and kept
in ``--cache``; the tracker is then replayed on them (the same figures as the pipeline, see
``diagnose_reacquire.py``).  Columns per id:

* ``born`` / ``first`` / ``last``: the frame the track was created (tentative), first and
  last reported; ``frames``: frames reported; ``det``: share of those frames in which a
  detection overlaps its box at IoU >= 0.3; ``still``: share in which the track moved slower
  than ``lifecycle.still_speed``;
* ``contrast``: median over its reported frames of ``1 - BC(box, ring)``, the Bhattacharyya
  coefficient between the grey-level histogram (16 bins) of the box and that of a ring of
  0.3 box sizes around it (:mod:`mk_tracker.tracking.background_weighting`): a warm person
  on a cool floor stands out (large), a box on background does not (small);
* ``born on``: the largest IoU of the birth box with a track reported in the frame before;
* ``previous id``: the reported id whose last reported box is nearest to the birth box,
  among ids last reported before this id was first reported: ``gap`` seconds from its last
  report to this id's first, ``dist`` in its box heights, ``sim`` its appearance model on the birth box
  (``Refiner.appearance_similarity``; in thermal every person looks much alike);
* ``kind``: ``first second`` (born in the first second), ``re-birth`` (a previous id within
  ``--near`` heights and ``--max-gap`` seconds, by default ``lifecycle.max_lost_time``),
  ``beside a live track`` (born on a reported box at IoU > 0.1: a second box on a person
  who has one, e.g. the legs under a torso track), ``entering`` (none of these).

``--frames N ...`` also writes those frames with the detections (green) and the reported
ids (red; magenta: slower than ``still_speed``) to ``--image``.
"""

from __future__ import annotations

import argparse
import math
import pickle
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from diagnose_reacquire import DEFAULT_CLIP, capture  # noqa: E402
from mk_tracker.boxes import iou, iou_matrix  # noqa: E402
from mk_tracker.evaluation.identity_figures import identity_figures  # noqa: E402
from mk_tracker.parameters import updated  # noqa: E402
from mk_tracker.tools.pipeline_config import load_pipeline_config  # noqa: E402
from mk_tracker.tracking.multi_object_tracker import MultiObjectTracker  # noqa: E402
from mk_tracker.tracking.tracker_config import MultiObjectTrackerConfig  # noqa: E402
from setting_values import setting_changes  # noqa: E402


def contrast(grey: np.ndarray, box, ring: float = 0.3, bins: int = 16) -> float:
    """``1 - BC`` between the grey-level histograms of ``box`` and of the ring around it."""
    h, w = grey.shape
    x, y, bw, bh = (float(v) for v in box)
    x0, y0 = max(int(x - ring * bw), 0), max(int(y - ring * bh), 0)
    x1, y1 = min(int(x + bw + ring * bw) + 1, w), min(int(y + bh + ring * bh) + 1, h)
    if x1 <= x0 or y1 <= y0:
        return math.nan
    patch = grey[y0:y1, x0:x1].astype(np.int64) * bins // 256
    yy, xx = np.mgrid[y0:y1, x0:x1]
    inside = (xx + 0.5 >= x) & (xx + 0.5 < x + bw) & (yy + 0.5 >= y) & (yy + 0.5 < y + bh)
    a = np.bincount(patch[inside], minlength=bins).astype(float)
    b = np.bincount(patch[~inside], minlength=bins).astype(float)
    if a.sum() <= 0 or b.sum() <= 0:
        return math.nan
    return 1.0 - float(np.sqrt((a / a.sum()) * (b / b.sum())).sum())


def replay(inputs: list, config: MultiObjectTrackerConfig):
    """Replay the tracker; per frame the reported ``[(id, box)]``, and per id its Track."""
    trk = MultiObjectTracker(config)
    reported, tracks, born = [], {}, {}
    for k, (image, stamp, dets) in enumerate(inputs):
        if image.ndim == 2:
            image = np.repeat(image[..., None], 3, axis=2)
        result = trk.step(image, stamp, dets)
        for t in trk.tracks:
            tracks[t.id] = t
            born.setdefault(t.id, (k, t.box.copy()))
        still = {t.id: t.is_still() for t in trk.tracks}
        reported.append([(o.id, np.array(o.box), still.get(o.id, False))
                         for o in result.reported()])
    return reported, tracks, born, trk


def id_table(inputs: list, reported: list, tracks: dict, born: dict, refiner,
             near: float, max_gap: float) -> list[dict]:
    t0 = inputs[0][1]
    first, last, boxes = {}, {}, {}
    for k, frame in enumerate(reported):
        for tid, box, still in frame:
            first.setdefault(tid, k)
            last[tid] = k
            boxes.setdefault(tid, []).append((k, box, still))
    rows = []
    for tid in sorted(first):
        kb, birth_box = born[tid]
        seen = boxes[tid]
        det_hits = 0
        for k, box, _ in seen:
            d = np.array([d.box for d in inputs[k][2]], dtype=float).reshape(-1, 4)
            det_hits += int(len(d) and iou_matrix(box[None], d).max() >= 0.3)
        cons = [contrast(_plane(inputs[k][0]), box) for k, box, _ in seen]
        prev = [(r_id, b) for r_id, b, _ in reported[kb - 1]] if kb > 0 else []
        born_on = max((float(iou(birth_box, b)) for _, b in prev), default=0.0)
        best = None
        for oid in first:
            if oid >= tid or first[oid] >= kb or last[oid] >= first[tid]:
                continue
            obox = boxes[oid][-1][1]
            dist = float(np.hypot(*(_centre(birth_box) - _centre(obox)))) / max(obox[3], 1.0)
            if best is None or dist < best[1]:
                best = (oid, dist, inputs[first[tid]][1] - inputs[last[oid]][1])
        sim = math.nan
        if best is not None and refiner is not None and tracks[best[0]].target is not None:
            image = inputs[kb][0]
            image = np.repeat(image[..., None], 3, axis=2) if image.ndim == 2 else image
            try:
                sim = float(refiner.appearance_similarity(image, tracks[best[0]].target,
                                                          tuple(birth_box)))
            except ValueError:
                pass
        if inputs[kb][1] - t0 < 1.0:
            kind = "first second"
        elif best is not None and best[1] <= near and best[2] <= max_gap:
            kind = f"re-birth of {best[0]}"
        elif born_on > 0.1:
            kind = "beside a live track"
        else:
            kind = "entering"
        rows.append({"id": tid, "born": kb, "first": first[tid], "last": last[tid],
                     "frames": len(seen), "det": det_hits / len(seen),
                     "still": sum(s for _, _, s in seen) / len(seen),
                     "contrast": float(np.nanmedian(cons)) if cons else math.nan,
                     "born_on": born_on, "prev": best, "sim": sim, "kind": kind,
                     "x": float(_centre(birth_box)[0]), "y": float(_centre(birth_box)[1])})
    return rows


def _plane(image: np.ndarray) -> np.ndarray:
    return image if image.ndim == 2 else image[..., 0]


def _centre(box) -> np.ndarray:
    return np.array([box[0] + box[2] / 2.0, box[1] + box[3] / 2.0])


def write_frames(inputs: list, reported: list, frames: list[int], path: Path,
                 tile: int = 200) -> None:
    """A strip of ``frames``: detections green, reported ids red (magenta when still)."""
    import cv2
    tiles = []
    for k in frames:
        if not 0 <= k < len(inputs):
            continue
        im = cv2.cvtColor(_plane(inputs[k][0]), cv2.COLOR_GRAY2BGR)
        for d in inputs[k][2]:
            x, y, w, h = (int(v) for v in d.box)
            cv2.rectangle(im, (x, y), (x + w, y + h), (0, 255, 0), 1)
        for tid, b, still in reported[k]:
            x, y, w, h = (int(v) for v in b)
            colour = (255, 0, 255) if still else (0, 0, 255)
            cv2.rectangle(im, (x, y), (x + w, y + h), colour, 2)
            cv2.putText(im, str(tid), (x + 3, y + 18), cv2.FONT_HERSHEY_SIMPLEX, 0.7, colour, 2)
        cv2.putText(im, f"frame {k}", (5, im.shape[0] - 10), cv2.FONT_HERSHEY_SIMPLEX, 0.8,
                    (0, 255, 255), 2)
        tiles.append(cv2.resize(im, (tile, tile), interpolation=cv2.INTER_AREA))
    if tiles:
        path.parent.mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(path), np.hstack(tiles))


def markdown(rows: list[dict]) -> str:
    lines = ["| id | born | first | last | frames | det | still | contrast | born on (IoU) | "
             "birth centre | previous id: gap (s) / dist (h) / sim | kind |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---|---|"]
    for r in rows:
        p = r["prev"]
        prev = "-" if p is None else f"{p[0]}: {p[2]:.1f} / {p[1]:.2f} / {r['sim']:.2f}"
        lines.append(f"| {r['id']} | {r['born']} | {r['first']} | {r['last']} | {r['frames']} "
                     f"| {r['det']:.2f} | {r['still']:.2f} | {r['contrast']:.2f} | "
                     f"{r['born_on']:.2f} | ({r['x']:.0f}, {r['y']:.0f}) | {prev} | "
                     f"{r['kind']} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clip", type=Path, default=DEFAULT_CLIP)
    parser.add_argument("--unmasked", action="store_true", help="no ignore region")
    parser.add_argument("--params", type=Path, nargs="*", default=[],
                        help="parameter files of the capture (e.g. a detector split) and of "
                             "the replay's tracker; give them again with --cache")
    parser.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE",
                        help="tracker settings of the replay (on the capture's config)")
    parser.add_argument("--cache", type=Path, default=None)
    parser.add_argument("--near", type=float, default=1.5)
    parser.add_argument("--max-gap", type=float, default=4.0)
    parser.add_argument("--frames", type=int, nargs="*", default=[])
    parser.add_argument("--image", type=Path, default=Path("out/ids_frames.png"))
    args = parser.parse_args(argv)
    if args.cache is not None and args.cache.is_file():
        with open(args.cache, "rb") as fh:
            inputs, piped = pickle.load(fh)[:2]
    else:
        if not args.clip.exists():
            print(f"{args.clip} not found", file=sys.stderr)
            return 1
        inputs, piped = capture(args.clip, not args.unmasked, args.params)
        if args.cache is not None:
            with open(args.cache, "wb") as fh:
                pickle.dump((inputs, piped), fh)
    # the pipeline's tracker settings: the package's config files and --params
    config = updated(load_pipeline_config(args.params).tracker, setting_changes(args.set))
    reported, tracks, born, trk = replay(inputs, config)
    f = identity_figures([[(i, b) for i, b, _ in fr] for fr in reported])
    print(f"capture: ids {piped['ids']} dup {piped['duplicates']:.2f} tracks "
          f"{piped['tracks']:.2f}; replay: ids {f['ids']} dup {f['duplicates']:.2f} tracks "
          f"{f['tracks']:.2f}", flush=True)
    print(markdown(id_table(inputs, reported, tracks, born, trk.refiner, args.near,
                            args.max_gap)))
    if args.frames:
        write_frames(inputs, reported, args.frames, args.image)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
