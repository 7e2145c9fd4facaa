"""Throttle log messages per *kind* of message, not per line of code.

rclpy's ``throttle_duration_sec`` throttles per call site, so after an unsupported encoding
the next second's "data shorter than step*height" from the same ``except`` clause would be
swallowed.  :class:`ThrottledLog` keys the throttle on the message with its numbers masked
(``"image data has 1000 bytes, fewer than 921600"`` and ``"... 12 bytes, fewer than 9"``
are one kind), logs each kind at most once per ``period`` seconds and says how many similar
messages it suppressed in between.  Thread-safe, testable without ROS.

rclpy fixes a logger's severity per *call site* (the first frame outside rclpy's logging
module) and raises ``ValueError`` when one call site logs at two severities; since every
:class:`ThrottledLog` emits from the same line, use :func:`throttled_ros_log`, whose emitters
call the rclpy logger from one function per severity.
"""

from __future__ import annotations

import re
import threading
import time
from typing import Any, Callable

_NUMBER = re.compile(r"[-+]?\d+(\.\d+)?(e[-+]?\d+)?")


def message_kind(text: str) -> str:
    """``text`` with every number replaced by ``#``."""
    return _NUMBER.sub("#", text)


class ThrottledLog:
    """Calls ``emit(text)`` at most once per ``period`` seconds for each message kind."""

    def __init__(self, emit: Callable[[str], None], period: float = 1.0,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self._emit = emit
        self._period = float(period)
        self._clock = clock
        self._last: dict[str, float] = {}
        self._suppressed: dict[str, int] = {}
        self._lock = threading.Lock()

    def __call__(self, text: str) -> bool:
        """Log ``text`` unless its kind was logged less than ``period`` ago; True if logged."""
        kind = message_kind(text)
        now = self._clock()
        with self._lock:
            last = self._last.get(kind)
            if last is not None and now - last < self._period:
                self._suppressed[kind] = self._suppressed.get(kind, 0) + 1
                return False
            skipped = self._suppressed.pop(kind, 0)
            self._last[kind] = now
        if skipped:
            text = f"{text} ({skipped} similar message(s) suppressed)"
        self._emit(text)
        return True


def _emit_debug(logger: Any, text: str) -> None:
    logger.debug(text)


def _emit_info(logger: Any, text: str) -> None:
    logger.info(text)


def _emit_warning(logger: Any, text: str) -> None:
    logger.warning(text)


def _emit_error(logger: Any, text: str) -> None:
    logger.error(text)


_EMITTERS = {"debug": _emit_debug, "info": _emit_info, "warning": _emit_warning,
             "error": _emit_error}


def throttled_ros_log(logger: Any, severity: str, period: float = 1.0) -> ThrottledLog:
    """A :class:`ThrottledLog` writing to an rclpy ``logger`` at ``severity``.

    Each severity has its own emitting function, so the call site rclpy sees differs per
    severity (see the module docstring).
    """
    try:
        emitter = _EMITTERS[severity]
    except KeyError:
        raise ValueError(f"severity must be one of {sorted(_EMITTERS)}, got {severity!r}") \
            from None
    return ThrottledLog(lambda text: emitter(logger, text), period=period)
