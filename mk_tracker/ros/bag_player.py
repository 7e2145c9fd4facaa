"""``bag_player``: play a rosbag2 bag over DDS where ``ros2 bag play`` is not installed.

Reads sqlite3 and mcap bags, split bags and bags recorded by real ROS 2 through
:mod:`mk_tracker.bags.bag_io`, and publishes each message's serialized CDR bytes unchanged
(rclpy 7.1 ``Publisher.publish`` accepts a ``bytes`` object and hands it to
``rcl_publish_serialized_message``; the message class is still needed for the type support).
Timing, rate, loop, start offset, topic selection, remapping and ``/clock`` follow
:mod:`mk_tracker.bags.playback`, which also documents the QoS rule (offered QoS from the bag
metadata when present, else RELIABLE/VOLATILE, depth ``--qos-depth``; ``--qos-override``
per topic).

Topics whose message type has no importable Python package (e.g. ``test_msgs``) cannot be
published by rclpy; they are named on stderr and the other topics are played.  A missing or
unreadable bag is reported in one line (exit status 2), not a traceback; if the bag breaks
part-way, every message read before the damage is played and the exit status is 1.

Example::

    bag_player out/scene --rate 2 --loop --clock 40 --remap /camera/image:=/image
"""

from __future__ import annotations

import argparse
import importlib
import signal
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator, Sequence

import yaml

from mk_tracker.bags.bag_errors import RosbagsMissing, require_bag_io
from mk_tracker.bags.playback import (DEFAULT_DEPTH, RELIABLE, TRANSIENT_LOCAL, PlaybackError,
                                 PlaybackOptions, PlaybackPlan, TopicQos,
                                 offered_qos_from_metadata, parse_qos_override, parse_remaps,
                                 resolve_qos)

NS_PER_S = 1_000_000_000


def message_class(msgtype: str) -> Any:
    """``"std_msgs/msg/String"`` -> the rclpy message class, or raise ImportError."""
    parts = msgtype.split("/")
    if len(parts) != 3 or parts[1] != "msg":
        raise ImportError(f"{msgtype!r} is not a message type name")
    module = importlib.import_module(f"{parts[0]}.msg")
    try:
        return getattr(module, parts[2])
    except AttributeError as exc:
        raise ImportError(f"{parts[0]}.msg has no {parts[2]}") from exc


def to_rclpy_qos(qos: TopicQos) -> Any:
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=qos.depth,
        reliability=(ReliabilityPolicy.RELIABLE if qos.reliability == RELIABLE
                     else ReliabilityPolicy.BEST_EFFORT),
        durability=(DurabilityPolicy.TRANSIENT_LOCAL if qos.durability == TRANSIENT_LOCAL
                    else DurabilityPolicy.VOLATILE))


@dataclass
class PlayedTopic:
    bag_topic: str
    topic: str
    msgtype: str
    qos: TopicQos
    publisher: Any = None
    count: int = 0


class StopFlag:
    """Set by SIGINT/SIGTERM; sleeping on it wakes up at once."""

    def __init__(self) -> None:
        self._event = threading.Event()

    def set(self, *_: Any) -> None:
        self._event.set()

    def is_set(self) -> bool:
        return self._event.is_set()

    def sleep(self, seconds: float) -> None:
        self._event.wait(max(seconds, 0.0))


def _log(text: str) -> None:
    print(f"bag_player: {text}", file=sys.stderr, flush=True)


def bag_offered_qos(bag: str | Path) -> dict[str, list[tuple[str, str]]]:
    """Offered QoS per topic from the bag's metadata.yaml ({} when there is none)."""
    meta = Path(bag) / "metadata.yaml"
    try:
        return offered_qos_from_metadata(yaml.safe_load(meta.read_text()) or {})
    except (OSError, UnicodeDecodeError, yaml.YAMLError, AttributeError):
        return {}


