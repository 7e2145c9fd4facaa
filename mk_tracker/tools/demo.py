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

``--rgb-only`` is the system for a camera without a thermal twin: the bag has no thermal
topic, ``detector_node`` runs ``method: background`` (background subtraction) on
``/image_raw`` (remapped), and the default scene is the ``static_camera`` preset (a far view
at 7 fps with cast shadows, fading light and people who stop).  The scene and its bag are
built by :mod:`~mk_tracker.tools.demo_scene`, the outputs read back by
:mod:`~mk_tracker.tools.demo_outputs`.

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
import shutil
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from mk_tracker.bags.bag_io import BagError
from mk_tracker.tools.demo_outputs import (compare_tracks, node_report, node_statistics,
                                           read_tracks, render_online)
from mk_tracker.tools.demo_scene import (DEFAULT_FPS, DEFAULT_FRAMES, SCENES,
                                         STATIC_CAMERA_FPS, DemoError, choose_seed,
                                         detector_pauses, make_demo_scene, write_demo_bag,
                                         write_params_file)
from mk_tracker.tools.pipeline import (CONFIG_DIR, PipelineError, PipelineOptions, format_metrics,
                                 load_pipeline_config, process_bag)

SUMMARY_FILE = "demo_summary.json"
RECORD_TOPICS = ("/tracks", "/thermal/detections")
#: wall seconds between /scene_info and the first frame, and after the last one
LEAD_S = 2.0
#: the same at real time (the player already waits for the nodes and the recorder)
REALTIME_LEAD_S = 0.5
#: ``--rgb-only``: the detector's input is the RGB camera
RGB_ONLY_REMAPS = ("thermal/image_raw:=image_raw",)


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
                 startup_wait_s: float = 300.0, remaps: list[str] | None = None) -> None:
        import threading

        self.ready = bag.parent / (bag.name + ".ready")
        self.status: int | None = None
        self.error: BaseException | None = None
        self._stop = threading.Event()
        self._specs = self._build(bag, params, record, rate, domain_id, startup_wait_s,
                                  remaps or [])
        self._args = dict(linger_s=linger_s, timeout_s=timeout_s,
                          ready_timeout_s=startup_wait_s, stop_event=self._stop)
        self._log_path = log_path
        self._thread = threading.Thread(target=self._run, name="demo-launch", daemon=True)
        self._thread.start()

    def _build(self, bag: Path, params: Path, record: Path, rate: float, domain_id: int,
               startup_wait_s: float, remaps: list[str]) -> list:
        from dataclasses import replace

        from mk_tracker.ros import launcher

        parser = argparse.ArgumentParser()
        launcher.configure_parser(parser)
        args = parser.parse_args(["--params-file", str(params), "--record", str(record),
                                  "--record-topics", *RECORD_TOPICS,
                                  *(a for r in remaps for a in ("--remap", r))])
        # no --bag: the bag does not exist yet; the player is added here
        specs = launcher.build_specs(args)
        wait_args, go_after = launcher.player_waits(specs, remaps)
        # the remaps are the nodes' (the RGB-only bag has no thermal topic to remap)
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


# -- the command --------------------------------------------------------------------------

def configure_parser(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=Path, default=Path("out/demo"),
                        help="output folder (default out/demo; a previous demo output "
                             "there is replaced)")
    parser.add_argument("--seed", type=int, default=None,
                        help="scene seed (default: a new one on every run, printed)")
    parser.add_argument("--rgb-only", action="store_true",
                        help="the RGB-only system: no thermal camera; detector_node finds "
                             "people by background subtraction (method: background) in "
                             "/image_raw; default scene static_camera")
    parser.add_argument("--scene", choices=SCENES, default=None,
                        help="groups (default: 6-10 people walking in groups past three "
                             "pillars), the crowd preset (people wandering alone, 25 fps) or "
                             "static_camera (a far view at 7 fps with shadows, fading light "
                             "and people who stop; the default with --rgb-only)")
    parser.add_argument("--people", type=int, default=None,
                        help="people (default: 6-10 from the seed; crowd: 5; "
                             "static_camera: 10)")
    parser.add_argument("--frames", type=int, default=DEFAULT_FRAMES,
                        help=f"frames (default {DEFAULT_FRAMES})")
    parser.add_argument("--fps", type=float, default=None,
                        help=f"frame rate of the groups scene (default {DEFAULT_FPS:g}) "
                             f"or the static_camera scene ({STATIC_CAMERA_FPS:g})")
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
    scene_name = args.scene or ("static_camera" if args.rgb_only else "groups")
    scene, groups, preset = make_demo_scene(scene_name, seed, args.people, args.frames,
                                            args.fps, args.width, args.height)
    print(f"scene seed {seed} (mk_tracker demo --seed {seed} shows this scene again): "
          f"{len(scene.config.people)} people in groups of "
          f"{'+'.join(str(len(g)) for g in groups)}, {len(scene.config.occluders)} pillars, "
          f"{len(scene)} frames at {scene.config.fps:g} fps, "
          f"{scene.rgb_size[0]}x{scene.rgb_size[1]}", flush=True)
    fps = float(scene.config.fps)
    homography = scene.info()["homography"]
    params = out / "params.yaml"
    write_params_file(params, homography,
                      method="background" if args.rgb_only else "kernel_covariance")
    remaps = list(RGB_ONLY_REMAPS) if args.rgb_only else []
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
                        timeout_s=playback_s + 360.0, linger_s=1.0, remaps=remaps)
    try:
        write_demo_bag(scene, bag, {k: p * rate for k, p in pauses.items()},
                       lead_s=lead * rate, preset=preset, thermal=not args.rgb_only)
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
                        timeout_s=playback_s + 360.0, linger_s=3.0, remaps=remaps)
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
        "seed": seed, "scene": preset, "rgb_only": bool(args.rgb_only), "frames": frames,
        "fps": fps,
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
