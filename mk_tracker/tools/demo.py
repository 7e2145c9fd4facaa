"""``mk_tracker demo`` (what ``make demo`` runs): the whole system, end to end, over DDS, at
real time.

1. Generates a synthetic RGB+thermal scene with ground truth: by default
   (:func:`groups_scene`) 640x480, 6-10 people who walk in groups of one to three, cross
   the floor from side to side (so groups walking the other way cross them) and pass in
   front of and behind three pillars.  Its seed is new on every run unless ``--seed`` is
   given, so the demo shows a scene nobody tuned on; the seed is printed and repeats the
   scene.  The scene is written as a bag whose *bag times* put every thermal frame 3/4 of
   a frame period before its RGB frame (header stamps are untouched, so the algorithms see
   the scene's own times) and pause ``--warmup`` seconds where the thermal detector makes
   its first full-frame pass.
2. Plays it through ``detector_node`` and ``tracker_node`` over DDS with
   :mod:`mk_tracker.ros.launcher` (bag player, both nodes, bag recorder; Fast DDS
   shared-memory profile ``config/fastdds_shm.xml``, a unique ``ROS_DOMAIN_ID``,
   ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``) at rate 1, i.e. at the scene's own frame
   rate: a node that is busy when a newer frame arrives drops the older one, as it would
   with a camera.  ``/tracks`` and ``/thermal/detections`` are recorded.
3. Scores the recorded tracks against the ground truth (:mod:`mk_tracker.evaluation.metrics`)
   and writes their annotated video, a strip of annotated frames (PNG), the MOT file and the
   per-frame error plot.  Each node's processed and dropped frame counts (from its own
   shutdown log) are printed next to the scores, whatever they are.

``--compare-offline`` is the slow check instead: playback slow enough that no frame is
dropped (``--period`` wall seconds per frame, pauses at every full-frame detector pass), the
offline pipeline (:mod:`mk_tracker.tools.pipeline`) on the same bag with the same parameters
file, and a frame-by-frame comparison: the same track ids in every frame and every box
within ``--tolerance`` pixels (1 by default).

Everything goes into ``--out`` (default ``out/demo``); ``demo_summary.json`` holds the
figures.  Exit status: 0 when the run completed (1 if a process crashed, 2 on bad options,
3 with ``--require-agreement`` when online and offline disagree).
"""

from __future__ import annotations

import argparse
import json
import os
import secrets
import shutil
import sys
import tempfile
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
                                            THERMAL_TOPIC, build_preset)

SUMMARY_FILE = "demo_summary.json"
STRIP_FILE = "strip.png"
RECORD_TOPICS = ("/tracks", "/thermal/detections")
#: share of a frame period between a thermal frame and its RGB frame in bag time
RGB_DELAY = 0.75
#: wall seconds between /scene_info and the first frame, and after the last one
LEAD_S = 2.0
#: the same at real time (the player already waits for the nodes and the recorder)
REALTIME_LEAD_S = 0.5
END_TOPIC = "/demo/end_of_scene"
SCENES = ("groups", "crowd")
#: the scene's frame rate and length by default: 200 frames at 20 fps = 10 s of scene
DEFAULT_FPS = 20.0
DEFAULT_FRAMES = 200
#: frames of the PNG strip and the width of each
STRIP_FRAMES = 4
STRIP_WIDTH = 320


class DemoError(ValueError):
    """Bad demo options or an output folder that is not ours to replace."""


# -- the scene ----------------------------------------------------------------------------

def choose_seed(seed: int | None) -> int:
    """``seed`` if given, else a fresh one from the operating system's entropy (so every
    run without ``--seed`` shows another scene); small enough to type back."""
    return int(seed) if seed is not None else secrets.randbelow(1_000_000)