def plan_topics(topics: Sequence[Any], offered: dict[str, list[tuple[str, str]]],
                plan: PlaybackPlan, default_depth: int, overrides: dict[str, TopicQos]
                ) -> tuple[dict[str, PlayedTopic], list[str]]:
    """Playable topics (bag topic -> PlayedTopic) and a description of unplayable ones.

    ``topics`` are :class:`mk_tracker.bags.bag_io.TopicInfo` records.
    """
    played: dict[str, PlayedTopic] = {}
    unplayable: list[str] = []
    for topic in topics:
        out = plan.topic_map.get(topic.name)
        if out is None:
            continue
        try:
            message_class(topic.msgtype)
        except ImportError as exc:
            unplayable.append(f"{topic.name} [{topic.msgtype}] ({topic.count} messages): "
                              f"no Python message package ({exc})")
            continue
        override = overrides.get(out) or overrides.get(topic.name) \
            or overrides.get("/" + topic.name.lstrip("/"))
        qos = resolve_qos(offered.get(topic.name, []), override, default_depth)
        played[topic.name] = PlayedTopic(topic.name, out, topic.msgtype, qos)
    return played, unplayable


#: Seconds the player still waits after every awaited subscriber has matched, so that the
#: subscribers have matched the player's writers too (see :func:`_wait_for_subscribers`).
DISCOVERY_SETTLE_S = 0.5


def _wait_for_subscribers(publishers: dict[str, Any], minimum: int, timeout_s: float,
                          stop: StopFlag) -> None:
    """Wait until each publisher (output topic -> publisher) has ``minimum`` matched
    subscriptions, or ``timeout_s``; a message published before its subscriber has matched
    would be lost (volatile) or arrive late.

    Discovery is not symmetric: this writer can match a reader before that reader has
    matched the writer, and a reliable sample sent in between reaches the reader only when
    the writer repairs it after its next heartbeat (Fast DDS: up to 3 s later; seen as a
    first detection message arriving after the frame it belongs to).  So after the last
    match the player waits ``DISCOVERY_SETTLE_S`` more."""
    deadline = time.monotonic() + timeout_s
    while not stop.is_set():
        missing = [name for name, pub in publishers.items()
                   if pub.get_subscription_count() < minimum]
        if not missing:
            stop.sleep(DISCOVERY_SETTLE_S)
            return
        if time.monotonic() >= deadline:
            _log(f"no subscriber after {timeout_s:g} s on {', '.join(missing)}; playing anyway")
            return
        stop.sleep(0.02)


def _wait_for_go(stream: Any, stop: StopFlag) -> None:
    """Block until a line or end of file arrives on ``stream``, or ``stop`` is set.

    The writer side cannot see whether a subscriber's reader has matched this writer yet
    (:func:`_wait_for_subscribers`); the subscribers can, and log it.  mk_launch reads their
    logs and sends the line, so the first message is not played before the readers exist
    for it."""
    _log("waiting for the go line on stdin")
    arrived = threading.Event()

    def read() -> None:
        try:
            stream.readline()
        except (OSError, ValueError):
            pass
        arrived.set()

    threading.Thread(target=read, daemon=True).start()
    while not (arrived.is_set() or stop.is_set()):
        arrived.wait(0.05)


@dataclass
class Lateness:
    """How late messages were published relative to their schedule (player-side only)."""

    count: int = 0
    total_ns: int = 0
    max_ns: int = 0

    def add(self, late_ns: int) -> None:
        late_ns = max(late_ns, 0)
        self.count += 1
        self.total_ns += late_ns
        self.max_ns = max(self.max_ns, late_ns)

    def summary(self) -> str:
        mean = self.total_ns / self.count / 1e6 if self.count else 0.0
        return f"publish lateness mean {mean:.2f} ms, max {self.max_ns / 1e6:.2f} ms"


