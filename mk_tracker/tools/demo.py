"""``mk_tracker demo`` (what ``make demo`` runs): the whole system, end to end, over DDS.

1. Generates a seeded synthetic RGB+thermal scene (:mod:`mk_tracker.synthetic.scene_bag`, preset
   ``crowd``: people crossing each other and passing behind pillars, sizes changing with the
   perspective) and writes it as a bag whose *bag times* put every thermal frame 3/4 of a
   frame period before its RGB frame (header stamps are untouched, so the algorithms see the
   scene's own times), and pauses where the thermal detector makes a full-frame pass
   (the first one also pays for numba's compilation: seconds, not milliseconds).
2. Plays it through ``detector_node`` and ``tracker_node`` over DDS with
   :mod:`mk_tracker.ros.launcher` (bag player, both nodes, bag recorder; Fast DDS
   shared-memory profile ``config/fastdds_shm.xml``, a unique ``ROS_DOMAIN_ID``,
   ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``), at a rate slow enough that no frame is
   dropped (``--period`` wall seconds per frame), and records ``/tracks`` and
   ``/thermal/detections``.
3. Scores the recorded tracks against the ground truth (:mod:`mk_tracker.evaluation.metrics`) and
   writes their annotated video, MOT file and per-frame error plot with the pipeline's
   writers (:mod:`mk_tracker.drawing.video_output`, :mod:`mk_tracker.evaluation.error_plots`).
4. Runs the offline pipeline (:mod:`mk_tracker.tools.pipeline`) on the same bag with the same
   parameters file (before step 2, which also warms numba's on-disk cache) and reports whether online and offline agree: the same track ids in
   every frame and every box within ``--tolerance`` pixels (1 by default).

Everything goes into ``--out`` (default ``out/demo``); ``demo_summary.json`` holds the
figures.  Exit status: 0 when the run completed (1 if a process crashed, 3 with
``--require-agreement`` when online and offline disagree).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mk_tracker.bags.bag_io import BagError, BagWriter, open_bag
from mk_tracker.messages.detection_messages import read_detection_array
from mk_tracker.evaluation.metrics import MotRow, mot_accumulator, mot_metrics, write_mot_file
from mk_tracker.messages.message_types import stamp_to_nanoseconds, stamp_to_seconds
from mk_tracker.tools.pipeline import (CONFIG_DIR, PipelineError, PipelineOptions, format_metrics,
                                 load_pipeline_config, process_bag)
from mk_tracker.synthetic.scene_bag import (GROUND_TRUTH_TOPIC, RGB_TOPIC, SCENE_INFO_TOPIC,
                                  build_preset, read_scene_info, write_scene_bag)

SUMMARY_FILE = "demo_summary.json"
RECORD_TOPICS = ("/tracks", "/thermal/detections")
#: share of a frame period between a thermal frame and its RGB frame in bag time
RGB_DELAY = 0.75
#: wall seconds between /scene_info and the first frame, and after the last one
LEAD_S = 2.0
END_TOPIC = "/demo/end_of_scene"


class DemoError(ValueError):
    """Bad demo options or an output folder that is not ours to replace."""


# -- the scene bag ------------------------------------------------------------------------

def write_demo_bag(scene_bag: Path, out: Path, fps: float,
                   pauses: dict[int, float] | None = None, lead_s: float = 0.0) -> None:
    """Copy ``scene_bag`` to ``out`` with the demo's bag times (module docstring, step 1):
    each RGB frame (and its ground truth) ``RGB_DELAY`` periods after its thermal frame,
    ``pauses[k]`` seconds of bag time between the thermal and the RGB frame number ``k``,
    and every frame ``lead_s`` after ``/scene_info`` (time for the recorder to match the
    nodes' publishers before the first frame).  A last ``END_TOPIC`` message ``lead_s``
    after the last frame keeps the player (and its publishers) alive until the last frame
    has been delivered."""
    pauses = dict(pauses or {})
    period_ns = 1e9 / fps
    with open_bag(scene_bag) as reader, BagWriter(out, typestore=reader.typestore) as writer:
        for t in reader.topics.values():
            writer.add_topic(t.name, t.msgtype)
        t0 = None
        for m in reader.messages():
            if t0 is None:
                t0 = m.timestamp_ns
            k = int(round((m.timestamp_ns - t0) / period_ns))
            rgb = m.topic in (RGB_TOPIC, GROUND_TRUTH_TOPIC)
            shift = RGB_DELAY * period_ns if rgb else 0.0
            if m.topic != SCENE_INFO_TOPIC:
                shift += lead_s * 1e9
            shift += 1e9 * sum(p for j, p in pauses.items() if j < k or (rgb and j == k))
            last = int(round(m.timestamp_ns + shift))
            writer.write_raw(m.topic, last, m.data)
        if t0 is not None:
            writer.add_topic(END_TOPIC, "std_msgs/msg/String")
            end = reader.typestore.types["std_msgs/msg/String"](data="end of the demo scene")
            writer.write(END_TOPIC, last + int(round(max(lead_s, 1.0 / fps) * 1e9)), end)


def detector_pauses(config: Any, frames: int, warmup_s: float, full_pass_s: float
                    ) -> dict[int, float]:
    """Wall seconds to wait before the RGB frames whose thermal frame gets a full-frame
    pass of the detector (Schizas et al. 2018, Algorithm 2: the start-up pass after
    ``startup_frames`` frames, then one every ``reconfigure_period`` frames), which take
    several times a tracking pass (the first one also compiles the numba kernels)."""
    first = config.startup_frames - 1
    pauses = {first: warmup_s}
    for k in range(first + config.reconfigure_period, frames, config.reconfigure_period):
        pauses[k] = full_pass_s
    return pauses


def write_params_file(path: Path, homography: Any) -> None:
    """One parameters file for both nodes and the offline pipeline: the scene's homography
    (thermal -> RGB) and reliable detection delivery; everything else stays default."""
    h = ", ".join(repr(float(v)) for v in np.asarray(homography, dtype=float).reshape(9))
    path.write_text(
        "detector_node:\n  ros__parameters:\n    method: kernel_covariance\n"
        "tracker_node:\n  ros__parameters:\n"
        "    detections_qos:\n      reliability: reliable\n"
        f"    tracker:\n      homography: [{h}]\n", encoding="utf-8")


# -- running the nodes --------------------------------------------------------------------

def ros_environment(domain_id: int) -> dict[str, str]:
    """Environment of every ROS process of the demo: own domain, local discovery only,
    Fast DDS shared-memory transport."""
    profile = str(CONFIG_DIR / "fastdds_shm.xml")
    repo = str(Path(__file__).resolve().parents[2])
    path = os.environ.get("PYTHONPATH", "")
    return {"ROS_DOMAIN_ID": str(domain_id), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
            "FASTRTPS_DEFAULT_PROFILES_FILE": profile, "FASTDDS_DEFAULT_PROFILES_FILE": profile,
            "PYTHONPATH": os.pathsep.join(p for p in (repo, path) if p),
            "PYTHONUNBUFFERED": "1", "RCUTILS_COLORIZED_OUTPUT": "0"}


def run_nodes(bag: Path, params: Path, record: Path, rate: float, domain_id: int,
              timeout_s: float, log_path: Path) -> int:
    """Player, both nodes and the recorder through :mod:`mk_tracker.ros.launcher`;
    returns its status (0 = every process ended well)."""
    from dataclasses import replace

    from mk_tracker.ros import launcher

    parser = argparse.ArgumentParser()
    launcher.configure_parser(parser)
    args = parser.parse_args(["--bag", str(bag), "--params-file", str(params),
                              "--rate", f"{rate:.6f}", "--record", str(record),
                              "--record-topics", *RECORD_TOPICS, "--linger", "3",
                              "--wait-for-subscribers", "20"])
    env = ros_environment(domain_id)
    specs = [replace(s, env={**s.env, **env}) for s in launcher.build_specs(args)]
    # (the launcher starts the player once the recorder has subscribed to the nodes' topics)
    with open(log_path, "w", encoding="utf-8") as log:
        return launcher.run_processes(specs, linger_s=3.0, timeout_s=timeout_s, out=log)


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


# -- reading, scoring and comparing -------------------------------------------------------

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


def _frames_and_truth(bag: Path) -> tuple[list[int], list[MotRow], list[np.ndarray],
                                          dict[int, list]]:
    """RGB stamps in bag order, ground-truth rows (frame = 1-based index), the images."""
    from mk_tracker.frame_processing import tracker_input

    stamps: list[int] = []
    images: list[np.ndarray] = []
    truth_by_stamp: dict[int, list] = {}
    with open_bag(bag) as reader:
        for m, msg in reader.read_messages([RGB_TOPIC, GROUND_TRUTH_TOPIC]):
            ns = stamp_to_nanoseconds(msg.header.stamp)
            if m.topic == RGB_TOPIC:
                stamps.append(ns)
                images.append(tracker_input(msg))
            else:
                truth_by_stamp[ns] = read_detection_array(msg)
    rows = [MotRow(i + 1, int(d.id), d.box) for i, ns in enumerate(stamps)
            for d in truth_by_stamp.get(ns, [])]
    return stamps, rows, images, truth_by_stamp


@dataclass(frozen=True)
class _Drawn:
    """A recorded track as :func:`mk_tracker.frame_processing.tracker_debug_image` draws it
    (recorded messages carry no state or kernels)."""

    id: int
    box: tuple
    score: float
    state: str = ""


def render_online(scene_bag: Path, recorded: Path, out: Path, homography: Any,
                  fps: float) -> dict[str, Any]:
    """Score the recorded ``/tracks`` and write their MOT file, video and error plot."""
    from mk_tracker.evaluation.error_plots import ErrorPlotError, mot_frame_errors, plot_mot_errors
    from mk_tracker.frame_processing import tracker_debug_image
    from mk_tracker.tracking.multi_object_tracker import FrameDetection
    from mk_tracker.drawing.video_output import VideoOutput

    out.mkdir(parents=True, exist_ok=True)
    stamps, truth_rows, images, truth = _frames_and_truth(scene_bag)
    tracks = read_tracks(recorded, scores=True)
    dets_by_stamp: dict[int, list] = {}
    with open_bag(recorded, on_error="skip") as reader:
        if "/thermal/detections" in reader.topics:
            for _, msg in reader.read_messages(["/thermal/detections"]):
                dets_by_stamp[stamp_to_nanoseconds(msg.header.stamp)] = [
                    FrameDetection(d.box, d.score, stamp_to_seconds(msg.header.stamp),
                                   "thermal")
                    for d in read_detection_array(msg, on_error="skip")[0]]
    rows = [MotRow(i + 1, tid, box, score) for i, ns in enumerate(stamps)
            for tid, box, score in tracks.get(ns, [])]
    write_mot_file(out / "tracks.txt", rows)
    h = np.asarray(homography, dtype=float).reshape(3, 3)
    with VideoOutput(out / "video.mp4", fps=fps) as video:
        for i, (ns, image) in enumerate(zip(stamps, images)):
            drawn = [_Drawn(tid, box, score) for tid, box, score in tracks.get(ns, [])]
            video.write(tracker_debug_image(
                image, drawn, {}, dets_by_stamp.get(ns, []), h,
                [f"online frame {i + 1}  tracks {len(drawn)}"
                 + ("" if ns in tracks else "  (no /tracks message)")],
                ground_truth=[d.box for d in truth.get(ns, [])]))
        video_frames = video.frames
    metrics = mot_metrics(truth_rows, rows)
    files = {"tracks": str(out / "tracks.txt"), "video": str(out / "video.mp4")}
    try:
        acc = mot_accumulator(truth_rows, rows, frames=range(1, len(stamps) + 1))
        plot_mot_errors(mot_frame_errors(acc), out / "errors.png",
                        title="online (nodes over DDS): per-frame errors")
        files["plot"] = str(out / "errors.png")
    except ErrorPlotError:
        pass
    return {"frames": len(stamps), "frames_with_tracks_message": sum(s in tracks for s in stamps),
            "video_frames": video_frames, "metrics": metrics, "files": files}


# -- the command --------------------------------------------------------------------------

def configure_parser(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=Path, default=Path("out/demo"),
                        help="output folder (default out/demo; a previous demo output "
                             "there is replaced)")
    parser.add_argument("--frames", type=int, default=120, help="frames (default 120)")
    parser.add_argument("--people", type=int, default=4, help="people (default 4)")
    parser.add_argument("--seed", type=int, default=7,
                        help="scene seed (default 7)")
    parser.add_argument("--width", type=int, default=320)
    parser.add_argument("--height", type=int, default=240)
    parser.add_argument("--period", type=float, default=0.5, metavar="S",
                        help="wall-clock seconds per frame during playback (default 0.5: "
                             "slow enough that no frame is dropped)")
    parser.add_argument("--warmup", type=float, default=6.0, metavar="S",
                        help="wall-clock pause after the detector's first full pass "
                             "(default 6)")
    parser.add_argument("--full-pass-pause", type=float, default=1.5, metavar="S",
                        help="wall-clock pause at each later full-frame detector pass "
                             "(default 1.5)")
    parser.add_argument("--tolerance", type=float, default=1.0, metavar="PX",
                        help="largest online/offline box difference that still agrees")
    parser.add_argument("--domain-id", type=int, default=None,
                        help="ROS_DOMAIN_ID (default: derived from the process id)")
    parser.add_argument("--require-agreement", action="store_true",
                        help="exit with status 3 when online and offline disagree")


def _prepare_out(out: Path) -> None:
    if out.exists():
        if not (out / SUMMARY_FILE).is_file() and any(out.iterdir()):
            raise DemoError(f"{out} exists and is not a previous demo output; choose --out")
        shutil.rmtree(out)
    out.mkdir(parents=True)


def run_demo(args: argparse.Namespace) -> dict[str, Any]:
    if args.frames < 10 or args.people < 1 or args.period <= 0:
        raise DemoError("need --frames >= 10, --people >= 1 and --period > 0")
    import importlib.util

    for module in ("rclpy", "vision_msgs"):
        if importlib.util.find_spec(module) is None:
            raise DemoError(f"{module} is not installed in this Python ({sys.executable}); "
                            "'make env' sets the environment up")
    out: Path = args.out
    _prepare_out(out)
    t0 = time.monotonic()
    scene = build_preset("crowd", seed=args.seed, people=args.people, frames=args.frames,
                         width=args.width, height=args.height)
    write_scene_bag(scene, out / "scene_generated", preset="crowd")
    info = read_scene_info(out / "scene_generated")
    fps = float(info["fps"])
    params = out / "params.yaml"
    write_params_file(params, info["homography"])
    config = load_pipeline_config([params], include_defaults=False)   # as the nodes get it
    rate = (1.0 / fps) / args.period
    bag = out / "scene"
    pauses = detector_pauses(config.detector, args.frames, args.warmup, args.full_pass_pause)
    write_demo_bag(out / "scene_generated", bag, fps,
                   {k: p * rate for k, p in pauses.items()}, lead_s=LEAD_S * rate)
    shutil.rmtree(out / "scene_generated")
    print(f"scene: {args.frames} frames, {args.people} people, {args.width}x{args.height} "
          f"-> {bag}", flush=True)

    # offline first: it also fills numba's on-disk cache, so the nodes' first detector pass
    # loads compiled code instead of compiling it while frames arrive
    print("running the offline pipeline on the bag ...", flush=True)
    result = process_bag(bag, out / "offline", config,
                         PipelineOptions(progress=False, use_scene_homography=False))
    domain = args.domain_id if args.domain_id is not None else 1 + os.getpid() % 100
    playback_s = args.period * args.frames + sum(pauses.values()) + 2 * LEAD_S
    print(f"playing it through detector_node and tracker_node over DDS (domain {domain}, "
          f"rate {rate:.3f}, about {playback_s:.0f} s) ...", flush=True)
    status = run_nodes(bag, params, out / "recorded", rate, domain,
                       timeout_s=playback_s + 90.0, log_path=out / "launch.log")
    online = render_online(bag, out / "recorded", out / "online", info["homography"], fps)
    agreement = compare_tracks(result.tracks, read_tracks(out / "recorded"))
    summary = {
        "frames": args.frames, "people": args.people, "seed": args.seed,
        "rate": rate, "domain_id": domain, "launch_status": status,
        "nodes": node_statistics(out / "launch.log"),
        "online": online,
        "offline": {"frames": result.frames, "metrics": result.metrics, "files": result.files,
                    "seconds": round(result.seconds, 2)},
        "agreement": {**agreement.__dict__, "tolerance": args.tolerance,
                      "agree": agreement.agree(args.tolerance)},
        "seconds": round(time.monotonic() - t0, 1),
        "files": {"scene_bag": str(bag), "recorded_bag": str(out / "recorded"),
                  "params": str(params), "launch_log": str(out / "launch.log")},
    }
    (out / SUMMARY_FILE).write_text(json.dumps(summary, indent=2, default=float))
    return summary


def run(args: argparse.Namespace) -> int:
    try:
        summary = run_demo(args)
    except (DemoError, PipelineError, BagError) as exc:
        print(f"mk_tracker demo: {exc}", file=sys.stderr)
        return 2
    online, agreement = summary["online"], summary["agreement"]
    print(f"online (nodes over DDS): {online['frames_with_tracks_message']}/{online['frames']} "
          f"frames tracked; " + format_metrics(
              {k: online["metrics"][k] for k in ("mota", "idf1", "num_switches",
                                                 "num_false_positives", "num_misses")}))
    offline = summary["offline"]["metrics"]
    print("offline (mk_tracker process): " + format_metrics(
        {k: offline[k] for k in ("mota", "idf1", "num_switches", "num_false_positives",
                                 "num_misses")}))
    verdict = "AGREE" if agreement["agree"] else "DISAGREE"
    print(f"online vs offline: {verdict} over {agreement['frames']} frames (missing online "
          f"{agreement['missing_online']}, id mismatches {agreement['id_mismatch_frames']}, "
          f"largest box difference {agreement['max_box_difference']:.3f} px)"
          + (f"; first difference: {agreement['first_difference']}"
             if agreement["first_difference"] else ""))
    print(f"outputs in {args.out}: online/video.mp4, online/errors.png, offline/video.mp4, "
          f"offline/errors.png, {SUMMARY_FILE}, launch.log")
    for name, stats in summary["nodes"].items():
        print(f"{name}: {stats}")
    if summary["launch_status"] != 0:
        print("a ROS process crashed; see launch.log", file=sys.stderr)
        return 1
    if args.require_agreement and not agreement["agree"]:
        return 3
    return 0