def groups_scene(seed: int, people: int | None = None, frames: int = DEFAULT_FRAMES,
                 fps: float = DEFAULT_FPS, width: int = 640, height: int = 480,
                 pillars: int = 3):
    """The demo's scene: ``people`` (default 6-10, drawn from ``seed``) in groups of 1-3.

    Each group walks back and forth between the left and the right third of the floor
    (waypoints alternate sides, each at a random depth), odd groups starting on the other
    side, so groups meet and cross in the middle, where the ``pillars`` stand (bottom edge
    at 60-80% of the height: people whose feet are higher up pass behind them).  Members of
    a group share the group's waypoints shifted by a fixed offset and its speed (60-100 px/s,
    about 0.7-1.2 m/s for a 1.7 m person 144 px tall), so they walk together: half of the
    groups side by side (each member 5-8% of the height deeper in the image than the one
    before and 0.3-0.6 body widths aside, so the nearer one partly hides the farther one
    while the group crosses the view), the others one after the other (1.6-2.2 body widths
    apart along x).  Returns ``(scene, groups)``, ``groups`` being the person ids of each
    group.
    """
    from mk_tracker.synthetic.scene import make_scene
    from mk_tracker.synthetic.scene_config import OccluderSpec, PersonSpec, SceneConfig

    rng = np.random.default_rng([int(seed), 0xDE30])
    n = int(rng.integers(6, 11)) if people is None else int(people)
    if n < 1:
        raise DemoError(f"need at least one person, got {n}")
    sizes: list[int] = []
    while sum(sizes) < n:
        sizes.append(min(n - sum(sizes), int(rng.choice([1, 2, 2, 3, 3]))))
    body_h = 0.3 * height
    body_w = body_h / 2.75
    floor_y = (0.5 * height, 0.9 * height)
    specs: list = []
    groups: list[list[int]] = []
    for g, size in enumerate(sizes):
        speed = float(rng.uniform(60.0, 100.0)) / fps          # px per frame
        legs = int(frames * speed / (0.4 * width)) + 3
        start_left = g % 2 == 0
        waypoints = np.empty((legs, 2))
        for j in range(legs):
            left = start_left == (j % 2 == 0)
            side = (0.08, 0.32) if left else (0.68, 0.92)
            waypoints[j] = rng.uniform(*side) * width, rng.uniform(*floor_y)
        members = []
        abreast = bool(rng.random() < 0.5)
        for m in range(size):
            rank = m - (size - 1) / 2
            if abreast:   # side by side, ~0.75 m apart: a row deeper per member
                offset = np.array([rank * rng.uniform(0.3, 0.6) * body_w,
                                   rank * rng.uniform(0.05, 0.08) * height])
            else:         # one after the other along the walk, ~1 m apart
                offset = np.array([rank * rng.uniform(1.6, 2.2) * body_w,
                                   rng.uniform(-0.02, 0.02) * height])
            members.append(len(specs))
            specs.append(PersonSpec(
                waypoints=tuple(map(tuple, (waypoints + offset).round(2).tolist())),
                speed=round(speed, 4), height=body_h,
                torso_temperature=float(rng.uniform(301.5, 304.0))))
        groups.append(members)
    occluders = []
    for k in range(pillars):
        w, h = 0.06 * width, 0.42 * height
        cx = width * (k + 1) / (pillars + 1) + float(rng.uniform(-0.04, 0.04)) * width
        bottom = float(rng.uniform(0.6, 0.8)) * height
        occluders.append(OccluderSpec(box=(cx - w / 2, bottom - h, w, h),
                                      color=tuple(int(v) for v in rng.integers(40, 120, 3))))
    config = SceneConfig(seed=int(seed), frames=int(frames), fps=float(fps), width=int(width),
                         height=int(height), perspective=0.6, people=tuple(specs),
                         occluders=tuple(occluders))
    return make_scene(config), groups


# -- the scene bag ------------------------------------------------------------------------

