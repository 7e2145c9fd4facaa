"""End-to-end latency and sustained rate of detector_node + tracker_node (640x480, 30 Hz).

For each crowd size (``--people``, default 5 and 15) both nodes run as separate processes
(``python -m mk_tracker.ros.detector_node`` / ``tracker_node`` with config/detector.yaml /
config/tracker.yaml) on a ROS domain nobody else uses, localhost discovery and the
shared-memory Fast DDS profile config/fastdds_shm.xml (test/nodes_harness.py's ``ros_env``).
This process pre-renders ``crowd_scene(n, width=640, height=480)`` into Image messages,
warms the nodes up (publishing until the detector's first non-empty detections and the
tracker's first tracks arrive: the first full-frame pass compiles numba code), then
publishes RGB (bgr8, ``image_raw``) and thermal (mono8, ``thermal/image_raw``) at ``--rate``
Hz for ``--seconds`` with header stamp = wall-clock publication time, and subscribes to
``tracks`` and ``thermal/detections`` on a background executor thread.

``--thermal-clip VIDEO`` measures the thermal-only set-up instead (issue #19): the frames of
a real thermal recording (mono8, e.g. BU-TIV-lab 512x512, played back and forth when the run
needs more frames than it has) go on ``thermal/image_raw`` only, the tracker's ``image_raw`` is
remapped to it (as ``ros2 launch ... thermal_only:=true`` does) and the detector gets
``--ignore-region`` (the burned-in counter of BU-TIV-lab by default); nothing is published on
``image_raw``.  Visible people are unknown there (no ground truth)::

    .venv/bin/python benchmarks/latency.py --thermal-clip ../shared/data/thermal/BU-TIV-lab/BU-TIV-lab.mp4 \
        --output docs/latency_thermal_only.md

Per crowd size it reports frames published, messages received, sustained rate, latency =
receive time - image stamp carried by the message (median, p95, max) for both outputs, the
nodes' own dropped-frame counters, and the load average before/after.  Writes
docs/latency.md with the exact command::

    .venv/bin/python benchmarks/latency.py
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
for _path in (REPO, REPO / "test", REPO / "benchmarks"):
    if str(_path) not in sys.path:
        sys.path.insert(0, str(_path))

import numpy as np  # noqa: E402

DETECTOR = "mk_tracker.ros.detector_node"
TRACKER = "mk_tracker.ros.tracker_node"
# periodic report lines of the nodes (logged when the drop counter grew since the last one)
_REPORT = {
    DETECTOR: re.compile(r"\[(\d+\.\d+)\] \[detector_node\]: (\d+) frames, \d+ detections, "
                         r"(\d+) frames dropped"),
    TRACKER: re.compile(r"\[(\d+\.\d+)\] \[tracker_node\]: (\d+) frames tracked, "
                        r"(\d+) dropped"),
}


class _EnvSetter:
    """``setenv`` on os.environ, for test/quiet_domain.py's monkeypatch argument."""

    @staticmethod
    def setenv(key: str, value: str) -> None:
        os.environ[key] = value


def stamp_ns(msg) -> int:
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


def summary_ms(latencies_s: list[float]) -> dict[str, float]:
    """Median, p95 and max of latencies (seconds) in ms; NaN when there are none."""
    if not latencies_s:
        return {"median": float("nan"), "p95": float("nan"), "max": float("nan")}
    a = 1e3 * np.asarray(latencies_s)
    return {"median": float(np.median(a)), "p95": float(np.percentile(a, 95)),
            "max": float(a.max())}


def drops_before(log: str, module: str, wall_time: float) -> int:
    """The node's drop counter in its last periodic report logged before ``wall_time``
    (0 if none): subtracted from the shutdown total to get the drops of the measurement."""
    dropped = 0
    for match in _REPORT[module].finditer(log):
        if float(match.group(1)) < wall_time:
            dropped = int(match.group(3))
    return dropped


def warmup_index(j: int, frames: int) -> int:
    """Frame of the ``j``-th warm-up publication: 0, 1, ..., frames-1, then back and forth
    (frames-2, ..., 0, 1, ...) so the scene keeps moving."""
    if j < frames or frames < 2:
        return min(j, frames - 1)
    m = j % (2 * frames - 2)
    return m if m < frames else 2 * frames - 2 - m


