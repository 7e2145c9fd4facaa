"""What ``mk_tracker demo`` reads back after the run (:mod:`mk_tracker.tools.demo`, step 3):
the nodes' own statistics from the launch log, the recorded tracks (scored against the
scene's ground truth, drawn into a video and a PNG strip) and the frame-by-frame
comparison with the offline pipeline.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mk_tracker.bags.bag_io import open_bag
from mk_tracker.evaluation.metrics import MotRow, mot_accumulator, mot_metrics, write_mot_file
from mk_tracker.messages.detection_messages import read_detection_array
from mk_tracker.messages.message_types import stamp_to_nanoseconds, stamp_to_seconds
from mk_tracker.synthetic.scene_bag import GROUND_TRUTH_TOPIC, RGB_TOPIC
from mk_tracker.tools.demo_scene import DemoError

STRIP_FILE = "strip.png"
#: frames of the PNG strip and the width of each
STRIP_FRAMES = 4
STRIP_WIDTH = 320


def node_statistics(log_path: Path) -> dict[str, dict]:
    """The ``shutting down: {...}`` statistics each node logged (frames, dropped, ...)."""
    import ast
    import re

    stats: dict[str, dict] = {}
    try:
        text = log_path.read_text(encoding="utf-8", errors="replace")
    except OSError:
        return stats
    for name, body in re.findall(r"\[(\w+_node)\].*shutting down: (\{[^}]*\})", text):
        try:
            stats[name] = ast.literal_eval(body)
        except (ValueError, SyntaxError):
            continue
    return stats


@dataclass
class Agreement:
    frames: int = 0
    missing_online: int = 0
    id_mismatch_frames: int = 0
    max_box_difference: float = 0.0
    first_difference: str = ""

    def agree(self, tolerance: float) -> bool:
        return (self.frames > 0 and self.missing_online == 0 and self.id_mismatch_frames == 0
                and self.max_box_difference <= tolerance)


def read_tracks(bag: Path, topic: str = "/tracks", scores: bool = False
                ) -> dict[int, list[tuple]]:
    """``{header stamp (ns): [(track id, box), ...]}`` of a tracks topic
    (``(track id, box, score)`` with ``scores``)."""
    out: dict[int, list[tuple[int, tuple]]] = {}
    with open_bag(bag, on_error="skip") as reader:
        if topic not in reader.topics:
            return out
        for _, msg in reader.read_messages([topic]):
            dets, _ = read_detection_array(msg, on_error="skip")
            out[stamp_to_nanoseconds(msg.header.stamp)] = [
                (int(d.id), d.box, d.score) if scores else (int(d.id), d.box)
                for d in dets if d.id.lstrip("-").isdigit()]
    return out


def compare_tracks(offline: dict[int, list], online: dict[int, list]) -> Agreement:
    """Frame-by-frame comparison of two ``read_tracks`` results (offline is the reference)."""
    a = Agreement()
    for stamp in sorted(offline):
        a.frames += 1
        if stamp not in online:
            a.missing_online += 1
            a.first_difference = a.first_difference or f"stamp {stamp}: no online tracks"
            continue
        off = dict(offline[stamp])
        on = dict(online[stamp])
        if set(off) != set(on):
            a.id_mismatch_frames += 1
            a.first_difference = a.first_difference or (
                f"stamp {stamp}: ids offline {sorted(off)} online {sorted(on)}")
            continue
        for tid, box in off.items():
            diff = float(np.max(np.abs(np.subtract(box, on[tid])))) if off else 0.0
            a.max_box_difference = max(a.max_box_difference, diff)
    return a


@dataclass(frozen=True)
class _Drawn:
    """A recorded track as :func:`mk_tracker.frame_processing.tracker_debug_image` draws it
    (recorded messages carry no state or kernels)."""

    id: int
    box: tuple
    score: float
    state: str = ""


def strip_indices(frames: int, count: int = STRIP_FRAMES) -> list[int]:
    """Frame indices of the PNG strip: ``count`` evenly spaced from a quarter of the scene
    (past the detector's start-up and the tracks' confirmation) to its last frame."""
    if frames <= 0:
        return []
    picks = np.linspace(frames // 4, frames - 1, min(count, frames))
    return sorted({int(round(v)) for v in picks})


def write_strip(panels: list[np.ndarray], path: Path, width: int = STRIP_WIDTH) -> tuple:
    """The annotated frames side by side, each scaled to ``width`` px wide, 4 px apart, as a
    palette PNG (24-bit if Pillow is missing); returns the PNG's ``(width, height)``."""
    import cv2

    if not panels:
        raise DemoError("no frames for the strip")
    scaled = []
    for panel in panels:
        h = max(1, int(round(panel.shape[0] * width / panel.shape[1])))
        scaled.append(cv2.resize(panel, (width, h), interpolation=cv2.INTER_AREA))
    height = max(p.shape[0] for p in scaled)
    gap = np.full((height, 4, 3), 32, dtype=np.uint8)
    row = []
    for k, p in enumerate(scaled):
        if p.shape[0] < height:
            p = np.vstack([p, np.zeros((height - p.shape[0], width, 3), np.uint8)])
        row += ([gap] if k else []) + [p]
    strip = np.hstack(row)
    try:
        # a 256-colour palette: 2.4x smaller than the 24-bit PNG of these noisy frames
        # (~220 KB instead of ~520 KB for four 320x240 panels), no visible loss
        from PIL import Image

        rgb = Image.fromarray(cv2.cvtColor(strip, cv2.COLOR_BGR2RGB))
        rgb.quantize(colors=256, method=Image.Quantize.MEDIANCUT,
                     dither=Image.Dither.NONE).save(path, format="PNG", optimize=True)
    except ImportError:
        if not cv2.imwrite(str(path), strip, [cv2.IMWRITE_PNG_COMPRESSION, 9]):
            raise DemoError(f"cannot write {path}") from None
    return int(strip.shape[1]), int(strip.shape[0])