def write_demo_bag(scene: Any, out: Path, pauses: dict[int, float] | None = None,
                   lead_s: float = 0.0, preset: str = "") -> int:
    """Render ``scene`` into a new bag at ``out`` with the demo's bag times (module
    docstring, step 1); the topics, messages and header stamps are those of
    :func:`mk_tracker.synthetic.scene_bag.write_scene_bag` (without ``/thermal/ground_truth``,
    which nothing here reads).  Thermal frame ``k`` is logged at its stamp plus ``lead_s``
    (time after ``/scene_info`` for the player's subscribers to settle) plus every pause
    ``pauses[j]`` with ``j < k``; its RGB frame and ground truth ``RGB_DELAY`` periods later
    plus ``pauses[k]`` too.  A last ``END_TOPIC`` message ``lead_s`` (at least a period)
    after the last frame keeps the player (and its publishers) alive until the last frame
    has been delivered.  Frames are rendered and written one at a time, straight to their
    final times (no second copy of a bag of ~1.2 MB a frame).  Returns the frames written."""
    from mk_tracker.messages.detection_messages import make_detection_array
    from mk_tracker.messages.image_conversion import numpy_to_image
    from mk_tracker.messages.message_types import bag_message_types, make_header
    from mk_tracker.synthetic.scene_bag import (RGB_FRAME_ID, THERMAL_FRAME_ID,
                                                ground_truth_detections)

    pauses = dict(pauses or {})
    period_ns = 1e9 / float(scene.config.fps)
    encoding = scene.config.thermal_encoding
    info = scene.info()
    info["preset"] = preset
    info["topics"] = {"rgb": RGB_TOPIC, "thermal": THERMAL_TOPIC,
                      "ground_truth": GROUND_TRUTH_TOPIC}
    info["frame_ids"] = {"rgb": RGB_FRAME_ID, "thermal": THERMAL_FRAME_ID}
    with BagWriter(out) as writer:
        types = bag_message_types(writer.typestore)
        string = writer.typestore.types["std_msgs/msg/String"]
        for topic, msgtype in ((SCENE_INFO_TOPIC, "std_msgs/msg/String"),
                               (RGB_TOPIC, "sensor_msgs/msg/Image"),
                               (THERMAL_TOPIC, "sensor_msgs/msg/Image"),
                               (GROUND_TRUTH_TOPIC, "vision_msgs/msg/Detection2DArray"),
                               (END_TOPIC, "std_msgs/msg/String")):
            writer.add_topic(topic, msgtype)
        first = round(scene.stamp(0) * 1e9)
        writer.write(SCENE_INFO_TOPIC, first, string(data=json.dumps(info)))
        paused = 0.0                        # pauses before frame k, seconds
        last = first
        for k in range(len(scene)):
            frame = scene.frame(k)
            ns = round(frame.stamp * 1e9)
            thermal_t = round(ns + 1e9 * (lead_s + paused))
            paused += pauses.get(k, 0.0)
            rgb_t = round(ns + 1e9 * (lead_s + paused) + RGB_DELAY * period_ns)
            rgb_header = make_header(types, RGB_FRAME_ID, ns)
            thermal_header = make_header(types, THERMAL_FRAME_ID, ns)
            writer.write(THERMAL_TOPIC, thermal_t, numpy_to_image(
                frame.thermal, encoding, thermal_header, types=types))
            writer.write(RGB_TOPIC, rgb_t, numpy_to_image(frame.rgb, "bgr8", rgb_header,
                                                          types=types))
            writer.write(GROUND_TRUTH_TOPIC, rgb_t, make_detection_array(
                ground_truth_detections(scene, frame, "rgb"), rgb_header, types))
            last = rgb_t
        writer.write(END_TOPIC, last + round(max(lead_s * 1e9, period_ns)),
                     string(data="end of the demo scene"))
    return len(scene)


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


#: the bag player's process: imports rclpy and the player (seconds), then waits for the
#: file ``argv[1]`` (the scene bag is written meanwhile) and plays with ``argv[2:]``
PLAYER_WAITING_FOR_BAG = (
    "import os, sys, time\n"
    "import rclpy\n"
    "from mk_tracker.ros import bag_player\n"
    "while not os.path.exists(sys.argv[1]):\n"
    "    time.sleep(0.02)\n"
    "sys.exit(bag_player.main(sys.argv[2:]))\n")


