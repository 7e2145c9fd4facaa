"""Real thermal video (issue #19): the detector and the tracker on BU-TIV-lab, figures that
need no ground truth, beside IoU peers fed the same detections.

    .venv/bin/python benchmarks/bench_real_thermal.py --out docs/benchmark_real_thermal.md

The clip (../shared/data/thermal/BU-TIV-lab, ~7 people, 562 frames, 512x512, 30 fps) is
imported with the project's own import (thermal-only bag) and processed by ``mk_tracker
process``'s code twice: as it is, and with the burned-in frame counter covered by an ignore
region.  Reported per run: detections per frame, published tracks per frame, distinct track
ids (against ~7 people), pairs of tracks overlapping at IoU > 0.5 per frame (duplicates),
and the detector's CPU time per frame.  The peers (SORT-style, norfair, and ByteTrack /
OC-SORT / motpy when installed) get the masked run's detections frame by frame.  A strip
of annotated frames is written to docs/images/real_thermal_frames.png.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from mk_tracker.bags.bag_io import open_bag  # noqa: E402
from mk_tracker.bags.recording_import import import_recording, open_recording  # noqa: E402
from mk_tracker.drawing.debug_image import TrackDrawing, draw_tracks  # noqa: E402
from mk_tracker.evaluation.identity_figures import identity_figures as figures  # noqa: E402
from mk_tracker.frame_processing import build_detector  # noqa: E402
from mk_tracker.messages.detection_messages import read_detection_array  # noqa: E402
from mk_tracker.messages.image_conversion import image_to_numpy  # noqa: E402
from mk_tracker.messages.message_types import stamp_to_nanoseconds  # noqa: E402
from mk_tracker.tools.pipeline import PipelineOptions, process_bag  # noqa: E402
from mk_tracker.tools.pipeline_config import load_pipeline_config  # noqa: E402

DEFAULT_CLIP = ROOT.parent / "shared" / "data" / "thermal" / "BU-TIV-lab" / "BU-TIV-lab.mp4"
#: the burned-in counter (about 90x40 px at the top left, README of the data) with a margin
COUNTER_REGION = (0.0, 0.0, 110.0, 50.0)
STRIP_FRAMES = (150, 420, 540)


def detector_ms(bag: Path, regions: tuple, extra: tuple = ()) -> float:
    """Median CPU time (ms) of the detector (defaults, then the ``extra`` parameter files)
    on one frame of ``bag``."""
    cfg = load_pipeline_config(list(extra))
    det = build_detector(cfg.method, cfg.detector, cfg.threshold, regions)
    times = []
    with open_bag(bag) as reader:
        for m in reader.messages(["/thermal/image_raw"]):
            msg = reader.deserialize(m)
            frame = image_to_numpy(msg)
            t0 = time.thread_time()
            det.process(frame, m.timestamp_ns * 1e-9, encoding=msg.encoding)
            times.append(time.thread_time() - t0)
    return 1000.0 * float(np.median(times[10:] or times))


def frame_height(bag: Path) -> int:
    """Rows of the first thermal image of ``bag``."""
    with open_bag(bag) as reader:
        for m in reader.messages(["/thermal/image_raw"]):
            return int(reader.deserialize(m).height)
    return 0


def run_pipeline(bag: Path, out: Path, regions: tuple, extra: tuple = ()
                 ) -> tuple[list, list, list[int]]:
    params = out.parent / f"{out.name}.yaml"
    flat = ", ".join(str(v) for v in regions) if regions else "0.0, 0.0, 0.0, 0.0"
    params.write_text(f"detector_node:\n  ros__parameters:\n    ignore_regions: [{flat}]\n")
    result = process_bag(bag, out, config=load_pipeline_config([*extra, params]),
                         options=PipelineOptions(progress=False, write_video=False,
                                                 write_plots=False))
    stamps = sorted(result.frame_stamps) or sorted(result.tracks)
    tracks = [list(result.tracks.get(ns, [])) for ns in stamps]
    dets_by_ns: dict[int, list] = {}
    with open_bag(out / "bag") as reader:
        for m in reader.messages(["/thermal/detections"]):
            msg = reader.deserialize(m)
            dets_by_ns[stamp_to_nanoseconds(msg.header.stamp)] = [
                (*d.box, d.score) for d in read_detection_array(msg)]
    detections = [dets_by_ns.get(ns, []) for ns in stamps]
    return tracks, detections, stamps


class EveryNth:
    """A frame source (:class:`~mk_tracker.bags.video_source.FrameSource`) that keeps every
    ``step``-th frame from frame ``offset`` on, at ``1 / step`` of the rate."""

    def __init__(self, source, step: int, offset: int = 0) -> None:
        self.source, self.step, self.offset = source, step, offset
        self.path, self.kind = source.path, source.kind
        self.fps = source.fps / step
        self.declared = -(-max(source.declared - offset, 0) // step)
        self.unreadable = 0

    def frames(self):
        for k, frame in enumerate(self.source.frames()):
            if k >= self.offset and (k - self.offset) % self.step == 0:
                yield frame
        self.unreadable = self.source.unreadable


def peers(fps: float) -> dict:
    from peers.norfair_peer import NorfairPeer
    from peers.sort_tracker import SortTracker
    out = {"SORT-style (Kalman + IoU)": lambda: SortTracker(),
           "norfair (IoU)": lambda: NorfairPeer()}
    try:
        from peers.trackers_peers import MotpyPeer, TrackersPeer
        import trackers  # noqa: F401
        out["ByteTrack (trackers 2.6.1)"] = lambda: TrackersPeer("bytetrack", fps)
        out["OC-SORT (trackers 2.6.1)"] = lambda: TrackersPeer("ocsort", fps)
        out["motpy"] = lambda: MotpyPeer(fps)
    except ImportError as exc:
        print(f"ByteTrack/OC-SORT/motpy not installed ({exc}); skipped", file=sys.stderr)
    return out


def strip(bag: Path, tracks: list, stamps: list[int], path: Path) -> None:
    wanted = {stamps[k]: k for k in STRIP_FRAMES if k < len(stamps)}
    tiles = []
    with open_bag(bag) as reader:
        for m in reader.messages(["/thermal/image_raw"]):
            if m.timestamp_ns not in wanted:
                continue
            msg = reader.deserialize(m)
            grey = image_to_numpy(msg)
            canvas = cv2.cvtColor(grey, cv2.COLOR_GRAY2BGR)
            k = wanted[m.timestamp_ns]
            canvas = draw_tracks(canvas, [TrackDrawing(b, tid, "confirmed", 1.0, ())
                                          for tid, b in tracks[k]])
            cv2.putText(canvas, f"frame {k}", (120, 30), cv2.FONT_HERSHEY_SIMPLEX, 0.8,
                        (0, 255, 255), 2)
            tiles.append(cv2.resize(canvas, (384, 384)))
    if tiles:
        path.parent.mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(path), np.hstack(tiles))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clip", type=Path, default=DEFAULT_CLIP)
    parser.add_argument("--out", type=Path, default=None, help="markdown report to write")
    parser.add_argument("--params", type=Path, nargs="*", default=[],
                        help="parameter files applied over the defaults (ablations)")
    parser.add_argument("--frame-step", type=int, default=1,
                        help="keep every N-th frame (the clip at 1/N of its frame rate: "
                        "a slower camera)")
    parser.add_argument("--frame-offset", type=int, default=0,
                        help="with --frame-step N: start at this frame (0..N-1), another "
                        "sampling of the same clip")
    parser.add_argument("--masked-only", action="store_true",
                        help="only the run with the counter masked (ablations)")
    args = parser.parse_args(argv)
    if not args.clip.exists():
        print(f"{args.clip} not found", file=sys.stderr)
        return 1
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        source = open_recording(args.clip, None)
        if args.frame_step > 1 or args.frame_offset:
            source = EveryNth(source, max(args.frame_step, 1), args.frame_offset)
        bag = tmp / "bag"
        import_recording(source, bag, thermal=True)
        masked = None
        for label, regions in (("as it is", ()), ("counter masked", COUNTER_REGION)):
            if args.masked_only and not regions:
                continue
            t0 = time.perf_counter()
            tracks, dets, stamps = run_pipeline(bag, tmp / label.replace(" ", "_"), regions,
                                                tuple(args.params))
            wall = time.perf_counter() - t0
            f = figures(tracks, dets)
            f["detector_ms"] = detector_ms(bag, regions, tuple(args.params))
            rows_px = frame_height(bag)
            f["taller"] = sum(float(b[3]) > rows_px for frame in tracks for _, b in frame)
            rows.append((f"kernel covariance -> ours ({label})", f, wall))
            print(rows[-1], file=sys.stderr)
            masked = (tracks, dets, stamps)
        tracks, dets, stamps = masked
        for name, factory in peers(source.fps).items():
            tracker = factory()
            peer_tracks = [tracker.update(ns * 1e-9, d) for ns, d in zip(stamps, dets)]
            rows.append((f"kernel covariance (counter masked) -> {name}",
                         figures(peer_tracks, dets), float("nan")))
            print(rows[-1], file=sys.stderr)
        if args.out is not None:
            strip(bag, tracks, stamps, ROOT / "docs" / "images" / "real_thermal_frames.png")
    lines = ["| detections -> tracker | detections / frame | tracks / frame | distinct ids "
             "(~7 people) | duplicate pairs (IoU > 0.5) / frame | detector CPU ms / frame | "
             "reported boxes taller than the frame |",
             "|---|---|---|---|---|---|---|"]
    for name, f, _ in rows:
        ms = f"{f['detector_ms']:.1f}" if "detector_ms" in f else "-"
        lines.append(f"| {name} | {f['detections']:.2f} | {f['tracks']:.2f} | {f['ids']} | "
                     f"{f['duplicates']:.2f} | {ms} | {f.get('taller', '-')} |")
    table = "\n".join(lines)
    print(table)
    if args.out is not None:
        args.out.write_text(
            "# Real thermal video: BU-TIV-lab (issue #19)\n\nProduced by:\n\n```\n"
            ".venv/bin/python benchmarks/bench_real_thermal.py --out "
            "docs/benchmark_real_thermal.md\n```\n\n"
            f"Clip: `{args.clip.name}`, {len(stamps)} frames, imported with `mk_tracker import "
            "--thermal` and processed thermal-only (the tracker follows the thermal image). "
            f"Ignore region for the counter: {list(COUNTER_REGION)}. No ground truth: the "
            "figures are those of the issue (about 7 people, 4-6 visible at a time). "
            "Peers see the masked run's detections and report only the boxes they matched; "
            "people who stop after walking are not detected, so peers drop them.\n\n"
            f"{table}\n\n![tracks on frames {', '.join(map(str, STRIP_FRAMES))}]"
            "(images/real_thermal_frames.png)\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