def play_iteration(plan: PlaybackPlan, messages: Iterator, played: dict[str, PlayedTopic],
                   clock_publisher: Any, clock_period_ns: int, stop: StopFlag,
                   lateness: Lateness | None = None) -> int:
    """Publish one pass over ``messages`` on schedule; return how many were published."""
    from rosgraph_msgs.msg import Clock
    start = time.monotonic_ns()
    next_clock = 0
    published = 0

    def tick(elapsed: int) -> None:
        nonlocal next_clock
        if clock_publisher is not None and elapsed >= next_clock:
            now = plan.clock_ns(elapsed)
            msg = Clock()
            msg.clock.sec, msg.clock.nanosec = divmod(now, NS_PER_S)
            clock_publisher.publish(msg)
            next_clock = (elapsed // clock_period_ns + 1) * clock_period_ns

    for item in plan.schedule(messages):
        target = played.get(item.bag_topic)
        if target is None:
            continue
        while not stop.is_set():
            elapsed = time.monotonic_ns() - start
            tick(elapsed)
            wait = item.due_ns - elapsed
            if wait <= 0:
                break
            if clock_publisher is not None:
                wait = min(wait, next_clock - elapsed)
            stop.sleep(min(wait, 100_000_000) / NS_PER_S)
        if stop.is_set():
            break
        if lateness is not None:
            lateness.add(time.monotonic_ns() - start - item.due_ns)
        target.publisher.publish(item.data)
        target.count += 1
        published += 1
    if not stop.is_set():
        tick(next_clock)  # a final tick at the end of the pass
    return published


def configure_parser(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("bag", help="rosbag2 bag directory (sqlite3 or mcap, may be split)")
    parser.add_argument("--rate", type=float, default=1.0, help="playback rate factor")
    parser.add_argument("--loop", action="store_true", help="play the bag again and again")
    parser.add_argument("--start-offset", type=float, default=0.0, metavar="S",
                        help="start S seconds after the bag's first message")
    parser.add_argument("--topics", nargs="+", default=None, metavar="TOPIC",
                        help="play only these bag topics")
    parser.add_argument("--remap", action="append", default=[], metavar="FROM:=TO",
                        help="publish bag topic FROM on TO (repeatable)")
    parser.add_argument("--clock", type=float, nargs="?", const=40.0, default=0.0,
                        metavar="HZ", help="publish /clock with the bag time (default 40 Hz)")
    parser.add_argument("--qos-depth", type=int, default=DEFAULT_DEPTH, metavar="N",
                        help="keep-last depth of every publisher (default 10)")
    parser.add_argument("--qos-override", action="append", default=[],
                        metavar="TOPIC=POLICY[,POLICY]",
                        help="e.g. /camera/image=best_effort,1 (reliable|best_effort, "
                             "volatile|transient_local, depth)")
    parser.add_argument("--delay", type=float, default=0.0, metavar="S",
                        help="sleep S seconds after creating the publishers")
    parser.add_argument("--wait-for-subscribers", type=float, default=0.0, metavar="S",
                        help="wait up to S seconds until every published topic (/clock too) "
                             "has a subscriber, then 0.5 s for discovery to settle")
    parser.add_argument("--min-subscribers", type=int, default=1, metavar="N",
                        help="subscribers per topic that --wait-for-subscribers waits for")
    parser.add_argument("--wait-topics", nargs="+", default=None, metavar="TOPIC",
                        help="output topics --wait-for-subscribers waits for (default: all "
                             "played topics); played topics not named here are not awaited")
    parser.add_argument("--go-on-stdin", action="store_true",
                        help="after the wait for subscribers, play only once a line (or "
                             "end of file) arrives on stdin: mk_launch sends it when the "
                             "nodes have logged that their readers matched this player")
    parser.add_argument("--ack-timeout", type=float, default=5.0, metavar="S",
                        help="at the end, wait up to S s for reliable messages to be acked")


def run(args: argparse.Namespace) -> int:
    # rosbags is imported here, not with the module: without it the player says so
    # (RosbagsMissing, reported by main) and everything else of the package still imports
    bag_io = require_bag_io("bag_player")
    from rosbags.typesys import Stores, get_typestore

    # signals first: a Ctrl-C while the bag opens or rclpy loads ends quietly too
    stop = StopFlag()
    signal.signal(signal.SIGINT, stop.set)
    signal.signal(signal.SIGTERM, stop.set)
    reader = None
    try:
        overrides = dict(parse_qos_override(o, args.qos_depth) for o in args.qos_override)
        options = PlaybackOptions(rate=args.rate, loop=args.loop,
                                  start_offset_s=args.start_offset,
                                  topics=tuple(args.topics) if args.topics else None,
                                  remaps=parse_remaps(args.remap))
        if args.clock < 0:
            raise PlaybackError("--clock rate must be positive")
        if args.qos_depth < 1:
            raise PlaybackError("--qos-depth must be at least 1")
        # no deserialization here: an empty typestore (definitions stored in the bag are
        # still registered) saves the ~0.5 s of building the full Jazzy one
        reader = bag_io.open_bag(args.bag, on_error="skip",
                                 typestore=get_typestore(Stores.EMPTY))
        for problem in reader.problems:
            _log(f"warning: {problem}")
        reported = len(reader.problems)
        first = next(iter(reader.messages()), None)
        if first is None:
            raise PlaybackError(f"{args.bag}: no readable message in the bag")
        topics = list(reader.topics.values())
        plan = PlaybackPlan(first.timestamp_ns, [t.name for t in topics], options)
        played, unplayable = plan_topics(topics, bag_offered_qos(args.bag), plan,
                                         args.qos_depth, overrides)
        for text in unplayable:
            _log(f"cannot play {text}; playing the other topics")
        if not played:
            raise PlaybackError("none of the selected topics can be played")
    except (bag_io.BagError, PlaybackError) as exc:
        _log(f"error: {exc}")
        if reader is not None:
            reader.close()
        return 2

    import rclpy
    from rclpy.duration import Duration
    from rclpy.signals import SignalHandlerOptions
    from rosgraph_msgs.msg import Clock

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node("bag_player")
    status = 0
    total = 0
    lateness = Lateness()
    t0 = time.monotonic()
    try:
        for topic in played.values():
            topic.publisher = node.create_publisher(message_class(topic.msgtype), topic.topic,
                                                    to_rclpy_qos(topic.qos))
            _log(f"{topic.bag_topic} -> {topic.topic} [{topic.msgtype}] "
                 f"{topic.qos.reliability}/{topic.qos.durability}/depth {topic.qos.depth}")
        clock_pub = None
        if args.clock > 0:
            clock_pub = node.create_publisher(Clock, "/clock", 10)
        if args.delay > 0:
            stop.sleep(args.delay)
        if args.wait_for_subscribers > 0:
            awaited = {t.topic: t.publisher for t in played.values()}
            if clock_pub is not None:
                awaited["/clock"] = clock_pub
            if args.wait_topics is not None:
                names = {"/" + t.lstrip("/") for t in args.wait_topics}
                awaited = {n: p for n, p in awaited.items() if n in names}
                if not awaited:
                    _log(f"none of {sorted(names)} is published; not waiting for subscribers")
            _wait_for_subscribers(awaited, args.min_subscribers, args.wait_for_subscribers,
                                  stop)
        if args.go_on_stdin:
            _wait_for_go(sys.stdin, stop)
        clock_period = round(NS_PER_S / args.clock) if args.clock > 0 else 0
        selected = sorted(played)
        while not stop.is_set():
            try:
                count = play_iteration(plan, reader.messages(topics=selected), played,
                                       clock_pub, clock_period, stop, lateness)
            except (bag_io.BagError, PlaybackError) as exc:
                _log(f"error while reading the bag: {exc}")
                status = 1
                break
            total += count
            if count == 0 and not stop.is_set():
                _log(f"error: no message of the selected topics at or after the start "
                     f"offset of {options.start_offset_s:g} s")
                status = 1
                break
            if len(reader.problems) > reported:
                for problem in reader.problems[reported:]:
                    _log(f"error: {problem}")
                reported = len(reader.problems)
                status = 1
            if not options.loop:
                break
        for topic in played.values():
            if topic.qos.reliability == RELIABLE and not stop.is_set():
                topic.publisher.wait_for_all_acked(Duration(seconds=args.ack_timeout))
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        reader.close()
    counts = ", ".join(f"{t.topic}: {t.count}" for t in played.values())
    print(f"played {total} messages in {time.monotonic() - t0:.3f} s ({counts}); "
          f"{lateness.summary()}", flush=True)
    if reported and status == 0:
        status = 1  # problems found on opening: what was readable has been played
    return status


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="bag_player", description=__doc__.splitlines()[0])
    configure_parser(parser)
    args = parser.parse_args(argv)
    try:
        return run(args)
    except RosbagsMissing as exc:
        _log(f"error: {exc}")
        return 2


if __name__ == "__main__":
    sys.exit(main())