class NodeRun:
    """Player, both nodes and the recorder through :mod:`mk_tracker.ros.launcher`, in a
    background thread, so that they start while the scene bag is still being written.

    The nodes and the recorder start at once; the player starts once the recorder has
    subscribed to the nodes' topics (the launcher's rule), imports rclpy, waits for the
    file ``ready`` (:meth:`bag_ready` creates it when the bag is complete), then for the
    nodes to subscribe to its topics (``startup_wait_s``, long: on a machine's first run the
    nodes compile numba's kernels before they subscribe) and for the launcher's go line
    (the nodes logged their readers' match), then plays at ``rate``.
    :attr:`status` is the launcher's (0 = every process ended well)."""

    def __init__(self, bag: Path, params: Path, record: Path, rate: float, domain_id: int,
                 timeout_s: float, log_path: Path, linger_s: float = 3.0,
                 startup_wait_s: float = 300.0) -> None:
        import threading

        self.ready = bag.parent / (bag.name + ".ready")
        self.status: int | None = None
        self.error: BaseException | None = None
        self._stop = threading.Event()
        self._specs = self._build(bag, params, record, rate, domain_id, startup_wait_s)
        self._args = dict(linger_s=linger_s, timeout_s=timeout_s,
                          ready_timeout_s=startup_wait_s, stop_event=self._stop)
        self._log_path = log_path
        self._thread = threading.Thread(target=self._run, name="demo-launch", daemon=True)
        self._thread.start()

    def _build(self, bag: Path, params: Path, record: Path, rate: float, domain_id: int,
               startup_wait_s: float) -> list:
        from dataclasses import replace

        from mk_tracker.ros import launcher

        parser = argparse.ArgumentParser()
        launcher.configure_parser(parser)
        args = parser.parse_args(["--params-file", str(params), "--record", str(record),
                                  "--record-topics", *RECORD_TOPICS])
        # no --bag: the bag does not exist yet; the player is added here
        specs = launcher.build_specs(args)
        wait_args, go_after = launcher.player_waits(specs)
        play = [str(bag), "--rate", f"{rate:.6f}", "--wait-for-subscribers",
                f"{startup_wait_s:g}", *wait_args]
        specs.append(launcher.ProcessSpec(
            "bag_player", (sys.executable, "-c", PLAYER_WAITING_FOR_BAG, str(self.ready),
                           *play), essential=False, env=dict(specs[0].env),
            go_after=go_after))
        env = ros_environment(domain_id)
        return [replace(s, env={**s.env, **env}) for s in specs]

    def _run(self) -> None:
        from mk_tracker.ros import launcher

        try:
            with open(self._log_path, "w", encoding="utf-8") as log:
                self.status = launcher.run_processes(self._specs, out=log, **self._args)
        except BaseException as exc:      # reported by wait()
            self.error = exc

    def bag_ready(self) -> None:
        self.ready.touch()

    def stop(self) -> None:
        self._stop.set()

    def wait(self) -> int:
        self._thread.join()
        if self.error is not None:
            raise self.error
        return 1 if self.status is None else self.status


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


# -- outputs ------------------------------------------------------------------------------

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


# -- the command --------------------------------------------------------------------------

def configure_parser(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=Path, default=Path("out/demo"),
                        help="output folder (default out/demo; a previous demo output "
                             "there is replaced)")
    parser.add_argument("--seed", type=int, default=None,
                        help="scene seed (default: a new one on every run, printed)")
    parser.add_argument("--scene", choices=SCENES, default="groups",
                        help="groups (default: 6-10 people walking in groups past three "
                             "pillars) or the crowd preset (people wandering alone, 25 fps)")
    parser.add_argument("--people", type=int, default=None,
                        help="people (default: 6-10 from the seed; crowd: 5)")
    parser.add_argument("--frames", type=int, default=DEFAULT_FRAMES,
                        help=f"frames (default {DEFAULT_FRAMES})")
    parser.add_argument("--fps", type=float, default=None,
                        help=f"frame rate of the groups scene (default {DEFAULT_FPS:g})")
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=480)
    parser.add_argument("--warmup", type=float, default=None, metavar="S",
                        help="wall-clock pause after the detector's first full pass "
                             "(default 1 at real time, 6 with --compare-offline)")
    parser.add_argument("--error-plot", action="store_true",
                        help="also write online/errors.png (per-frame errors; matplotlib "
                             "costs a few seconds; always on with --compare-offline)")
    parser.add_argument("--keep-bag", action="store_true",
                        help="keep the played scene bag in OUT/scene (640x480: ~1.2 MB a "
                             "frame); it is written to /dev/shm and deleted by default")
    parser.add_argument("--domain-id", type=int, default=None,
                        help="ROS_DOMAIN_ID (default: derived from the process id)")
    slow = parser.add_argument_group(
        "online = offline check (plays slowly so that no frame is dropped)")
    slow.add_argument("--compare-offline", action="store_true",
                      help="play slowly, run the offline pipeline on the same bag and compare "
                           "the tracks frame by frame (not real time)")
    slow.add_argument("--period", type=float, default=0.5, metavar="S",
                      help="wall-clock seconds per frame with --compare-offline (default 0.5)")
    slow.add_argument("--full-pass-pause", type=float, default=1.5, metavar="S",
                      help="wall-clock pause at each later full-frame detector pass with "
                           "--compare-offline (default 1.5)")
    slow.add_argument("--tolerance", type=float, default=1.0, metavar="PX",
                      help="largest online/offline box difference that still agrees")
    slow.add_argument("--require-agreement", action="store_true",
                      help="exit with status 3 when online and offline disagree")


def _prepare_out(out: Path) -> None:
    if out.exists():
        if not (out / SUMMARY_FILE).is_file() and any(out.iterdir()):
            raise DemoError(f"{out} exists and is not a previous demo output; choose --out")
        shutil.rmtree(out)
    out.mkdir(parents=True)


