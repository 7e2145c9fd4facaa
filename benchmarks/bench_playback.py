"""Timing accuracy and cost of bag_player.

Compares, in the same run:

* publishing one 640x480 bgr8 image from a bag as the stored serialized bytes (what
  bag_player does) against deserializing it into an rclpy message first and publishing
  that (what a player decoding the bag would do);
* end to end over DDS (bag_player as a process, a raw subscriber here): how late each
  message arrives relative to its schedule, at rate 1 and rate 2, with the images offered
  RELIABLE (the player's default for bags without QoS) and BEST_EFFORT
  (``--qos-override /image=best_effort``), and with a deeper writer history
  (``--qos-depth 100`` instead of 10), and how many arrive.

Usage::

    .venv/bin/python benchmarks/bench_playback.py [--seconds 4] [--out docs/playback.md]
"""

from __future__ import annotations

import argparse
import os
import platform
import shlex
import statistics
import struct
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

from mk_tracker.bags.bag_io import open_bag  # noqa: E402
from mk_tracker.bags.bag_writer import BagWriter  # noqa: E402

S = 1_000_000_000
T0 = 1_700_000_000 * S


def write_bag(path: Path, seconds: float) -> dict[str, list[int]]:
    """30 Hz 640x480 bgr8 /image and 100 Hz /chatter for ``seconds``."""
    stamps: dict[str, list[int]] = {"/image": [], "/chatter": []}
    rng = np.random.default_rng(0)
    frame = rng.integers(0, 255, 640 * 480 * 3, dtype=np.uint8)
    with BagWriter(path, "mcap") as writer:
        ts = writer.typestore
        Image, Header, Time, String = (ts.types["sensor_msgs/msg/Image"],
                                       ts.types["std_msgs/msg/Header"],
                                       ts.types["builtin_interfaces/msg/Time"],
                                       ts.types["std_msgs/msg/String"])
        events = [(T0 + round(i * S / 30), "/image") for i in range(int(seconds * 30))]
        events += [(T0 + i * S // 100, "/chatter") for i in range(int(seconds * 100))]
        for t, topic in sorted(events):
            if topic == "/image":
                header = Header(stamp=Time(sec=t // S, nanosec=t % S), frame_id="camera")
                msg = Image(header=header, height=480, width=640, encoding="bgr8",
                            is_bigendian=0, step=640 * 3, data=frame)
            else:
                msg = String(data=f"tick {t}")
            writer.write(topic, t, msg)
            stamps[topic].append(t)
    return stamps


def publish_cost(bag: Path, repeat: int) -> dict[str, float]:
    """Median ms per image: publish stored bytes vs deserialize + publish."""
    import rclpy
    from rclpy.context import Context
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import Image

    with open_bag(bag) as reader:
        data = bytes(next(reader.messages(["/image"])).data)
    context = Context()
    rclpy.init(context=context, domain_id=99)
    node = rclpy.create_node("bench_publish", context=context)
    pub = node.create_publisher(Image, "/bench_image", 10)

    def med(fn) -> float:
        times = []
        for _ in range(repeat):
            t = time.perf_counter()
            fn()
            times.append((time.perf_counter() - t) * 1000)
        return statistics.median(times)

    result = {"raw bytes (bag_player)": med(lambda: pub.publish(data)),
              "deserialize + publish": med(lambda: pub.publish(deserialize_message(data,
                                                                                     Image)))}
    node.destroy_node()
    rclpy.try_shutdown(context=context)
    return result


def bag_time(topic: str, data: bytes) -> int:
    """Bag time of a received message, from its content (image header stamp / tick text)."""
    if topic == "/image":
        sec, nanosec = struct.unpack_from("<iI", data, 4)
        return sec * S + nanosec
    return int(data[8:].rstrip(b"\x00").decode().split()[1])


def end_to_end(bag: Path, stamps: dict[str, list[int]], rate: float, extra: list[str],
               reliability: str, domain: int) -> dict[str, dict[str, float]]:
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Image
    from std_msgs.msg import String

    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    context = Context()
    rclpy.init(context=context, domain_id=domain)
    node = rclpy.create_node("bench_listener", context=context)
    received: dict[str, list[tuple[float, int]]] = {"/image": [], "/chatter": []}
    policy = (ReliabilityPolicy.RELIABLE if reliability == "reliable"
              else ReliabilityPolicy.BEST_EFFORT)
    for topic, cls in (("/image", Image), ("/chatter", String)):
        qos = QoSProfile(depth=100, reliability=policy if topic == "/image"
                         else ReliabilityPolicy.RELIABLE)
        node.create_subscription(cls, topic, lambda m, tp=topic: received[tp].append(
            (time.monotonic(), bag_time(tp, m))), qos, raw=True)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    running = True

    def spin() -> None:
        while running:
            executor.spin_once(timeout_sec=0.01)
    thread = threading.Thread(target=spin, daemon=True)
    thread.start()
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    proc = subprocess.run([sys.executable, "-m", "mk_tracker.ros.bag_player", str(bag),
                           "--rate", str(rate), "--wait-for-subscribers", "10", *extra],
                          env=env, cwd=REPO, capture_output=True, text=True, timeout=300)
    time.sleep(0.5)
    running = False
    thread.join()
    executor.shutdown()
    node.destroy_node()
    rclpy.try_shutdown(context=context)
    if proc.returncode != 0:
        raise RuntimeError(proc.stderr)
    # schedule origin: the first /chatter message (t = T0, always first in the bag)
    first = [w for w, t in received["/chatter"] if t == T0]
    origin = first[0] if first else float("nan")
    out = {}
    for topic, arrivals in received.items():
        errors = [abs((w - origin) - (t - T0) / S / rate) * 1000 for w, t in arrivals]
        out[topic] = {"received": len(arrivals), "sent": len(stamps[topic]),
                      "player": proc.stdout.strip().rpartition("; ")[2],
                      "median_ms": statistics.median(errors) if errors else float("nan"),
                      "p95_ms": float(np.percentile(errors, 95)) if errors else float("nan"),
                      "max_ms": max(errors) if errors else float("nan")}
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=4.0, help="bag length")
    parser.add_argument("--repeat", type=int, default=50, help="publish-cost repetitions")
    parser.add_argument("--out", default=str(REPO / "docs" / "playback.md"))
    args = parser.parse_args()
    command = "  ".join([".venv/bin/python benchmarks/bench_playback.py",
                         shlex.join(sys.argv[1:])]).strip()
    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(tmp) / "bench"
        stamps = write_bag(bag, args.seconds)
        cost = publish_cost(bag, args.repeat)
        for name, ms in cost.items():
            print(f"publish one 640x480 bgr8 image, {name}: {ms:.3f} ms")
        runs = []
        domain = 60 + os.getpid() % 30
        for rate in (1.0, 2.0):
            for label, extra in (("reliable", []),
                                 ("reliable, --qos-depth 100", ["--qos-depth", "100"]),
                                 ("best_effort", ["--qos-override", "/image=best_effort"])):
                result = end_to_end(bag, stamps, rate, extra, label.split(",")[0], domain)
                runs.append((rate, label, result))
                for topic, r in result.items():
                    print(f"rate {rate} images {label} {topic}: {r['received']}/{r['sent']} "
                          f"received, |lateness| median {r['median_ms']:.1f} ms, "
                          f"p95 {r['p95_ms']:.1f} ms, max {r['max_ms']:.1f} ms; player: "
                          f"{r['player']}")
                domain += 1
    lines = ["# bag_player: timing accuracy and publishing cost", "",
             "Produced by:", "", "```", command, "```", "",
             f"Machine: {platform.machine()}, {os.cpu_count()} cores, Python "
             f"{platform.python_version()}, rclpy 7.1 wheels, Fast DDS; load average "
             f"{os.getloadavg()[0]:.1f} at the end of the run (other processes were "
             "running: figures on a loaded machine).", "",
             f"Bag: {args.seconds:g} s, /image 640x480 bgr8 at 30 Hz (921,600 B per message), "
             "/chatter String at 100 Hz.", "",
             "## Publishing one image (no subscriber), median of "
             f"{args.repeat}", "", "| method | ms per image |", "| --- | --- |"]
    lines += [f"| {name} | {ms:.3f} |" for name, ms in cost.items()]
    lines += ["", "## End to end over DDS (player process -> subscriber in another process)",
              "", "Lateness = |arrival - scheduled arrival|, the schedule anchored at the "
              "first /chatter message; each arrival is matched to its bag time by content "
              "(image header stamp, tick number).  The subscriber's image QoS matches the "
              "player's; /chatter is reliable on both sides.", "",
              "The last column is the player's own report (how late it called publish "
              "relative to the schedule, all topics): the difference to the arrival "
              "lateness is DDS transport and the subscriber.", "",
              "| rate | player QoS | topic | received/sent | median ms | p95 ms | max ms | "
              "player |", "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for rate, label, result in runs:
        for topic, r in result.items():
            lines.append(f"| {rate:g} | {label} | {topic} | {r['received']}/{r['sent']} | "
                         f"{r['median_ms']:.1f} | {r['p95_ms']:.1f} | {r['max_ms']:.1f} | "
                         f"{r['player']} |")
    Path(args.out).write_text("\n".join(lines) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
