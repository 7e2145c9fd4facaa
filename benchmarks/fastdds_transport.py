"""Frames received / sent and latency of 640x480 bgr8 images between two processes.

Compares Fast DDS with its default transports against config/fastdds_shm.xml (a 16 MiB
shared-memory segment).  A publisher process sends ``--rate`` Hz images for ``--seconds``;
a subscriber process (best effort, keep last ``--depth``, like the nodes' image
subscriptions) counts what arrives and the latency from the header stamp.  Both processes
run on this machine, on their own ROS_DOMAIN_ID, with ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST.

    .venv/bin/python benchmarks/fastdds_transport.py

writes docs/fastdds_transport.md.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PROFILE = REPO / "config" / "fastdds_shm.xml"
TOPIC = "bench/image"


def _qos(depth: int):
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=ReliabilityPolicy.BEST_EFFORT)


def run_subscriber(args: argparse.Namespace) -> None:
    import rclpy
    from rclpy.node import Node
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Image

    rclpy.init()
    node = Node("bench_subscriber")
    latencies: list[float] = []
    seqs: set[int] = set()

    def on_message(msg) -> None:
        now = time.time()
        sent = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        latencies.append(now - sent)
        seqs.add(int(msg.header.stamp.nanosec))

    if args.node:
        # count the tracker node's output: one tracks message per processed frame
        from vision_msgs.msg import Detection2DArray
        node.create_subscription(Detection2DArray, "tracks", on_message,
                                 QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                                            reliability=ReliabilityPolicy.RELIABLE))
    else:
        node.create_subscription(Image, TOPIC, on_message, _qos(args.depth))
    print("ready", flush=True)
    deadline = time.time() + args.seconds + 8.0
    while time.time() < deadline:
        rclpy.spin_once(node, timeout_sec=0.05)
        if os.path.exists(args.done_file) and time.time() > os.path.getmtime(args.done_file) + 1.0:
            break
    latencies.sort()
    result = {"received": len(seqs),
              "median_latency_ms": 1e3 * latencies[len(latencies) // 2] if latencies else None,
              "p95_latency_ms": 1e3 * latencies[int(0.95 * (len(latencies) - 1))]
              if latencies else None}
    print("RESULT " + json.dumps(result), flush=True)
    node.destroy_node()
    rclpy.shutdown()


def run_publisher(args: argparse.Namespace) -> None:
    import numpy as np
    import rclpy
    from rclpy.node import Node
    from sensor_msgs.msg import Image

    rclpy.init()
    node = Node("bench_publisher")
    pub = node.create_publisher(Image, "image_raw" if args.node else TOPIC, _qos(args.depth))
    deadline = time.time() + 10.0
    while pub.get_subscription_count() == 0 and time.time() < deadline:
        time.sleep(0.05)
    time.sleep(1.0)  # let discovery settle both ways
    rng = np.random.default_rng(0)
    frame = rng.integers(0, 255, size=(480, 640, 3), dtype=np.uint8)
    msg = Image(height=480, width=640, encoding="bgr8", is_bigendian=0, step=640 * 3)
    msg.header.frame_id = "camera"
    msg.data = frame.tobytes()
    count = int(args.seconds * args.rate)
    period = 1.0 / args.rate
    start = time.time()
    for i in range(count):
        target = start + i * period
        delay = target - time.time()
        if delay > 0:
            time.sleep(delay)
        now = time.time()
        # the frame number travels in the nanoseconds (unique per frame, and the tracker
        # node copies the header into its output): stamp = int(now) s + i ns + ms part
        msg.header.stamp.sec = int(now)
        msg.header.stamp.nanosec = (int((now - int(now)) * 1e3) * 1_000_000) + i
        pub.publish(msg)
    print("RESULT " + json.dumps({"sent": count}), flush=True)
    Path(args.done_file).touch()
    time.sleep(0.5)
    node.destroy_node()
    rclpy.shutdown()


def _result(output: str) -> dict:
    for line in output.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[len("RESULT "):])
    raise RuntimeError(f"no result in output:\n{output}")


def measure(use_profile: bool, domain: int, args: argparse.Namespace) -> dict:
    env = dict(os.environ)
    env["ROS_DOMAIN_ID"] = str(domain)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    for var in ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE",
                "RMW_FASTRTPS_USE_QOS_FROM_XML"):
        env.pop(var, None)
    if use_profile:
        env["FASTRTPS_DEFAULT_PROFILES_FILE"] = str(PROFILE)
        env["FASTDDS_DEFAULT_PROFILES_FILE"] = str(PROFILE)
    done = Path(f"/tmp/mk_tracker_fastdds_bench_{os.getpid()}_{domain}.done")
    done.unlink(missing_ok=True)
    common = [sys.executable, __file__, "--seconds", str(args.seconds), "--rate",
              str(args.rate), "--depth", str(args.depth), "--done-file", str(done)]
    if args.node:
        common.append("--node")
    node_proc = None
    node_log = Path(f"/tmp/mk_tracker_fastdds_bench_{os.getpid()}_{domain}.log")
    if args.node:
        env["PYTHONPATH"] = os.pathsep.join([str(REPO), env.get("PYTHONPATH", "")])
        node_proc = subprocess.Popen(
            [sys.executable, "-m", "mk_tracker.ros.tracker_node"], env=env,
            stdout=node_log.open("w"), stderr=subprocess.STDOUT, start_new_session=True)
        deadline = time.time() + 30
        while "tracking" not in node_log.read_text() and time.time() < deadline:
            time.sleep(0.1)
    sub = subprocess.Popen(common + ["--role", "sub"], env=env, stdout=subprocess.PIPE,
                           text=True)
    try:
        assert sub.stdout is not None
        sub.stdout.readline()  # "ready"
        pub = subprocess.run(common + ["--role", "pub"], env=env, capture_output=True,
                             text=True, timeout=args.seconds + 30)
        out, _ = sub.communicate(timeout=args.seconds + 30)
    finally:
        if sub.poll() is None:
            sub.kill()
            sub.wait()
        done.unlink(missing_ok=True)
        if node_proc is not None:
            os.killpg(node_proc.pid, signal.SIGINT)
            try:
                node_proc.wait(10)
            except subprocess.TimeoutExpired:
                os.killpg(node_proc.pid, signal.SIGKILL)
                node_proc.wait()
    result = _result(pub.stdout)
    result.update(_result(out))
    if node_proc is not None:
        log = node_log.read_text()
        node_log.unlink(missing_ok=True)
        match = re.search(r"'dropped': (\d+)", log)
        result["node_dropped"] = int(match.group(1)) if match else None
    result["profile"] = "config/fastdds_shm.xml" if use_profile else "Fast DDS defaults"
    return result


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--role", choices=("bench", "pub", "sub"), default="bench")
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--rate", type=float, default=30.0)
    parser.add_argument("--depth", type=int, default=1)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--done-file", default="")
    parser.add_argument("--node", action="store_true",
                        help="send the images to a tracker_node process (default QoS) and "
                        "count its tracks messages, i.e. frames the node processed")
    parser.add_argument("--output", default=None,
                        help="markdown report (default docs/fastdds_transport.md, or "
                        "docs/fastdds_tracker_node.md with --node)")
    args = parser.parse_args()
    if args.output is None:
        args.output = str(REPO / "docs" / ("fastdds_tracker_node.md" if args.node
                                           else "fastdds_transport.md"))
    if args.role == "sub":
        run_subscriber(args)
        return 0
    if args.role == "pub":
        run_publisher(args)
        return 0
    rows = []
    domain = 150 + os.getpid() % 50
    for repeat in range(args.repeats):
        for use_profile in (False, True):
            r = measure(use_profile, domain, args)
            domain += 1
            r["repeat"] = repeat + 1
            rows.append(r)
            print(f"{r['profile']:<24} run {r['repeat']}: received {r['received']}/{r['sent']}"
                  f" ({100.0 * r['received'] / r['sent']:.1f} %), median latency "
                  f"{r['median_latency_ms']:.1f} ms, p95 {r['p95_latency_ms']:.1f} ms"
                  + (f", node dropped {r.get('node_dropped')}" if args.node else ""),
                  flush=True)
    command = "    .venv/bin/python benchmarks/fastdds_transport.py " + " ".join(
        a for a in sys.argv[1:] if not a.startswith("--output"))
    if args.node:
        title = "# Fast DDS transport: 640x480 bgr8 into tracker_node"
        setup = (f"{args.rate:g} Hz for {args.seconds:g} s per run from a best-effort publisher "
                 "process into a tracker_node process with its default image QoS (sensor "
                 "data, best effort, depth 1, newest frame only); a third process counts the "
                 "node's `tracks` messages (one per processed frame). 'node dropped' = frames "
                 "the node received but replaced by a newer one before processing (its own "
                 "count). Latency = tracks receive time - image stamp (transport + tracking "
                 "+ transport).")
        header = ["| profile | run | processed / sent | % | node dropped | median latency ms "
                  "| p95 latency ms |", "|---|---|---|---|---|---|---|"]
    else:
        title = "# Fast DDS transport: 640x480 bgr8 between two processes"
        setup = (f"{args.rate:g} Hz for {args.seconds:g} s per run, best-effort publisher and "
                 f"subscriber (keep last {args.depth}), rclpy in both processes. Latency = "
                 "receive time - header stamp (same clock), over the received frames only.")
        header = ["| profile | run | received / sent | % | median latency ms | p95 latency ms |",
                  "|---|---|---|---|---|---|"]
    lines = [title, "", "Produced by:", "", command.rstrip(), "",
             setup + " ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, own ROS_DOMAIN_ID per run, "
             "2-core machine shared with other work.", ""] + header
    for r in rows:
        dropped = f" {r.get('node_dropped')} |" if args.node else ""
        lines.append(f"| {r['profile']} | {r['repeat']} | {r['received']} / {r['sent']} | "
                     f"{100.0 * r['received'] / r['sent']:.1f} |{dropped} "
                     f"{r['median_latency_ms']:.1f} | {r['p95_latency_ms']:.1f} |")
    Path(args.output).write_text("\n".join(lines) + "\n")
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
