"""bag_recorder.drain: on a stop, the messages already in the subscriptions' queues are
written before the bag is closed (no DDS here: an executor stand-in hands queued messages
to the recorder's own callbacks, one ready callback per ``spin_once`` as rclpy does)."""

from __future__ import annotations

import os
import signal

import pytest

from mk_tracker.ros.bag_recorder import Recorder, drain


class Writer:
    def __init__(self) -> None:
        self.rows: list[tuple[str, int, bytes]] = []

    def write_raw(self, topic: str, stamp: int, data: bytes) -> None:
        self.rows.append((topic, stamp, data))


class Executor:
    """``ready``: what each ``spin_once`` finds, in order -- ``(topic, bytes, stamp)`` for a
    message, ``None`` for a ready callback that takes no message (a guard condition)."""

    def __init__(self, recorder: Recorder, ready: list, endless: bool = False) -> None:
        self.recorder, self.ready, self.endless, self.spins = recorder, list(ready), endless, 0

    def spin_once(self, timeout_sec: float) -> None:
        assert timeout_sec == 0.0           # a drain never blocks
        self.spins += 1
        if self.endless:
            self.recorder._callback("/a")(b"x", {"received_timestamp": self.spins})
        elif self.ready:
            item = self.ready.pop(0)
            if item is not None:
                topic, data, stamp = item
                self.recorder._callback(topic)(data, {"received_timestamp": stamp})


def recorder_with(topics: tuple[str, ...]) -> tuple[Recorder, Writer]:
    writer = Writer()
    recorder = Recorder(node=None, writer=writer, topics=topics, depth=10)
    recorder.counts = {t: 0 for t in topics}    # as discover() sets them when subscribing
    return recorder, writer


def test_drain_writes_every_queued_message_past_one_idle_callback():
    recorder, writer = recorder_with(("/a", "/b"))
    queued = [("/a", b"1", 10), None, ("/b", b"2", 11), ("/a", b"3", 12)]
    executor = Executor(recorder, queued)
    assert drain(executor, recorder) == 3
    assert writer.rows == [("/a", 10, b"1"), ("/b", 11, b"2"), ("/a", 12, b"3")]
    assert recorder.counts == {"/a": 2, "/b": 1}
    # 4 queued callbacks, then the two empty rounds that end it
    assert executor.spins == 6


def test_drain_of_empty_queues_writes_nothing_and_stops_after_two_rounds():
    recorder, writer = recorder_with(("/a",))
    executor = Executor(recorder, [])
    assert drain(executor, recorder) == 0
    assert writer.rows == [] and executor.spins == 2


def test_drain_is_bounded_when_messages_never_stop():
    recorder, writer = recorder_with(("/a",))
    executor = Executor(recorder, [], endless=True)
    assert drain(executor, recorder, max_rounds=50) == 50
    assert executor.spins == 50 and len(writer.rows) == 50


def test_run_drains_after_a_stop_before_it_closes_the_bag(tmp_path, monkeypatch):
    """run() itself: a SIGINT ends the loop and drain() gets the run's executor and
    recorder while the bag is still open (the DDS test cannot show it: the race it closes
    is rare on an idle machine)."""
    pytest.importorskip("rclpy")
    from nodes_harness import apply_env_to_test_process, unique_domain

    from mk_tracker.bags import bag_io
    from mk_tracker.ros import bag_recorder

    apply_env_to_test_process(monkeypatch, unique_domain())
    previous = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    monkeypatch.setattr(bag_recorder.Recorder, "discover",
                        lambda self: os.kill(os.getpid(), signal.SIGINT))
    closed: list[bool] = []
    original_close = bag_io.BagWriter.close
    monkeypatch.setattr(bag_io.BagWriter, "close",
                        lambda self: (closed.append(True), original_close(self))[1])
    calls = []
    monkeypatch.setattr(bag_recorder, "drain", lambda executor, recorder: calls.append(
        (type(executor).__name__, type(recorder).__name__, list(closed))))
    try:
        assert bag_recorder.main(["-o", str(tmp_path / "bag"), "/a"]) == 0
    finally:                                        # run() installed its own handlers
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    assert calls == [("SingleThreadedExecutor", "Recorder", [])]   # once, bag still open
    assert closed == [True]
