"""How well a node keeps up with its camera: rates, dropped frames, latency, and a verdict.

What a robot's operator (``rqt_runtime_monitor``, ``ros2 topic echo /diagnostics``, a
diagnostic aggregator) wants from a perception node is not an algorithm's state but whether
frames come in, whether they all come out, and how late.  A node

* samples its cumulative frame counters (:class:`FrameCounts`) once per diagnostics period
  with :meth:`HealthWindow.sample`;
* records the latency of each frame whose output it published with
  :meth:`HealthWindow.latency`: the time from the image's header stamp to the publish, read
  in the clock the node runs on (the ROS clock: with ``use_sim_time`` the simulated one);

and :meth:`HealthWindow.summary` gives the figures over the last ``window`` seconds of the
window's own clock (wall time, monotonic: rates are per real second even under simulated
time).  :func:`diagnose` turns a summary into what ``diagnostic_msgs/DiagnosticStatus``
carries -- a level, a message and key/value pairs -- by the rules of
:class:`DiagnosticsConfig`:

* ERROR when no image arrived for ``error_no_input_periods`` periods (also before the first);
* WARN when more than ``warn_drop_fraction`` of the images that arrived in the window were
  dropped (a newer one replaced them before the node was free) or skipped (bad input, or
  rejected by the algorithm), or when the median latency in the window is above
  ``warn_latency``;
* OK otherwise.

No rclpy here; :mod:`mk_tracker.ros.node_diagnostics` publishes it.  Thread-safe: a node's
worker thread records latencies while its executor samples.
"""

from __future__ import annotations

import statistics
import threading
import time
from collections import deque
from dataclasses import dataclass
from typing import Callable

from mk_tracker.parameters import parameter

#: ``diagnostic_msgs/DiagnosticStatus`` levels (the message stores them as one byte)
OK, WARN, ERROR = 0, 1, 2
LEVEL_NAMES = {OK: "OK", WARN: "WARN", ERROR: "ERROR"}


@dataclass(frozen=True)
class DiagnosticsConfig:
    """When a node publishes ``/diagnostics`` and where its OK / WARN / ERROR lines lie."""

    period: float = parameter(
        1.0, "Seconds between the node's /diagnostics messages (diagnostic_msgs/"
        "DiagnosticArray); 0 = do not publish", minimum=0.0, maximum=3600.0, read_only=True)
    window: float = parameter(
        5.0, "Seconds of history over which /diagnostics reports rates, dropped frames and "
        "latency", minimum=0.1, maximum=3600.0)
    warn_drop_fraction: float = parameter(
        0.1, "WARN when more than this fraction of the images that arrived in the window "
        "were dropped (a newer image arrived before the node was free) or skipped (bad "
        "input)", minimum=0.0, maximum=1.0)
    warn_latency: float = parameter(
        0.5, "WARN when the median latency in the window (image header stamp -> output "
        "published, in the node's clock: the ROS clock) is above this many seconds",
        minimum=0.0, maximum=3600.0)
    error_no_input_periods: int = parameter(
        5, "ERROR when no image arrived for this many diagnostics periods", minimum=1,
        maximum=1_000_000)


@dataclass(frozen=True)
class FrameCounts:
    """Cumulative counts of a node's images (or their differences over a window)."""

    received: int = 0    #: images that arrived (dropped ones included)
    processed: int = 0   #: images whose output was published
    dropped: int = 0     #: replaced by a newer image before the node took them
    skipped: int = 0     #: taken, but bad input or rejected by the algorithm

    def __sub__(self, other: "FrameCounts") -> "FrameCounts":
        return FrameCounts(self.received - other.received, self.processed - other.processed,
                           self.dropped - other.dropped, self.skipped - other.skipped)


@dataclass(frozen=True)
class HealthSummary:
    """The figures of one :meth:`HealthWindow.summary`."""

    span: float                    #: seconds the window's counts cover
    window: FrameCounts            #: counts within the window
    total: FrameCounts             #: counts since the node started
    input_rate: float              #: images that arrived per second in the window
    processed_rate: float          #: outputs published per second in the window
    latency_median: float | None   #: s, None when nothing was published in the window
    latency_max: float | None      #: s
    since_input: float             #: s since an image last arrived (since start: none yet)