def _recorded_detections(recorded: Path) -> dict[int, list]:
    from mk_tracker.tracking.multi_object_tracker import FrameDetection

    out: dict[int, list] = {}
    with open_bag(recorded, on_error="skip") as reader:
        if "/thermal/detections" not in reader.topics:
            return out
        for _, msg in reader.read_messages(["/thermal/detections"]):
            out[stamp_to_nanoseconds(msg.header.stamp)] = [
                FrameDetection(d.box, d.score, stamp_to_seconds(msg.header.stamp), "thermal")
                for d in read_detection_array(msg, on_error="skip")[0]]
    return out


def render_online(scene_bag: Path, recorded: Path, out: Path, homography: Any,
                  fps: float, frames: int, error_plot: bool = True) -> dict[str, Any]:
    """Score the recorded ``/tracks`` and write their MOT file, video, PNG strip and
    (``error_plot``; importing matplotlib alone takes seconds) the per-frame error plot.
    The scene bag is read once, frame by frame (a 640x480 scene does not fit in memory
    comfortably).  A frame without a ``/tracks`` message (the tracker dropped it,
    or it was lost) has no hypotheses: its people count as misses."""
    from mk_tracker.drawing.video_output import VideoOutput
    from mk_tracker.frame_processing import tracker_debug_image, tracker_input

    out.mkdir(parents=True, exist_ok=True)
    tracks = read_tracks(recorded, scores=True)
    dets = _recorded_detections(recorded)
    h = np.asarray(homography, dtype=float).reshape(3, 3)
    wanted = set(strip_indices(frames))
    panels: list[np.ndarray] = []
    stamps: list[int] = []
    truth_rows: list[MotRow] = []
    rows: list[MotRow] = []
    pending: dict[int, tuple[int, Any]] = {}     # stamp -> (frame index, RGB message)
    truth: dict[int, list] = {}

    def draw(ns: int, video: VideoOutput) -> None:
        index, msg = pending.pop(ns)
        people = truth.pop(ns, [])
        truth_rows.extend(MotRow(index + 1, int(d.id), d.box) for d in people)
        boxes = [d.box for d in people]
        drawn = [_Drawn(tid, box, score) for tid, box, score in tracks.get(ns, [])]
        canvas = tracker_debug_image(
            tracker_input(msg), drawn, {}, dets.get(ns, []), h,
            [f"frame {index + 1}  tracks {len(drawn)}"
             + ("" if ns in tracks else "  (no /tracks message: dropped)")],
            ground_truth=boxes)
        video.write(canvas)
        if index in wanted:
            panels.append(canvas)

    with VideoOutput(out / "video.mp4", fps=fps) as video, open_bag(scene_bag) as reader:
        for m, msg in reader.read_messages([RGB_TOPIC, GROUND_TRUTH_TOPIC]):
            ns = stamp_to_nanoseconds(msg.header.stamp)
            if m.topic == RGB_TOPIC:
                index = len(stamps)
                stamps.append(ns)
                pending[ns] = (index, msg)
                rows += [MotRow(index + 1, tid, box, score)
                         for tid, box, score in tracks.get(ns, [])]
            else:
                truth[ns] = read_detection_array(msg)
            if ns in pending and ns in truth:
                draw(ns, video)
        for ns in sorted(pending):                      # frames without ground truth
            draw(ns, video)
        video_frames = video.frames
    write_mot_file(out / "tracks.txt", rows)
    files = {"tracks": str(out / "tracks.txt"), "video": str(out / "video.mp4")}
    strip = None
    if panels:
        strip = write_strip(panels, out / STRIP_FILE)
        files["strip"] = str(out / STRIP_FILE)
    metrics = mot_metrics(truth_rows, rows)
    tracked = {i + 1 for i, ns in enumerate(stamps) if ns in tracks}
    metrics_tracked = mot_metrics([r for r in truth_rows if r.frame in tracked],
                                  [r for r in rows if r.frame in tracked]) if tracked else {}
    if error_plot:
        from mk_tracker.evaluation.error_plots import (ErrorPlotError, mot_frame_errors,
                                                       plot_mot_errors)
        try:
            acc = mot_accumulator(truth_rows, rows, frames=range(1, len(stamps) + 1))
            plot_mot_errors(mot_frame_errors(acc), out / "errors.png",
                            title="online (nodes over DDS): per-frame errors")
            files["plot"] = str(out / "errors.png")
        except ErrorPlotError:
            pass
    return {"frames": len(stamps), "frames_with_tracks_message": len(tracked),
            "detection_messages": sum(ns in dets for ns in stamps),
            "video_frames": video_frames, "strip_size": strip, "metrics": metrics,
            "metrics_frames_with_tracks": metrics_tracked, "files": files}


def node_report(name: str, stats: dict | None, played: int) -> str:
    """One line per node: frames played to it, processed, dropped, unaccounted for.
    ``dropped`` is the node's own count of frames replaced by a newer one before it got to
    them; the rest of the played frames never reached its worker (lost in transport, or
    still queued at shutdown)."""
    if not stats:
        return (f"{name}: {played} frames played; it logged no statistics (crashed or "
                "killed?), see launch.log")
    processed, dropped = int(stats.get("frames", 0)), int(stats.get("dropped", 0))
    extra = "".join(f", {stats[k]} {k.replace('_', ' ')}"
                    for k in ("bad_images", "rejected_frames") if stats.get(k))
    return (f"{name}: {played} frames played, {processed} processed, {dropped} dropped "
            f"(a newer frame arrived while it was busy), "
            f"{played - processed - dropped} not received{extra}")
