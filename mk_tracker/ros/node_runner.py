"""What every mk_tracker node process does around its node: start, spin, stop, report.

* :func:`run_node` is the body of a node's ``main()``: a SIGTERM handler that lets the node
  stop cleanly, ``rclpy.init``, construction (a bad parameter or a missing message package
  -> message on stderr and exit status 1), spinning until Ctrl-C / SIGTERM /
  ``rclpy.shutdown`` (also when the shutdown lands while the executor builds its wait set,
  where rclpy raises ``RCLError``), then ``destroy_node`` and shutdown.
* :class:`ReportTimer` says when the next periodic report (every ``report_period``
  seconds of wall time) is due.
* :func:`log_shutdown` logs the node's statistics at shutdown, also after Ctrl-C when the
  context (and with it /rosout) is already gone.
* :func:`logged_warm_up` runs one of :mod:`mk_tracker.warm_up`'s functions while a node
  starts, with a log line before and after; a failure is a warning, never the node's end.
"""

from __future__ import annotations

import signal
import sys
import time
from typing import Any, Callable, Sequence

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy_impl
from rclpy.node import Node

from mk_tracker.numba_support import fallback_warning
from mk_tracker.parameters import ParameterError


class ReportTimer:
    """Wall-clock schedule of a node's periodic report (the algorithms never see it)."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock
        self.last_report = clock()

    def due(self, period: float) -> bool:
        """True (and the schedule restarts) when ``period`` seconds have passed since the
        last report."""
        now = self._clock()
        if now - self.last_report < period:
            return False
        self.last_report = now
        return True


def log_shutdown(node: Node, statistics: dict[str, Any]) -> None:
    """Log ``shutting down: {statistics}``: on /rosout while the context is up, else on
    stderr (after Ctrl-C the context is gone and /rosout cannot be published to)."""
    text = f"shutting down: {statistics}"
    if node.context.ok():
        node.get_logger().info(text)
    else:
        print(f"[{node.get_name()}] {text}", file=sys.stderr, flush=True)


def logged_warm_up(node: Node, what: str, warm_up: Callable[[], Any]) -> None:
    """Compile / load ``what``'s numba kernels now (``warm_up()``), not on the first frame."""
    logger = node.get_logger()
    logger.info(f"preparing the compiled kernels of the {what} (the first run on a machine "
                f"compiles them: tens of seconds; later runs load them from numba's cache)")
    try:
        seconds = warm_up().seconds
    except Exception as exc:  # a warm-up problem must not stop the node; frames will show it
        logger.warning(f"warm-up of the {what} failed ({type(exc).__name__}: {exc}); the "
                       f"first frames may be slow")
        return
    logger.info(f"{what} ready ({seconds:.1f} s)")


def run_node(node_class: Callable[[], Node], name: str,
             args: Sequence[str] | None = None) -> int:
    """Run one node until shutdown; returns the process exit status (0, or 1 when the node
    cannot be constructed)."""
    # rclpy shuts the context down on SIGTERM and then calls the previous handler, which by
    # default kills the process at once; a no-op Python handler lets the node stop cleanly
    # (worker joined, statistics logged), as on Ctrl-C.
    signal.signal(signal.SIGTERM, lambda signum, frame: None)
    rclpy.init(args=list(args) if args is not None else None)
    try:
        node = node_class()
    except (ParameterError, ImportError) as exc:
        print(f"{name}: {exc}", file=sys.stderr)
        rclpy.try_shutdown()
        return 1
    fallback = fallback_warning()       # one line when numba's compiled paths are off
    if fallback:
        node.get_logger().warning(fallback)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except _rclpy_impl.RCLError:
        # SIGTERM / Ctrl-C shut the context down between the executor's check of it and
        # the creation of its next wait set: rclpy then raises RCLError ("the given context
        # is not valid") instead of ExternalShutdownException.  After a shutdown that is
        # the same clean stop; while the context is still up it is a real error.
        if node.context.ok():
            raise
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0