class HealthWindow:
    """Rolling window of frame counts and latencies (see the module docstring).

    The oldest sample kept is the newest one at least ``window`` seconds old, so once the
    node has run that long the figures cover at least ``window`` seconds (at most one
    sampling period more).  ``clock`` gives seconds (monotonic wall time by default).
    """

    def __init__(self, window: float, clock: Callable[[], float] = time.monotonic) -> None:
        if not window > 0:
            raise ValueError(f"window must be > 0 s, got {window!r}")
        self.window = float(window)
        self._clock = clock
        now = clock()
        self._samples: deque[tuple[float, FrameCounts]] = deque([(now, FrameCounts())])
        self._latencies: deque[tuple[float, float]] = deque()
        self._last_input = now
        self._lock = threading.Lock()

    def sample(self, counts: FrameCounts) -> None:
        """Record the node's cumulative ``counts`` now (once per diagnostics period)."""
        now = self._clock()
        with self._lock:
            if counts.received > self._samples[-1][1].received:
                self._last_input = now       # an image came since the previous sample
            self._samples.append((now, counts))
            self._prune(now)

    def latency(self, seconds: float) -> None:
        """Record the latency of one published frame (image stamp -> publish, in s)."""
        now = self._clock()
        with self._lock:
            self._latencies.append((now, float(seconds)))

    def summary(self) -> HealthSummary:
        """The figures over the window (counts as of the last :meth:`sample`)."""
        now = self._clock()
        with self._lock:
            self._prune(now)
            (t0, first), (t1, last) = self._samples[0], self._samples[-1]
            # latencies of the frames counted in the window: recorded after its first sample
            values = [v for t, v in self._latencies if t > t0]
            since_input = now - self._last_input
        span = t1 - t0
        counts = last - first
        return HealthSummary(
            span=span, window=counts, total=last,
            input_rate=counts.received / span if span > 0 else 0.0,
            processed_rate=counts.processed / span if span > 0 else 0.0,
            latency_median=statistics.median(values) if values else None,
            latency_max=max(values) if values else None,
            since_input=since_input)

    def _prune(self, now: float) -> None:
        start = now - self.window
        while len(self._samples) >= 2 and self._samples[1][0] <= start:
            self._samples.popleft()
        t0 = self._samples[0][0]
        while self._latencies and self._latencies[0][0] <= t0:
            self._latencies.popleft()


def _ms(seconds: float | None) -> str:
    return "n/a" if seconds is None else f"{seconds * 1000.0:.1f}"


def diagnose(summary: HealthSummary, config: DiagnosticsConfig,
             extra: dict[str, object] | None = None) -> tuple[int, str, list[tuple[str, str]]]:
    """``(level, message, key/values)`` of a node's input by the rules of ``config`` (module
    docstring); ``extra`` (e.g. the node's own counters) is appended to the key/values."""
    w = summary.window
    silent_after = config.error_no_input_periods * config.period
    problems: list[str] = []
    level = OK
    if config.period > 0 and summary.since_input >= silent_after:
        level = ERROR
        problems.append(f"no image for {summary.since_input:.1f} s"
                        + (" (none since start)" if summary.total.received == 0 else ""))
    lost = w.dropped + w.skipped
    if w.received > 0 and lost / w.received > config.warn_drop_fraction:
        level = max(level, WARN)
        problems.append(f"{lost} of {w.received} images lost in {summary.span:.1f} s "
                        f"({w.dropped} dropped, {w.skipped} skipped)")
    if summary.latency_median is not None and summary.latency_median > config.warn_latency:
        level = max(level, WARN)
        problems.append(f"median latency {_ms(summary.latency_median)} ms above "
                        f"{_ms(config.warn_latency)} ms")
    message = "; ".join(problems) if problems else f"{summary.processed_rate:.1f} Hz processed"
    values = [
        ("input rate (Hz)", f"{summary.input_rate:.2f}"),
        ("processed rate (Hz)", f"{summary.processed_rate:.2f}"),
        ("window (s)", f"{summary.span:.2f}"),
        ("received in window", str(w.received)),
        ("processed in window", str(w.processed)),
        ("dropped in window", str(w.dropped)),
        ("skipped in window", str(w.skipped)),
        ("latency median (ms)", _ms(summary.latency_median)),
        ("latency max (ms)", _ms(summary.latency_max)),
        ("seconds since last image", f"{summary.since_input:.2f}"),
        ("frames received", str(summary.total.received)),
        ("frames processed", str(summary.total.processed)),
        ("frames dropped", str(summary.total.dropped)),
        ("frames skipped", str(summary.total.skipped)),
    ]
    values.extend((str(k), str(v)) for k, v in (extra or {}).items())
    return level, message, values
