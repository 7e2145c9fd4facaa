"""The sliding window of frames of Algorithm 2 (Schizas, Maroulas & Ren 2018, Sec. 5).

Every pass of the thermal detector reads the last ``F`` (tracking) or ``F_s`` (start-up,
reconfiguration) frames of the stream.  :class:`FrameWindow` keeps the newest ``capacity``
frames in one float32 ring buffer, so that a new frame is one copy into its slot and no
window is ever stacked: the compiled block loop
(:func:`mk_tracker.detection.block_support._support`) reads the ring in place through the
slots that :meth:`FrameWindow.order` lists, oldest first.  The stamps of the frames held
give the time a window spans (the (5.2) search windows grow with it).
"""

from __future__ import annotations

import collections

import numpy as np

__all__ = ["FrameWindow"]


class FrameWindow:
    """The newest ``capacity`` frames of a stream and their stamps (seconds)."""

    def __init__(self, capacity: int) -> None:
        if int(capacity) < 1:
            raise ValueError(f"a frame window holds at least one frame, not {capacity}")
        self.capacity = int(capacity)
        #: ``(capacity, rows, cols)`` float32, or None before the first frame
        self.ring: np.ndarray | None = None
        self._slots: collections.deque = collections.deque(maxlen=self.capacity)
        self._added = 0

    def clear(self) -> None:
        """Forget every frame."""
        self._slots.clear()
        self.ring = None
        self._added = 0

    def __len__(self) -> int:
        return len(self._slots)

    def add(self, frame: np.ndarray, stamp: float) -> None:
        """Store ``frame`` (converted to float32) as the newest, over the oldest when full; a
        frame of another size starts a new ring."""
        if self.ring is None or self.ring.shape[1:] != frame.shape:
            self.ring = np.empty((self.capacity,) + frame.shape, dtype=np.float32)
            self._slots.clear()
        slot = self._added % self.capacity
        self._added += 1
        self.ring[slot] = frame
        self._slots.append((slot, float(stamp)))

    def order(self, n_frames: int) -> np.ndarray:
        """Ring slots of the newest ``n_frames`` frames (all when fewer), oldest first."""
        n = min(int(n_frames), len(self._slots))
        return np.array([self._slots[i][0] for i in range(len(self._slots) - n,
                                                           len(self._slots))], dtype=np.int64)

    def frames(self, n_frames: int) -> list[np.ndarray]:
        """The newest ``n_frames`` frames (views into the ring), oldest first."""
        return [self.ring[i] for i in self.order(n_frames)]

    def newest(self) -> np.ndarray:
        """The newest frame (a view into the ring); IndexError when empty."""
        return self.ring[self._slots[-1][0]]

    def span(self, n_frames: int) -> float:
        """Seconds from the oldest to the newest of the newest ``n_frames`` frames (0 with
        one frame or none)."""
        if not self._slots:
            return 0.0
        n = max(1, min(int(n_frames), len(self._slots)))
        return self._slots[-1][1] - self._slots[-n][1]