def _make_scene(args: argparse.Namespace, seed: int):
    """``(scene, groups, preset name)`` of the options."""
    if args.scene == "crowd":
        if args.fps is not None:
            raise DemoError("--fps applies to the groups scene only (crowd is 25 fps)")
        scene = build_preset("crowd", seed=seed, people=args.people or 5, frames=args.frames,
                             width=args.width, height=args.height)
        return scene, [[k] for k in range(len(scene.config.people))], "crowd"
    scene, groups = groups_scene(seed, people=args.people, frames=args.frames,
                                 fps=args.fps or DEFAULT_FPS, width=args.width,
                                 height=args.height)
    return scene, groups, "demo_groups"


def _scratch_dir() -> Path:
    """A new folder for the scene bag (several hundred MB at 640x480): in ``/dev/shm``
    (memory) where there is one, which saves seconds of disk writes, else the temp dir."""
    shm = Path("/dev/shm")
    where = str(shm) if shm.is_dir() and os.access(shm, os.W_OK) else None
    return Path(tempfile.mkdtemp(prefix="mk_tracker_demo_", dir=where))


def run_demo(args: argparse.Namespace) -> dict[str, Any]:
    scratch = _scratch_dir()
    try:
        return _run_demo(args, scratch)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def _run_demo(args: argparse.Namespace, scratch: Path) -> dict[str, Any]:
    if args.frames < 10 or (args.people is not None and args.people < 1) or args.period <= 0 \
            or (args.fps is not None and args.fps <= 0):
        raise DemoError("need --frames >= 10, --people >= 1, --fps > 0 and --period > 0")
    import importlib.util

    for module in ("rclpy", "vision_msgs"):
        if importlib.util.find_spec(module) is None:
            raise DemoError(f"{module} is not installed in this Python ({sys.executable}); "
                            "'make env' sets the environment up")
    out: Path = args.out
    compare = bool(args.compare_offline)
    _prepare_out(out)
    t0 = time.monotonic()
    timings: dict[str, float] = {}
    seed = choose_seed(args.seed)
    scene, groups, preset = _make_scene(args, seed)
    print(f"scene seed {seed} (mk_tracker demo --seed {seed} shows this scene again): "
          f"{len(scene.config.people)} people in groups of "
          f"{'+'.join(str(len(g)) for g in groups)}, {len(scene.config.occluders)} pillars, "
          f"{len(scene)} frames at {scene.config.fps:g} fps, "
          f"{scene.rgb_size[0]}x{scene.rgb_size[1]}", flush=True)
    fps = float(scene.config.fps)
    homography = scene.info()["homography"]
    params = out / "params.yaml"
    write_params_file(params, homography)
    config = load_pipeline_config([params], include_defaults=False)   # as the nodes get it
    frames = len(scene)
    if compare:
        rate = (1.0 / fps) / args.period
        warmup = 6.0 if args.warmup is None else args.warmup
        pauses = detector_pauses(config.detector, frames, warmup, args.full_pass_pause)
        lead = LEAD_S
    else:
        rate = 1.0
        warmup = 1.0 if args.warmup is None else args.warmup
        pauses = {config.detector.startup_frames - 1: warmup}
        lead = REALTIME_LEAD_S
    domain = args.domain_id if args.domain_id is not None else 1 + os.getpid() % 100
    scene_s = frames / fps
    playback_s = scene_s / rate + sum(pauses.values()) + 2 * lead
    bag = scratch / "scene"
    nodes = None
    if not compare:
        # the nodes start (seconds: imports, numba's cache) while the bag is written
        nodes = NodeRun(bag, params, out / "recorded", rate, domain, log_path=out / "launch.log",
                        timeout_s=playback_s + 360.0, linger_s=1.0)
    try:
        write_demo_bag(scene, bag, {k: p * rate for k, p in pauses.items()},
                       lead_s=lead * rate, preset=preset)
    except BaseException:
        if nodes is not None:
            nodes.stop()
            nodes.wait()
        raise
    timings["scene"] = time.monotonic() - t0

    result = None
    if compare:
        # offline first: it also fills numba's on-disk cache
        print("running the offline pipeline on the bag ...", flush=True)
        t = time.monotonic()
        result = process_bag(bag, out / "offline", config,
                             PipelineOptions(progress=False, use_scene_homography=False))
        timings["offline"] = time.monotonic() - t
        nodes = NodeRun(bag, params, out / "recorded", rate, domain, log_path=out / "launch.log",
                        timeout_s=playback_s + 360.0, linger_s=3.0)
    print(f"playing it through detector_node and tracker_node over DDS (domain {domain}) at "
          + ("real time" if rate == 1.0 else f"rate {rate:.3f} (slow, for the comparison)")
          + f": {scene_s:.1f} s of scene, {playback_s:.1f} s of playback with the "
          f"{warmup:g} s warm-up pause ...", flush=True)
    t = time.monotonic()
    nodes.bag_ready()
    status = nodes.wait()
    timings["nodes"] = time.monotonic() - t
    t = time.monotonic()
    online = render_online(bag, out / "recorded", out / "online", homography, fps,
                           frames, error_plot=compare or args.error_plot)
    files = {"recorded_bag": str(out / "recorded"), "params": str(params),
             "launch_log": str(out / "launch.log")}
    if args.keep_bag:
        shutil.copytree(bag, out / "scene")
        files["scene_bag"] = str(out / "scene")
    timings["outputs"] = time.monotonic() - t
    summary = {
        "seed": seed, "scene": preset, "frames": frames, "fps": fps,
        "people": len(scene.config.people), "groups": groups,
        "size": list(scene.rgb_size), "real_time": not compare,
        "rate": rate, "warmup_pause_s": warmup, "domain_id": domain, "launch_status": status,
        "nodes": node_statistics(out / "launch.log"),
        "online": online,
        "files": files,
    }
    if result is not None:
        agreement = compare_tracks(result.tracks, read_tracks(out / "recorded"))
        summary["offline"] = {"frames": result.frames, "metrics": result.metrics,
                              "files": result.files, "seconds": round(result.seconds, 2)}
        summary["agreement"] = {**agreement.__dict__, "tolerance": args.tolerance,
                                "agree": agreement.agree(args.tolerance)}
    timings["total"] = time.monotonic() - t0
    summary["seconds"] = {k: round(v, 1) for k, v in timings.items()}
    (out / SUMMARY_FILE).write_text(json.dumps(summary, indent=2, default=float))
    return summary


