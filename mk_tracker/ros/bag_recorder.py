"""``bag_recorder``: record chosen topics into a rosbag2 bag where ``ros2 bag record`` is not
installed.

Each requested topic is subscribed as soon as it appears in the ROS graph, with the type
the graph reports, and with ``raw=True``: the serialized CDR bytes are written unchanged
through :class:`mk_tracker.bags.bag_io.BagWriter` (mcap by default, sqlite3 on request), stamped
with the time the message was received (as ``ros2 bag record`` does).  The subscription QoS
adapts to the publishers found (as rosbag2 does): RELIABLE if every publisher offers
RELIABLE, else BEST_EFFORT; TRANSIENT_LOCAL if every publisher offers it, else VOLATILE.
The offered profiles of those publishers are stored in the bag metadata, so that
``bag_player`` (or ``ros2 bag play``) can reproduce them.

SIGINT and SIGTERM stop the recording cleanly: the messages already received (waiting in
the subscriptions' queues) are written first (:func:`drain`), then subscriptions are
destroyed, the bag is closed and its ``metadata.yaml`` written, and the exit status is 0.

Example::

    bag_recorder -o out/run1 /tracks /detections
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import time
from typing import Any, Sequence

from mk_tracker.bags.bag_errors import BagError, RosbagsMissing, require_bag_io
from mk_tracker.ros.bag_player import message_class


def _log(text: str) -> None:
    print(f"bag_recorder: {text}", file=sys.stderr, flush=True)


def adapted_qos(publisher_profiles: Sequence[Any], depth: int) -> Any:
    """Subscription QoS that matches every publisher (see the module docstring)."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    reliable = bool(publisher_profiles) and all(
        p.reliability == ReliabilityPolicy.RELIABLE for p in publisher_profiles)
    transient = bool(publisher_profiles) and all(
        p.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in publisher_profiles)
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=(ReliabilityPolicy.RELIABLE if reliable
                                   else ReliabilityPolicy.BEST_EFFORT),
                      durability=(DurabilityPolicy.TRANSIENT_LOCAL if transient
                                  else DurabilityPolicy.VOLATILE))


def offered_qos_records(publisher_profiles: Sequence[Any]) -> list[dict]:
    """Publishers' QoS as the plain dicts rosbag2 stores in ``offered_qos_profiles``."""
    records = []
    for p in publisher_profiles:
        records.append({"history": int(p.history), "depth": int(p.depth),
                        "reliability": int(p.reliability), "durability": int(p.durability)})
    return records


class Recorder:
    """Subscribes to ``topics`` when they appear and writes what arrives to ``writer``."""

    def __init__(self, node: Any, writer: Any, topics: Sequence[str], depth: int) -> None:
        self.node = node
        self.writer = writer
        self.wanted = ["/" + t.lstrip("/") for t in topics]
        self.depth = depth
        self.subscriptions: dict[str, Any] = {}
        self.counts: dict[str, int] = {}
        self.warned: set[str] = set()

    def discover(self) -> None:
        """Subscribe to every wanted topic that now has a publisher with a known type."""
        graph = dict(self.node.get_topic_names_and_types())
        for topic in self.wanted:
            if topic in self.subscriptions or topic not in graph:
                continue
            infos = self.node.get_publishers_info_by_topic(topic)
            if not infos:
                continue
            types = graph[topic]
            msgtype = types[0]
            if len(types) > 1 and topic not in self.warned:
                _log(f"{topic} is published with several types {types}; recording {msgtype}")
                self.warned.add(topic)
            try:
                cls = message_class(msgtype)
            except ImportError as exc:
                if topic not in self.warned:
                    _log(f"cannot record {topic} [{msgtype}]: {exc}")
                    self.warned.add(topic)
                continue
            profiles = [i.qos_profile for i in infos]
            try:
                self.writer.add_topic(topic, msgtype,
                                      offered_qos_profiles=offered_qos_records(profiles))
            except BagError as exc:
                if topic not in self.warned:
                    _log(f"cannot record {topic} [{msgtype}]: {exc}")
                    self.warned.add(topic)
                continue
            self.counts[topic] = 0
            self.subscriptions[topic] = self.node.create_subscription(
                cls, topic, self._callback(topic), adapted_qos(profiles, self.depth), raw=True)
            print(f"recording {topic} [{msgtype}]", flush=True)

    def _callback(self, topic: str):
        def on_message(data: bytes, info: Any) -> None:
            stamp = info.get("received_timestamp") if isinstance(info, dict) else None
            self.writer.write_raw(topic, int(stamp) if stamp else time.time_ns(), bytes(data))
            self.counts[topic] += 1
        return on_message


def drain(executor: Any, recorder: Recorder, max_rounds: int = 100_000) -> int:
    """Write what the subscriptions already hold: non-blocking spins until two in a row
    take no message (one may run another ready callback, e.g. a guard condition);
    ``max_rounds`` bounds a publisher that never pauses.  Returns how many were written.

    Without it a stop right after the last message arrived lost the messages the executor
    had not taken yet (a player whose every message was acknowledged, then a Ctrl-C)."""
    start = total = sum(recorder.counts.values())
    idle = 0
    for _ in range(max_rounds):
        executor.spin_once(timeout_sec=0.0)
        now = sum(recorder.counts.values())
        idle = idle + 1 if now == total else 0
        total = now
        if idle == 2:
            break
    return total - start


def configure_parser(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("topics", nargs="+", metavar="TOPIC", help="topics to record")
    parser.add_argument("-o", "--output", required=True, help="bag directory to create")
    parser.add_argument("--storage", choices=("mcap", "sqlite3"), default="mcap")
    parser.add_argument("--qos-depth", type=int, default=100, metavar="N",
                        help="keep-last depth of each subscription (default 100)")
    parser.add_argument("--discovery-period", type=float, default=0.1, metavar="S",
                        help="how often to look for the topics in the graph")


def run(args: argparse.Namespace) -> int:
    bag_io = require_bag_io("bag_recorder")     # rosbags on first use (main reports it)
    stop = threading.Event()

    def on_signal(*_: Any) -> None:
        stop.set()

    # signals first: a Ctrl-C while rclpy loads still finalises the bag
    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    try:
        writer = bag_io.BagWriter(args.output, storage=args.storage)
        writer.open()  # the bag exists (and is finalised) even if no topic ever appears
    except (BagError, ValueError, OSError) as exc:
        _log(f"error: cannot create bag {args.output!r}: {exc}")
        return 2
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("bag_recorder")
    recorder = Recorder(node, writer, args.topics, args.qos_depth)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    print(f"recording into {args.output} ({args.storage}); waiting for "
          f"{', '.join(recorder.wanted)}", flush=True)
    next_discovery = 0.0
    try:
        while not stop.is_set():
            if time.monotonic() >= next_discovery:
                recorder.discover()
                next_discovery = time.monotonic() + args.discovery_period
            executor.spin_once(timeout_sec=0.05)
        drain(executor, recorder)
    finally:
        for sub in recorder.subscriptions.values():
            node.destroy_subscription(sub)
        writer.close()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    total = sum(recorder.counts.values())
    counts = ", ".join(f"{t}: {n}" for t, n in recorder.counts.items()) or "no topic seen"
    print(f"recorded {total} messages into {args.output} ({counts})", flush=True)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="bag_recorder", description=__doc__.splitlines()[0])
    configure_parser(parser)
    args = parser.parse_args(argv)
    try:
        return run(args)
    except RosbagsMissing as exc:
        _log(f"error: {exc}")
        return 2


if __name__ == "__main__":
    sys.exit(main())
