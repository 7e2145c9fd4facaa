"""Frame time stamps as the libraries take them: seconds since any origin, a finite float.

The detectors and the tracker check every stamp the same way and raise their own input
error (a ``ValueError`` subclass) naming the bad value.  :class:`FrameRate` measures a
stream's frame rate from its stamps.
"""

from __future__ import annotations

import math
from collections import deque
from statistics import median
from typing import Any


def checked_stamp(stamp: Any, error: type[ValueError] = ValueError) -> float:
    """``stamp`` as a float of seconds; ``error`` when it is not a number or not finite."""
    try:
        value = float(stamp)
    except (TypeError, ValueError) as exc:
        raise error(f"stamp {stamp!r} is not a number") from exc
    if not math.isfinite(value):
        raise error(f"stamp {stamp!r} is not finite")
    return value


class FrameRate:
    """A stream's frame rate measured from its stamps, and frame counts that were chosen at
    a reference rate converted to the same durations.

    The rate is the inverse of the median of the last ``window`` positive stamp differences
    (:meth:`add`), at most ``max_rate`` (stamps closer than that are broken, not a faster
    camera).  Both detectors count their start-up and windows in frames chosen at 25 fps;
    they use this to keep those durations on slower (or faster) streams."""

    def __init__(self, window: int = 25, max_rate: float = 1000.0) -> None:
        self._intervals: deque[float] = deque(maxlen=max(int(window), 1))
        self.max_rate = float(max_rate)
        self._rate: float | None = None          # kept with the intervals: read per count

    def add(self, interval: float) -> None:
        """One stamp difference (s); zero or negative ones are not intervals."""
        if interval > 0.0:
            self._intervals.append(float(interval))
            self._rate = 1.0 / max(float(median(self._intervals)), 1.0 / self.max_rate)

    def clear(self) -> None:
        self._intervals.clear()
        self._rate = None

    @property
    def rate(self) -> float | None:
        """Frames per second, or None before two stamps."""
        return self._rate

    def frames(self, count: int, reference_fps: float, minimum: int = 1,
               slower_only: bool = False) -> int:
        """``count`` frames counted at ``reference_fps``, as frames at the measured rate
        (the same duration, rounded half up, at least ``minimum``); ``count`` itself when
        ``reference_fps`` is 0, before a rate is known, or, with ``slower_only``, when the
        stream is not slower than the reference."""
        rate = self.rate
        if reference_fps <= 0.0 or rate is None or count <= 0:
            return count
        scale = rate / reference_fps
        if slower_only and scale >= 1.0:
            return count
        return max(int(minimum), int(math.floor(count * scale + 0.5)))
