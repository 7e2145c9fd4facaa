"""Scheduling of rosbag2 playback: when each recorded message is due, on which topic, with
which QoS, and what ``/clock`` says -- without any ROS middleware.

The bag player (:mod:`mk_tracker.ros.bag_player`) is a thin loop around this module: it
reads messages with :mod:`mk_tracker.bags.bag_io`, asks :class:`PlaybackPlan` which ones to play
and when, sleeps until each is due and publishes the serialized bytes unchanged.  Everything
here is pure so that timing, rate, loop, start offset, topic selection, remapping and the
``/clock`` time can be unit tested without DDS.

Time model.  A bag is played from ``bag_start + start_offset`` on.  A message stamped
``t`` (bag receive time, ns) is due ``(t - play_from) / rate`` nanoseconds after the
iteration started; during that iteration ``/clock`` reads
``play_from + elapsed * rate``.  With ``loop`` the next iteration starts as soon as the
previous one has published its last message, as ``ros2 bag play --loop`` does.

QoS.  A player must offer a QoS that its subscribers can match.  The rule (see
:func:`resolve_qos`) is: an explicit per-topic override wins; otherwise the offered QoS
profiles stored in the bag metadata decide reliability and durability when every recorded
publisher agreed; otherwise (no stored profile, or disagreement) RELIABLE + VOLATILE with the
default depth.  Images are not special-cased: a RELIABLE publisher is matched by both
reliable and best-effort subscriptions, whereas a BEST_EFFORT publisher is not matched by a
reliable subscription, so "reliable unless the bag says otherwise" is the choice that never
silently plays to nobody.  ``--qos-override /camera/image=best_effort`` restores the
sensor-data behaviour where bandwidth matters more than completeness.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterable, Iterator, Mapping, Sequence

NS_PER_S = 1_000_000_000

RELIABLE = "reliable"
BEST_EFFORT = "best_effort"
VOLATILE = "volatile"
TRANSIENT_LOCAL = "transient_local"
RELIABILITIES = (RELIABLE, BEST_EFFORT)
DURABILITIES = (VOLATILE, TRANSIENT_LOCAL)
DEFAULT_DEPTH = 10


class PlaybackError(ValueError):
    """Invalid playback options, or a bag that cannot be played as asked."""


# ---------------------------------------------------------------------------------------
# Topic selection and remapping


def parse_remaps(items: Sequence[str]) -> dict[str, str]:
    """``["/a:=/b", ...]`` -> ``{"/a": "/b"}``; the ``from:=to`` syntax of ROS 2 remapping."""
    remaps: dict[str, str] = {}
    for item in items:
        source, sep, target = item.partition(":=")
        if not sep or not source.strip() or not target.strip():
            raise PlaybackError(f"remap {item!r} is not of the form FROM:=TO")
        source, target = source.strip(), target.strip()
        if source in remaps and remaps[source] != target:
            raise PlaybackError(f"topic {source!r} is remapped twice")
        remaps[source] = target
    return remaps


def _same_topic(a: str, b: str) -> bool:
    """Topic names compare without their leading slash (bags may store ``AAA`` or ``/AAA``)."""
    return a.lstrip("/") == b.lstrip("/")


def output_topics(bag_topics: Iterable[str], selected: Sequence[str] | None = None,
                  remaps: Mapping[str, str] | None = None) -> dict[str, str]:
    """Map every bag topic to play to the topic it is published on.

    ``selected`` (None = all topics) and the keys of ``remaps`` name bag topics, with or
    without a leading slash.  Output names are made absolute.  A selected or remapped topic
    that is not in the bag is an error (a typo would otherwise play nothing); two bag
    topics remapped onto one output topic are an error too.
    """
    bag_topics = list(dict.fromkeys(bag_topics))
    remaps = dict(remaps or {})
    for name in list(selected or []) + list(remaps):
        if not any(_same_topic(name, t) for t in bag_topics):
            raise PlaybackError(f"topic {name!r} is not in the bag (it has "
                                f"{', '.join(sorted(bag_topics)) or 'no topics'})")
    chosen = [t for t in bag_topics
              if selected is None or any(_same_topic(t, s) for s in selected)]
    result: dict[str, str] = {}
    for topic in chosen:
        target = topic
        for source, dest in remaps.items():
            if _same_topic(source, topic):
                target = dest
        result[topic] = "/" + target.lstrip("/")
    seen: dict[str, str] = {}
    for topic, out in result.items():
        if out in seen:
            raise PlaybackError(f"bag topics {seen[out]!r} and {topic!r} would both be "
                                f"published on {out!r}")
        seen[out] = topic
    return result


# ---------------------------------------------------------------------------------------
# QoS


@dataclass(frozen=True)
class TopicQos:
    """Middleware-neutral QoS of one played topic (converted to rclpy in the ROS layer)."""

    reliability: str = RELIABLE
    durability: str = VOLATILE
    depth: int = DEFAULT_DEPTH

    def __post_init__(self) -> None:
        if self.reliability not in RELIABILITIES:
            raise PlaybackError(f"reliability {self.reliability!r} is not one of "
                                f"{list(RELIABILITIES)}")
        if self.durability not in DURABILITIES:
            raise PlaybackError(f"durability {self.durability!r} is not one of "
                                f"{list(DURABILITIES)}")
        if not isinstance(self.depth, int) or isinstance(self.depth, bool) or self.depth < 1:
            raise PlaybackError(f"QoS depth must be a positive integer, got {self.depth!r}")


def parse_qos_override(item: str, default_depth: int = DEFAULT_DEPTH) -> tuple[str, TopicQos]:
    """``"/topic=best_effort,transient_local,5"`` -> ``("/topic", TopicQos(...))``.

    After ``=`` come comma-separated tokens in any order: a reliability, a durability,
    and/or a positive integer depth.  Unnamed policies take the defaults.
    """
    topic, sep, spec = item.partition("=")
    if not sep or not topic.strip() or not spec.strip():
        raise PlaybackError(f"QoS override {item!r} is not of the form TOPIC=POLICY[,POLICY]")
    reliability, durability, depth = RELIABLE, VOLATILE, default_depth
    for token in (t.strip().lower() for t in spec.split(",")):
        if token in RELIABILITIES:
            reliability = token
        elif token in DURABILITIES:
            durability = token
        elif token.isdigit():
            depth = int(token)
        else:
            raise PlaybackError(f"QoS override {item!r}: unknown policy {token!r} (use "
                                f"{', '.join(RELIABILITIES + DURABILITIES)} or a depth)")
    return topic.strip(), TopicQos(reliability, durability, depth)


def resolve_qos(offered: Sequence[tuple[str, str]], override: TopicQos | None = None,
                default_depth: int = DEFAULT_DEPTH) -> TopicQos:
    """QoS to publish one topic with.

    ``offered`` lists ``(reliability, durability)`` of every publisher recorded in the bag
    metadata (``offered_qos_profiles``), each already named with the constants of this
    module; it may be empty.  See the module docstring for the rule.
    """
    if override is not None:
        return override
    reliabilities = {r for r, _ in offered}
    durabilities = {d for _, d in offered}
    reliability = reliabilities.pop() if len(reliabilities) == 1 else RELIABLE
    durability = durabilities.pop() if len(durabilities) == 1 else VOLATILE
    if reliability not in RELIABILITIES:
        reliability = RELIABLE
    if durability not in DURABILITIES:
        durability = VOLATILE
    return TopicQos(reliability, durability, default_depth)


_RELIABILITY_NAMES = {1: RELIABLE, 2: BEST_EFFORT, "reliable": RELIABLE,
                      "best_effort": BEST_EFFORT}
_DURABILITY_NAMES = {1: TRANSIENT_LOCAL, 2: VOLATILE, "transient_local": TRANSIENT_LOCAL,
                     "volatile": VOLATILE}


def offered_qos_from_metadata(metadata: Mapping) -> dict[str, list[tuple[str, str]]]:
    """``{topic: [(reliability, durability), ...]}`` from a parsed ``metadata.yaml``.

    rosbag2 stores each topic's ``offered_qos_profiles`` as a YAML string (bag versions
    4-8) or a list (newer), with policies as enum numbers (1 = reliable / transient local,
    2 = best effort / volatile) or names.  Profiles whose policies are "system default" or
    "unknown" say nothing and are left out; unreadable entries are ignored (the QoS then
    falls back to the default of :func:`resolve_qos`).
    """
    import yaml

    info = metadata.get("rosbag2_bagfile_information", metadata) if metadata else {}
    result: dict[str, list[tuple[str, str]]] = {}
    for entry in (info or {}).get("topics_with_message_count") or []:
        try:
            topic = entry["topic_metadata"]
            profiles = topic.get("offered_qos_profiles") or []
            if isinstance(profiles, str):
                profiles = yaml.safe_load(profiles) or []
            policies = []
            for profile in profiles:
                rel = profile.get("reliability")
                dur = profile.get("durability")
                rel = _RELIABILITY_NAMES.get(rel.lower() if isinstance(rel, str) else rel)
                dur = _DURABILITY_NAMES.get(dur.lower() if isinstance(dur, str) else dur)
                if rel is not None and dur is not None:
                    policies.append((rel, dur))
            result.setdefault(str(topic["name"]), []).extend(policies)
        except (KeyError, TypeError, AttributeError, yaml.YAMLError):
            continue
    return result


# ---------------------------------------------------------------------------------------
# Timing


@dataclass(frozen=True)
class PlaybackOptions:
    """How to play a bag.  ``start_offset_s`` is measured from the bag's first message."""

    rate: float = 1.0
    loop: bool = False
    start_offset_s: float = 0.0
    topics: tuple[str, ...] | None = None
    remaps: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not isinstance(self.rate, (int, float)) or not self.rate > 0 \
                or self.rate == float("inf"):
            raise PlaybackError(f"rate must be a positive finite number, got {self.rate!r}")
        if not isinstance(self.start_offset_s, (int, float)) or not self.start_offset_s >= 0 \
                or self.start_offset_s == float("inf"):
            raise PlaybackError("start offset must be a finite number of seconds >= 0, got "
                                f"{self.start_offset_s!r}")


