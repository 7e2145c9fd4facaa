"""The newest-frame worker: drops and counts overwritten frames, survives exceptions."""

import threading

from mk_tracker.ros.latest_frame import LatestFrameWorker


def test_slow_consumer_sees_the_newest_frame_and_counts_the_overwritten_ones():
    """No timing assumed: the test waits until the worker is inside ``process`` (an event it
    sets) before offering more items.  It used to sleep 50 ms and assume the worker thread
    had taken item 0 by then (``idle()`` turns False at ``submit``, not when the item is
    taken), which a loaded or single-core machine need not do."""
    processed = []
    gate = threading.Event()
    started = threading.Event()

    def process(item):
        started.set()
        gate.wait(30.0)
        processed.append(item)

    worker = LatestFrameWorker(process).start()
    try:
        worker.submit(0)                 # taken by the worker, which blocks on the gate
        assert started.wait(30.0), "the worker never took the first item"
        replaced = [worker.submit(i) for i in range(1, 6)]   # 1..4 are overwritten by 5
        assert replaced == [False, True, True, True, True]
        # item 0 in progress, item 5 waiting: submitted = processed + dropped + 2
        assert worker.counts() == (6, 0, 4)
        gate.set()
        assert worker.wait_idle(5.0)
        assert processed == [0, 5]
        assert worker.dropped == 4 and worker.processed == 2 and worker.submitted == 6
        assert worker.counts() == (6, 2, 4)
    finally:
        gate.set()
        worker.stop()


def test_exceptions_are_reported_and_the_worker_keeps_going():
    errors = []
    seen = []

    def process(item):
        if item == "bad":
            raise RuntimeError("boom")
        seen.append(item)

    worker = LatestFrameWorker(process, on_error=errors.append).start()
    try:
        for item in ("bad", "good"):
            worker.submit(item)
            assert worker.wait_idle(5.0)
        assert seen == ["good"]
        assert len(errors) == 1 and str(errors[0]) == "boom"
        assert worker.errors == 1
    finally:
        worker.stop()


def test_stop_ends_the_thread():
    worker = LatestFrameWorker(lambda item: None).start()
    worker.stop(timeout=5.0)
    assert not worker._thread.is_alive()
    assert worker.submit(1) is False      # accepted but never processed; no exception