SCORES = ("mota", "idf1", "num_switches", "num_false_positives", "num_misses")


def run(args: argparse.Namespace) -> int:
    try:
        summary = run_demo(args)
    except (DemoError, PipelineError, BagError) as exc:
        print(f"mk_tracker demo: {exc}", file=sys.stderr)
        return 2
    online = summary["online"]
    frames = summary["frames"]
    for name in ("detector_node", "tracker_node"):
        print(node_report(name, summary["nodes"].get(name), frames))
    print(f"recorded: /tracks for {online['frames_with_tracks_message']} of {frames} frames, "
          f"/thermal/detections for {online['detection_messages']} of {frames}")
    print(f"scores over all {frames} frames (a frame without /tracks counts as missed): "
          + format_metrics({k: online["metrics"][k] for k in SCORES}))
    if online["metrics_frames_with_tracks"] and online["frames_with_tracks_message"] < frames:
        print(f"scores over the {online['frames_with_tracks_message']} frames with /tracks: "
              + format_metrics({k: online["metrics_frames_with_tracks"][k] for k in SCORES}))
    if "agreement" in summary:
        offline, agreement = summary["offline"]["metrics"], summary["agreement"]
        print("offline (mk_tracker process): "
              + format_metrics({k: offline[k] for k in SCORES}))
        verdict = "AGREE" if agreement["agree"] else "DISAGREE"
        print(f"online vs offline: {verdict} over {agreement['frames']} frames (missing "
              f"online {agreement['missing_online']}, id mismatches "
              f"{agreement['id_mismatch_frames']}, largest box difference "
              f"{agreement['max_box_difference']:.3f} px)"
              + (f"; first difference: {agreement['first_difference']}"
                 if agreement["first_difference"] else ""))
    files = online["files"]
    written = ", ".join(os.path.relpath(p, args.out) for p in files.values())
    print(f"outputs in {args.out}: {written}, {SUMMARY_FILE}, launch.log"
          + (", offline/" if "offline" in summary else ""))
    seconds = summary["seconds"]
    phases = ", ".join(f"{k} {v:.1f} s" for k, v in seconds.items() if k != "total")
    print(f"wall time {seconds['total']:.1f} s ({phases}); seed {summary['seed']}")
    if summary["launch_status"] != 0:
        print("a ROS process crashed; see launch.log", file=sys.stderr)
        return 1
    if args.require_agreement and not summary.get("agreement", {}).get("agree", False):
        return 3
    return 0