@dataclass(frozen=True)
class ScheduledMessage:
    """One message to publish ``due_ns`` after the start of its iteration."""

    due_ns: int
    topic: str            # output topic (remapped)
    bag_topic: str
    msgtype: str
    timestamp_ns: int     # bag time
    data: bytes


class PlaybackPlan:
    """Which messages of a bag to play, when, and what the simulated clock reads.

    ``bag_start_ns`` is the bag's first message time (metadata ``starting_time``).
    """

    def __init__(self, bag_start_ns: int, bag_topics: Iterable[str],
                 options: PlaybackOptions = PlaybackOptions()) -> None:
        self.options = options
        self.bag_start_ns = int(bag_start_ns)
        self.play_from_ns = self.bag_start_ns + round(options.start_offset_s * NS_PER_S)
        self.topic_map = output_topics(bag_topics, options.topics, options.remaps)

    def due_ns(self, timestamp_ns: int) -> int:
        """Wall-clock delay from the iteration start at which a message stamped
        ``timestamp_ns`` is due."""
        return round((timestamp_ns - self.play_from_ns) / self.options.rate)

    def clock_ns(self, elapsed_ns: int) -> int:
        """Simulated bag time (for ``/clock``) ``elapsed_ns`` of wall time into an
        iteration."""
        return self.play_from_ns + round(max(elapsed_ns, 0) * self.options.rate)

    def schedule(self, messages: Iterable[tuple[str, str, int, bytes]]
                 ) -> Iterator[ScheduledMessage]:
        """The messages of one iteration to publish, in bag order.

        ``messages`` yields ``(topic, msgtype, timestamp_ns, data)`` in time order (as
        :mod:`mk_tracker.bags.bag_io` does).  Messages of unselected topics and messages before
        the start offset are skipped; a message older than its predecessor is an error,
        because playing it would reorder the bag.
        """
        previous = None
        for topic, msgtype, timestamp_ns, data in messages:
            if previous is not None and timestamp_ns < previous:
                raise PlaybackError(f"messages are not in time order ({timestamp_ns} after "
                                    f"{previous} on {topic!r})")
            previous = timestamp_ns
            out = self.topic_map.get(topic)
            if out is None or timestamp_ns < self.play_from_ns:
                continue
            yield ScheduledMessage(self.due_ns(timestamp_ns), out, topic, msgtype,
                                   timestamp_ns, data)