def clip_messages(path: Path) -> tuple[list[tuple], list[float]]:
    """(thermal mono8, None) Image messages of every frame of a thermal recording, and NaN
    visible-people counts (a recording has no ground truth)."""
    import cv2
    from std_msgs.msg import Header

    from mk_tracker.bags.recording_import import open_recording
    from mk_tracker.messages.image_conversion import numpy_to_image
    from mk_tracker.messages.message_types import ros_message_types

    types = ros_message_types()
    out = []
    for frame in open_recording(path, None).frames():
        grey = frame if frame.ndim == 2 else cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        out.append((numpy_to_image(np.ascontiguousarray(grey, dtype=np.uint8), "mono8",
                                   Header(frame_id="thermal_camera"), types=types), None))
    if len(out) < 2:
        raise RuntimeError(f"{path}: fewer than 2 frames")
    return out, [float("nan")] * len(out)


def render_messages(n_people: int, seed: int, frames: int) -> tuple[list[tuple], list[int]]:
    """(thermal mono8, RGB bgr8) Image messages of every frame, rendered before timing, and
    the number of people visible in the RGB plane of each frame (ground truth)."""
    from std_msgs.msg import Header

    from mk_tracker.messages.image_conversion import numpy_to_image
    from mk_tracker.messages.message_types import ros_message_types
    from mk_tracker.synthetic.presets import crowd_scene

    types = ros_message_types()
    scene = crowd_scene(n_people=n_people, seed=seed, width=640, height=480, frames=frames)
    out, visible = [], []
    for i in range(frames):
        f = scene.frame(i)
        visible.append(sum(1 for o in scene.ground_truth(i)
                           if o.in_frame_rgb and o.visible_fraction > 0.0))
        out.append((numpy_to_image(f.thermal, "mono8", Header(frame_id="thermal_camera"),
                                   types=types),
                    numpy_to_image(f.rgb, "bgr8", Header(frame_id="camera"), types=types)))
    return out, visible


