"""The sliding window of frames of Algorithm 2: the ring buffer keeps the newest frames in
order, with their stamps."""

from __future__ import annotations

import numpy as np
import pytest

from mk_tracker.detection.frame_window import FrameWindow


def frame(value: float, shape=(3, 4)) -> np.ndarray:
    return np.full(shape, value, dtype=np.uint8)


def test_the_newest_frames_come_back_oldest_first_after_the_ring_wraps():
    win = FrameWindow(3)
    assert len(win) == 0 and win.span(3) == 0.0
    for k in range(5):                               # 5 frames into 3 slots
        win.add(frame(10 * k), 0.1 * k)
    assert len(win) == 3
    assert [float(f[0, 0]) for f in win.frames(3)] == [20.0, 30.0, 40.0]
    assert [float(f[0, 0]) for f in win.frames(2)] == [30.0, 40.0]
    assert [float(f[0, 0]) for f in win.frames(10)] == [20.0, 30.0, 40.0]   # all it has
    assert float(win.newest()[0, 0]) == 40.0
    assert win.ring.dtype == np.float32 and win.ring.shape == (3, 3, 4)
    # order() lists the slots the compiled loop reads, in the same order as frames()
    assert np.array_equal(win.ring[win.order(3)], np.stack(win.frames(3)))
    assert win.span(3) == pytest.approx(0.2) and win.span(2) == pytest.approx(0.1)
    assert win.span(1) == 0.0


def test_clear_and_a_new_frame_size_start_over():
    win = FrameWindow(4)
    for k in range(3):
        win.add(frame(k), float(k))
    win.clear()
    assert len(win) == 0 and win.ring is None
    win.add(frame(7), 5.0)
    win.add(frame(9, shape=(2, 2)), 6.0)             # another size: a new ring
    assert len(win) == 1 and win.newest().shape == (2, 2)
    with pytest.raises(ValueError):
        FrameWindow(0)
