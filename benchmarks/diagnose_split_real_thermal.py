"""Why a detector split costs ids on BU-TIV-lab (issues #15 / #19): the splits drawn, and
what the tracker does with the tracks born on their parts.

Two parts, on the clip with its burned-in counter masked (``bench_real_thermal``'s
region), the detector being the shipped defaults then the ``--params`` files:

1. **The splits.**  The detector alone runs over the clip; every full-frame pass in which
   ``split_by_person_size`` cut a footprint into parts is listed (frame, part boxes, the
   expected person height at the footprint's bottom row, how many of the last pass's
   Kalman predictions (Algorithm 2's per-object filters) lie in the parts' union box grown
   by ``window_margin``).  Six of those frames, evenly spread, are drawn with the parts
   (green) and the predictions (red) into ``--image``.
2. **The tracks.**  The whole pipeline (``mk_tracker process``'s code, as
   ``bench_real_thermal`` runs it) gives, per track id: the frames it was reported in,
   how many of those no detection overlaps at IoU >= 0.3, and whether it was born on a box
   overlapping an older track at IoU > 0.3.  Summed: the share of reported boxes without a
   detection (tracks kept by the still-person and recovery rules).  Frames 120, 300 and
   540 are drawn with the detections (thin white) and the reported tracks into
   ``--tracks-image``.

Not a test: nothing is asserted.

    nice -n 10 .venv/bin/python benchmarks/diagnose_split_real_thermal.py \\
        --params <file with detector.split_by_person_size: true> --image out/splits.jpg \\
        --tracks-image out/split_tracks.jpg
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_real_thermal import COUNTER_REGION, DEFAULT_CLIP, run_pipeline  # noqa: E402

from mk_tracker.bags.recording_import import import_recording, open_recording  # noqa: E402
from mk_tracker.boxes import iou_matrix  # noqa: E402
from mk_tracker.drawing.debug_image import TrackDrawing, draw_tracks  # noqa: E402
from mk_tracker.detection.ignore_regions import MaskedDetector, parse_regions  # noqa: E402
from mk_tracker.detection.thermal_detector import ThermalDetector  # noqa: E402
from mk_tracker.tools.pipeline_config import load_pipeline_config  # noqa: E402

TILE = 256
TRACK_FRAMES = (120, 300, 540)


def _write(path: Path, tiles: list[np.ndarray]) -> None:
    """``tiles`` three to a row (JPEG when ``path`` ends so: small enough for docs/)."""
    while len(tiles) % 3:
        tiles.append(np.zeros_like(tiles[0]))
    rows = [np.hstack(tiles[i:i + 3]) for i in range(0, len(tiles), 3)]
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), np.vstack(rows), [cv2.IMWRITE_JPEG_QUALITY, 80])
    print(f"wrote {path}")


class _RecordingDetector(ThermalDetector):
    """The thermal detector, noting each size split of a full-frame pass."""

    frame_index = -1

    def __init__(self, config) -> None:
        super().__init__(config)
        self.splits: list[tuple[int, list, np.ndarray, float | None]] = []

    def _size_candidates(self, frame, result, rows, cols, bounds, footprint):
        out = super()._size_candidates(frame, result, rows, cols, bounds, footprint)
        if len(out) > 1:
            bottom = max(c.box[1] + c.box[3] for c in out)
            self.splits.append((self.frame_index, [c.box for c in out],
                                self._predictions()[:, :2].copy(),
                                self.heights.height_at(bottom)))
        return out


def _inside(boxes: list, points: np.ndarray, margin: float) -> int:
    x0 = min(b[0] for b in boxes) - margin
    y0 = min(b[1] for b in boxes) - margin
    x1 = max(b[0] + b[2] for b in boxes) + margin
    y1 = max(b[1] + b[3] for b in boxes) + margin
    return int(np.sum((points[:, 0] >= x0) & (points[:, 0] <= x1)
                      & (points[:, 1] >= y0) & (points[:, 1] <= y1)))


def splits(clip: Path, params: list[Path], image: Path | None) -> None:
    config = load_pipeline_config(params).detector
    det = _RecordingDetector(config)
    masked = MaskedDetector(det, parse_regions(list(COUNTER_REGION)))
    source = open_recording(clip, None)
    frames: dict[int, np.ndarray] = {}
    for k, frame in enumerate(source.frames()):
        grey = np.ascontiguousarray(frame if frame.ndim == 2 else frame[..., 1])
        det.frame_index = k
        before = len(det.splits)
        masked.process(grey, k / source.fps, encoding="mono8")
        if len(det.splits) > before:
            frames[k] = grey
    print(f"full-frame passes {det.full_passes}, footprints split {len(det.splits)} "
          f"(in {len(frames)} passes)")
    print("| frame | parts (x, y, w, h) | expected height at the bottom row | predictions "
          "inside |")
    print("|---:|---|---:|---:|")
    for k, boxes, preds, expected in det.splits:
        parts = ", ".join(str(tuple(int(v) for v in b)) for b in boxes)
        h = "-" if expected is None else f"{expected:.0f}"
        print(f"| {k} | {parts} | {h} | {_inside(boxes, preds, config.window_margin)} |")
    if image is None or not frames:
        return
    chosen = sorted(frames)[::max(1, len(frames) // 6)][:6]
    tiles = []
    for k in chosen:
        canvas = cv2.cvtColor(frames[k], cv2.COLOR_GRAY2BGR)
        for kk, boxes, preds, _ in det.splits:
            if kk != k:
                continue
            for x, y, w, h in (tuple(int(v) for v in b) for b in boxes):
                cv2.rectangle(canvas, (x, y), (x + w, y + h), (0, 255, 0), 2)
            for px, py in preds:
                cv2.circle(canvas, (int(px), int(py)), 6, (0, 0, 255), -1)
        cv2.putText(canvas, f"frame {k}", (120, 30), cv2.FONT_HERSHEY_SIMPLEX, 0.8,
                    (0, 255, 255), 2)
        tiles.append(cv2.resize(canvas, (TILE, TILE)))
    _write(image, tiles)


def tracks(clip: Path, params: list[Path], image: Path | None) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        import_recording(open_recording(clip, None), tmp / "bag", thermal=True)
        per_frame, dets, _ = run_pipeline(tmp / "bag", tmp / "run", COUNTER_REGION,
                                          tuple(params))
    first: dict[int, int] = {}
    last: dict[int, int] = {}
    shown: dict[int, int] = {}
    alone: dict[int, int] = {}
    over: dict[int, bool] = {}
    for k, (frame, found) in enumerate(zip(per_frame, dets)):
        boxes = np.array([d[:4] for d in found], dtype=np.float64).reshape(-1, 4)
        for tid, box in frame:
            b = np.array([box], dtype=np.float64)
            if tid not in first:
                first[tid] = k
                older = np.array([bb for t, bb in frame if t != tid and t in first
                                  and first[t] < k], dtype=np.float64).reshape(-1, 4)
                over[tid] = bool(len(older) and iou_matrix(b, older).max() > 0.3)
            last[tid] = k
            shown[tid] = shown.get(tid, 0) + 1
            covered = len(boxes) and iou_matrix(b, boxes).max() >= 0.3
            alone[tid] = alone.get(tid, 0) + (0 if covered else 1)
    print(f"\ndistinct ids {len(first)}")
    print("| id | frames | reported | without a detection (IoU >= 0.3) | born over an older "
          "track |")
    print("|---:|---|---:|---:|---|")
    for tid in sorted(first, key=first.get):
        print(f"| {tid} | {first[tid]}-{last[tid]} | {shown[tid]} | {alone[tid]} | "
              f"{'yes' if over[tid] else 'no'} |")
    total = sum(shown.values())
    print(f"\nreported boxes {total}, without a detection {sum(alone.values())} "
          f"({sum(alone.values()) / max(total, 1):.2f})")
    if image is None:
        return
    tiles = []
    for k, frame in enumerate(open_recording(clip, None).frames()):
        if k not in TRACK_FRAMES or k >= len(per_frame):
            continue
        grey = np.ascontiguousarray(frame if frame.ndim == 2 else frame[..., 1])
        canvas = cv2.cvtColor(grey, cv2.COLOR_GRAY2BGR)
        for x, y, w, h in (tuple(int(v) for v in d[:4]) for d in dets[k]):
            cv2.rectangle(canvas, (x, y), (x + w, y + h), (255, 255, 255), 1)
        canvas = draw_tracks(canvas, [TrackDrawing(b, tid, "confirmed", 1.0, ())
                                      for tid, b in per_frame[k]])
        cv2.putText(canvas, f"frame {k}", (120, 30), cv2.FONT_HERSHEY_SIMPLEX, 0.8,
                    (0, 255, 255), 2)
        tiles.append(cv2.resize(canvas, (TILE, TILE)))
    if tiles:
        _write(image, tiles)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clip", type=Path, default=DEFAULT_CLIP)
    parser.add_argument("--params", type=Path, nargs="*", default=[],
                        help="parameter files applied over the defaults")
    parser.add_argument("--image", type=Path, default=None, help="strip of split frames")
    parser.add_argument("--tracks-image", type=Path, default=None,
                        help="strip of frames with the reported tracks")
    parser.add_argument("--no-tracks", action="store_true", help="skip the pipeline run")
    args = parser.parse_args(argv)
    if not args.clip.exists():
        print(f"{args.clip} not found", file=sys.stderr)
        return 1
    splits(args.clip, args.params, args.image)
    if not args.no_tracks:
        tracks(args.clip, args.params, args.tracks_image)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
