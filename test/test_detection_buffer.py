"""Which detection messages belong to which RGB frame (frame_processing.DetectionBuffer):
the rule tracker_node and the offline pipeline share."""

from __future__ import annotations

import pytest

from mk_tracker.messages.detection_messages import Detection
from mk_tracker.frame_processing import DETECTOR_SILENCE, DetectionBatch, DetectionBuffer


def batch(stamp: float, frame_id: str = "thermal_camera") -> DetectionBatch:
    return DetectionBatch(stamp, frame_id, [Detection((10.0, 10.0, 5.0, 8.0), 0.9)])


def stamps(batches) -> list[float]:
    return [b.stamp for b in batches]


def test_a_frame_takes_batches_up_to_its_stamp_and_later_ones_wait():
    buf = DetectionBuffer(capacity=10)
    for s in (1.0, 1.1, 1.2):
        buf.add(batch(s), now=0.0)
    assert stamps(buf.take(1.1)) == [1.0, 1.1]      # 1.2 is from the future of frame 1.1
    assert len(buf) == 1
    assert stamps(buf.take(1.15)) == []
    assert stamps(buf.take(1.2)) == [1.2]
    assert len(buf) == 0


def test_capacity_drops_the_oldest_and_counts_it():
    buf = DetectionBuffer(capacity=2)
    assert buf.add(batch(1.0), 0.0) is False
    assert buf.add(batch(2.0), 0.0) is False
    assert buf.add(batch(3.0), 0.0) is True
    assert buf.overflowed == 1
    assert stamps(buf.take(5.0)) == [2.0, 3.0]


def test_without_wait_a_frame_never_waits():
    buf = DetectionBuffer(capacity=5, wait=0.0)
    buf.add(batch(1.0), now=10.0)
    assert not buf.waiting(2.0, now=10.0)


def test_a_frame_waits_until_a_batch_at_or_after_its_stamp_has_arrived():
    buf = DetectionBuffer(capacity=5, wait=0.3)
    assert not buf.waiting(1.0, now=10.0)          # no detector seen yet: nothing to wait for
    buf.add(batch(0.9), now=10.0)
    assert buf.waiting(1.0, now=10.01)             # its own detections have not come yet
    buf.add(batch(1.0), now=10.02)
    assert not buf.waiting(1.0, now=10.02)
    assert stamps(buf.take(1.0)) == [0.9, 1.0]
    # the detector skipped frame 1.1: its next message (1.2) proves 1.1's will not come
    assert buf.waiting(1.1, now=10.05)
    buf.add(batch(1.2), now=10.1)
    assert not buf.waiting(1.1, now=10.1)
    assert stamps(buf.take(1.1)) == []              # and 1.2 stays for its own frame
    assert stamps(buf.take(1.2)) == [1.2]


def test_a_silent_detector_is_not_waited_for():
    buf = DetectionBuffer(capacity=5, wait=0.5)
    buf.add(batch(1.0), now=10.0)
    assert buf.waiting(2.0, now=10.0 + DETECTOR_SILENCE)
    assert not buf.waiting(2.0, now=10.0 + DETECTOR_SILENCE + 0.5 + 0.01)


def test_time_going_backwards_discards_the_old_time_line():
    buf = DetectionBuffer(capacity=10, wait=0.2)
    buf.add(batch(5.0), now=0.0)
    assert stamps(buf.take(5.0)) == [5.0]
    buf.add(batch(5.1), now=0.1)                    # the old loop's last answer
    buf.add(batch(0.0), now=0.2)                    # the bag restarted
    assert not buf.waiting(0.0, now=0.2)
    assert stamps(buf.take(0.0)) == [0.0]
    assert buf.discarded == 1 and len(buf) == 0
    # and the new time line pairs normally again
    assert buf.waiting(0.1, now=0.25)
    buf.add(batch(0.1), now=0.3)
    assert not buf.waiting(0.1, now=0.3)


@pytest.mark.parametrize("capacity, wait", [(0, 0.0), (3, -0.1), (3, float("nan")),
                                            (3, float("inf"))])
def test_bad_settings_are_refused(capacity, wait):
    with pytest.raises(ValueError):
        DetectionBuffer(capacity, wait)