def measure(n_people: int, args: argparse.Namespace) -> dict:
    from builtin_interfaces.msg import Time
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Image
    from vision_msgs.msg import Detection2DArray

    from nodes_harness import READY, NodeProcess, Peer, ros_env
    from quiet_domain import quiet_domain
    from soak import node_statistics

    warm_frames = int(round(args.warmup_seconds * args.rate))
    count = int(round(args.seconds * args.rate))
    t_render = time.monotonic()
    clip = args.thermal_clip is not None
    if clip:
        messages, visible = clip_messages(args.thermal_clip)
        frames = len(messages)
    else:
        messages, visible = render_messages(n_people, args.seed, warm_frames + count)
        frames = warm_frames + count
    render_s = time.monotonic() - t_render

    domain = quiet_domain(_EnvSetter())       # also sets the ROS/Fast DDS env of this process
    env = ros_env(domain)
    args.log_dir.mkdir(parents=True, exist_ok=True)
    load_before = os.getloadavg()
    nodes: dict[str, NodeProcess] = {}
    image_qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                           reliability=ReliabilityPolicy.BEST_EFFORT)
    output_qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                            reliability=ReliabilityPolicy.RELIABLE)
    received: dict[str, list[tuple[float, int, int]]] = {"tracks": [], "detections": []}
    peer = None
    stop_spin = threading.Event()
    spinner = None
    result: dict = {"people": n_people, "clip": clip, "domain": domain, "render_s": render_s}
    try:
        extra = {DETECTOR: [], TRACKER: []}
        if clip:
            regions = ", ".join(f"{float(v)}" for v in args.ignore_region)
            extra = {DETECTOR: ["-p", f"ignore_regions:=[{regions}]"],
                     TRACKER: ["-r", "image_raw:=thermal/image_raw"]}
        for module, config in ((DETECTOR, "detector"), (TRACKER, "tracker")):
            nodes[module] = NodeProcess(
                module, ["--params-file", str(REPO / "config" / f"{config}.yaml"),
                         "-p", "report_period:=0.1", *extra[module]], env,
                args.log_dir / f"{config}_node_{n_people}.log")
        ready = dict(READY)
        if clip:
            ready[TRACKER] = "tracking /thermal/image_raw"
        for module, node in nodes.items():
            if not node.wait_for_output(ready[module], 60.0):
                raise RuntimeError(f"{module} did not start:\n{node.output()}")
        peer = Peer(domain, "latency_bench")
        thermal_pub = peer.publisher(Image, "thermal/image_raw", image_qos)
        rgb_pub = peer.publisher(Image, "image_raw", image_qos)

        def collector(key: str):
            store = received[key]

            def on_message(msg) -> None:
                store.append((time.time(), stamp_ns(msg), len(msg.detections)))
            return on_message

        peer.node.create_subscription(Detection2DArray, "tracks", collector("tracks"),
                                      output_qos)
        peer.node.create_subscription(Detection2DArray, "thermal/detections",
                                      collector("detections"), output_qos)
        if not peer.spin_until(lambda: thermal_pub.get_subscription_count() >= (2 if clip
                                                                             else 1)
                               and (clip or rgb_pub.get_subscription_count() > 0)
                               and peer.node.count_publishers("tracks") > 0
                               and peer.node.count_publishers("thermal/detections") > 0,
                               30.0):
            raise RuntimeError("the nodes did not connect")
        peer.spin_for(1.0)   # discovery settles both ways

        def spin() -> None:
            while not stop_spin.is_set():
                peer.executor.spin_once(timeout_sec=0.05)

        spinner = threading.Thread(target=spin, daemon=True)
        spinner.start()
        period = 1.0 / args.rate

        def publish(index: int) -> int:
            thermal, rgb = messages[index]
            now_ns = time.time_ns()
            stamp = Time(sec=now_ns // 1_000_000_000, nanosec=now_ns % 1_000_000_000)
            thermal.header.stamp = stamp
            thermal_pub.publish(thermal)
            if rgb is not None:
                rgb.header.stamp = stamp
                rgb_pub.publish(rgb)
            return now_ns

        # warm-up: the scene's first frames at the publish rate (played back and forth if
        # the budget runs out: a held frame has no motion and the detector finds nothing
        # in it) until the detector has found people and the tracker answers
        t_warm = time.monotonic()
        i = 0
        warmed = False
        while time.monotonic() - t_warm < args.warmup_timeout:
            publish(warmup_index(i, min(warm_frames, frames)))
            i += 1
            if (any(n > 0 for _, _, n in received["detections"])
                    and any(n > 0 for _, _, n in received["tracks"])):
                warmed = True
                break
            time.sleep(max(0.0, t_warm + i * period - time.monotonic()))
        result["warmup_s"] = time.monotonic() - t_warm
        result["warmup_frames"] = i
        result["warmed_up"] = warmed
        # settle: keep streaming so that the nodes' last drop report before the
        # measurement includes the warm-up's drops
        for _ in range(int(round(args.settle * args.rate))):
            time.sleep(max(0.0, t_warm + i * period - time.monotonic()))
            publish(warmup_index(i, min(warm_frames, frames)))
            i += 1
        # the measurement continues the scene's motion (a jump only after back-and-forth)
        first = i if i <= min(warm_frames, frames) else min(warm_frames, frames)
        result["continuous"] = i <= min(warm_frames, frames)

        # measurement
        shown = [warmup_index(first + k, frames) for k in range(count)]
        result["visible_mean"] = float(np.mean([visible[j] for j in shown]))
        published: set[int] = set()
        late = 0
        t0_wall = time.time()
        t0 = time.monotonic()
        for k in range(count):
            delay = t0 + k * period - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            elif delay < -period:
                late += 1
            published.add(publish(shown[k]))
        t_end = time.monotonic()
        time.sleep(args.drain)
        stop_spin.set()
        spinner.join(5.0)
        result.update(published=count, publish_s=t_end - t0, late_publications=late,
                      measure_start_wall=t0_wall)
        window = (t_end - t0) + period
        for key in ("tracks", "detections"):
            rows = [(rx, st, n) for rx, st, n in received[key] if st in published]
            result[f"{key}_received"] = len(rows)
            result[f"{key}_rate"] = len(rows) / window
            result[f"{key}_latency"] = summary_ms([rx - st * 1e-9 for rx, st, _ in rows])
            result[f"{key}_mean_objects"] = (float(np.mean([n for _, _, n in rows]))
                                             if rows else float("nan"))
        result["alive"] = all(node.alive() for node in nodes.values())
    finally:
        stop_spin.set()
        if spinner is not None:
            spinner.join(5.0)
        if peer is not None:
            peer.close()
        for node in nodes.values():
            node.stop()
    result["load_before"] = load_before
    result["load_after"] = os.getloadavg()
    for module, key in ((DETECTOR, "detector"), (TRACKER, "tracker")):
        log = nodes[module].output()
        stats = node_statistics(log)
        result[f"{key}_frames_total"] = stats.get("frames")
        result[f"{key}_dropped_total"] = stats.get("dropped")
        if stats.get("dropped") is not None and "measure_start_wall" in result:
            result[f"{key}_dropped_measured"] = stats["dropped"] - drops_before(
                log, module, result["measure_start_wall"])
    return result


def _fmt(x: float) -> str:
    return "n/a" if x != x else f"{x:.1f}"


def _label(r: dict) -> str:
    return "thermal clip" if r.get("clip") else f"{r['people']} people"


def report(results: list[dict], args: argparse.Namespace, command: str) -> str:
    clip = args.thermal_clip
    setup = (f"thermal only, {clip.name}" if clip is not None else "640x480")
    what = (
        f"The benchmark process reads `{clip.name if clip else ''}` into mono8 Image messages "
        "(played back and forth when the run needs more frames than the clip has), warms the "
        "nodes up (publishes until the first non-empty detections and tracks arrive), then "
        "publishes them on `thermal/image_raw` only (the tracker's `image_raw` remapped to "
        "it, as `thermal_only:=true` does; the detector's `ignore_regions` = "
        f"{list(args.ignore_region)}), best effort, at {args.rate:g} Hz for {args.seconds:g} "
        "s with header stamp = wall-clock publication time" if clip is not None else
        "The benchmark process pre-renders "
        f"`crowd_scene(n, seed={args.seed}, width=640, height=480)` into Image messages, "
        "warms the nodes up (publishes until the first non-empty detections and tracks "
        "arrive), then publishes thermal mono8 (`thermal/image_raw`) and RGB bgr8 "
        f"(`image_raw`), best effort, at {args.rate:g} Hz for {args.seconds:g} s with header "
        "stamp = wall-clock publication time")
    lines = [
        f"# End-to-end latency of detector_node + tracker_node ({setup}, "
        f"{args.rate:g} Hz)",
        "",
        f"Produced by (finished {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, 2-core "
        "machine, no GPU, shared with other work; load average below):",
        "",
        "```",
        command,
        "```",
        "",
        "Both nodes are separate processes started with config/detector.yaml / "
        "config/tracker.yaml (plus `report_period:=0.1` so their drop counters are logged "
        "every 0.1 s), own ROS_DOMAIN_ID, ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, Fast DDS "
        "profile config/fastdds_shm.xml.  " + what + ", and receives `tracks` and `thermal/detections` "
        "(reliable) in the same process on an executor thread.  Latency = receive time - "
        "the image stamp the message carries (transport + queueing + processing + "
        "transport); only messages answering a frame of the measurement count.  'Dropped' "
        "= the node's own counter of frames replaced by a newer one before it processed "
        "them, during the measurement (shutdown total minus the last periodic report before "
        "the measurement started, +-0.1 s; the warm-up is followed by "
        f"{args.settle:g} s of streaming before the measurement).",
        "",
        "| | " + " | ".join(f"{_label(r)}, run {r['repeat']}" for r in results)
        + " |",
        "|---|" + "---|" * len(results),
    ]

    def row(label: str, fn) -> None:
        lines.append(f"| {label} | " + " | ".join(fn(r) for r in results) + " |")

    row("warm-up (s / frames)", lambda r: f"{r.get('warmup_s', float('nan')):.1f} / "
        f"{r.get('warmup_frames', '?')}" + ("" if r.get("warmed_up") else " (timed out)")
        + ("" if r.get("continuous", True) else " (scene jumps at the start)"))
    row("frames published (each plane)", lambda r: f"{r['published']}")
    row("publish duration s (late publications)",
        lambda r: f"{r['publish_s']:.2f} ({r['late_publications']})")
    row("tracks messages received", lambda r: f"{r['tracks_received']}")
    row("sustained tracks rate, /s", lambda r: f"{r['tracks_rate']:.1f}")
    row("tracks latency median / p95 / max, ms",
        lambda r: " / ".join(_fmt(r["tracks_latency"][k]) for k in ("median", "p95", "max")))
    row("people visible in RGB per frame (mean, ground truth)",
        lambda r: _fmt(r["visible_mean"]))
    row("tracks per message (mean)", lambda r: _fmt(r["tracks_mean_objects"]))
    row("tracker_node dropped (measurement / whole run)",
        lambda r: f"{r.get('tracker_dropped_measured', '?')} / {r.get('tracker_dropped_total', '?')}")
    row("detections messages received", lambda r: f"{r['detections_received']}")
    row("detector rate, /s", lambda r: f"{r['detections_rate']:.1f}")
    row("detections latency median / p95 / max, ms",
        lambda r: " / ".join(_fmt(r["detections_latency"][k])
                             for k in ("median", "p95", "max")))
    row("detections per message (mean)", lambda r: _fmt(r["detections_mean_objects"]))
    row("detector_node dropped (measurement / whole run)",
        lambda r: f"{r.get('detector_dropped_measured', '?')} / "
        f"{r.get('detector_dropped_total', '?')}")
    row("nodes alive at the end", lambda r: str(r.get("alive")))
    row("load average 1/5/15 min before",
        lambda r: " / ".join(f"{x:.2f}" for x in r["load_before"]))
    row("load average 1/5/15 min after",
        lambda r: " / ".join(f"{x:.2f}" for x in r["load_after"]))
    lines += ["", "## Interpretation (generated from the figures above)", ""]
    lines += interpretation(results, args.rate)
    lines.append("")
    return "\n".join(lines)


def interpretation(results: list[dict], rate: float) -> list[str]:
    """Plain statements derived from the measured figures (no hand-edited numbers)."""
    out = []
    for n in sorted({r["people"] for r in results}):
        runs = [r for r in results if r["people"] == n]
        share = [100.0 * r["tracks_received"] / r["published"] for r in runs]
        det = [r["detections_rate"] for r in runs]
        keeps_up = min(share) >= 95.0
        out.append(
            f"* {_label(runs[0])}: the tracker answered {_span(share, '%')} of the {rate:g} Hz "
            f"frames ({_span([r['tracks_rate'] for r in runs], '/s')}), so it "
            + ("keeps up" if keeps_up else "does not keep up; it skips to the newest frame "
               "(the dropped counter) instead of queueing, which bounds the latency")
            + f"; median tracks latency {_span([r['tracks_latency']['median'] for r in runs], ' ms')}"
            f", p95 {_span([r['tracks_latency']['p95'] for r in runs], ' ms')}.  It held "
            f"{_span([r['tracks_mean_objects'] for r in runs], '')} tracks per frame"
            + (" (visible people unknown: no ground truth)" if runs[0].get("clip") else
               f" for {_span([r['visible_mean'] for r in runs], '')} visible people")
            + f".  The detector "
            f"ran at {_span(det, '/s')} ({_span([100 * d / rate for d in det], '%')} of the "
            f"frames), median detections latency "
            f"{_span([r['detections_latency']['median'] for r in runs], ' ms')}."
            + (" The tracker followed fewer than half of the visible people, so this is a "
               "light tracking load, not the load of tracking all of them."
               if not runs[0].get("clip") and max(r["tracks_mean_objects"] for r in runs)
               < 0.5 * min(r["visible_mean"] for r in runs) else ""))
    if not any(r.get("clip") for r in results):
        out.append(
            "* The tracker runs one multiple-kernel mean shift per track, so its cost should "
            "follow the number of tracks it holds rather than the number of people in the "
            "scene: compare the tracks per frame of the two crowd sizes before reading the "
            "rates as 'more people = slower'.")
    out += [
        "* Latency includes the publisher's serialization, shared-memory transport both ways, "
        "waiting in the node's newest-frame slot, processing, and the receiving executor "
        "thread of this Python process (which shares the GIL with the publishing loop).  "
        "Publisher, both nodes and the rest of the machine share 2 cores (load averages in "
        "the table), so the spread between runs is part of the result.",
    ]
    return out


def _span(values: list[float], unit: str) -> str:
    vals = [v for v in values if v == v]
    if not vals:
        return "n/a"
    lo, hi = f"{min(vals):.1f}", f"{max(vals):.1f}"
    return f"{lo}{unit}" if lo == hi else f"{lo}-{hi}{unit}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0,
                        help="measurement length per crowd size")
    parser.add_argument("--rate", type=float, default=30.0, help="publish rate, Hz")
    parser.add_argument("--people", type=int, nargs="+", default=[5, 15])
    parser.add_argument("--repeats", type=int, default=2,
                        help="runs of every crowd size (each a fresh pair of nodes)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--warmup-seconds", type=float, default=10.0,
                        help="scene frames reserved for the warm-up and settle phases "
                        "(rate x this)")
    parser.add_argument("--warmup-timeout", type=float, default=120.0,
                        help="give up waiting for the first detections/tracks after this")
    parser.add_argument("--settle", type=float, default=2.0,
                        help="seconds of streaming between the warm-up and the measurement")
    parser.add_argument("--drain", type=float, default=3.0,
                        help="seconds to keep receiving after the last publication")
    parser.add_argument("--output", type=Path, default=REPO / "docs" / "latency.md")
    parser.add_argument("--log-dir", type=Path, default=Path("/tmp/mk_tracker_latency"))
    parser.add_argument("--thermal-clip", type=Path, default=None,
                        help="thermal-only set-up on this recording instead of generated "
                        "crowds (--people is then ignored)")
    parser.add_argument("--ignore-region", type=float, nargs=4, default=[0.0, 0.0, 110.0, 50.0],
                        metavar=("X", "Y", "W", "H"),
                        help="with --thermal-clip: the detector's ignore region (default: "
                        "BU-TIV-lab's burned-in counter)")
    args = parser.parse_args(argv)
    if args.thermal_clip is not None:
        if not args.thermal_clip.is_file():
            parser.error(f"{args.thermal_clip}: no such file")
        args.people = [0]
    shown = [a for a in (sys.argv[1:] if argv is None else argv)]
    command = " ".join([".venv/bin/python benchmarks/latency.py", *shown])

    results = []
    for repeat in range(1, args.repeats + 1):
        for n in args.people:
            r = measure(n, args)
            r["repeat"] = repeat
            results.append(r)
            t, d = r["tracks_latency"], r["detections_latency"]
            print(f"{_label(r)}, run {repeat}: published {r['published']}, tracks "
                  f"{r['tracks_received']} ({r['tracks_rate']:.1f}/s) latency median "
                  f"{_fmt(t['median'])} p95 {_fmt(t['p95'])} max {_fmt(t['max'])} ms, "
                  f"tracker dropped {r.get('tracker_dropped_measured')}; detections "
                  f"{r['detections_received']} ({r['detections_rate']:.1f}/s) latency median "
                  f"{_fmt(d['median'])} p95 {_fmt(d['p95'])} max {_fmt(d['max'])} ms, "
                  f"detector dropped {r.get('detector_dropped_measured')}; load "
                  f"{r['load_before']} -> {r['load_after']}", flush=True)
    results.sort(key=lambda r: (r["people"], r["repeat"]))
    text = report(results, args, command)
    args.output.write_text(text)
    print(text)
    print(f"wrote {args.output}")
    return 0 if all(r.get("alive") for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
