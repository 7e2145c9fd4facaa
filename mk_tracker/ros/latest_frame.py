"""Process only the newest frame: a one-slot mailbox drained by a worker thread.

A subscription callback calls :meth:`LatestFrameWorker.submit` and returns at once; the
worker thread processes whatever is newest when it becomes free.  A frame that is replaced
before the worker took it is *dropped* and counted, so a node that cannot keep up falls
behind by at most one frame instead of queueing without bound, and can say how many frames
it skipped.  Exceptions raised by the processing function are handed to ``on_error`` and
never end the thread: one bad message must not stop a node.

No rclpy in here, so it is testable without DDS.
"""

from __future__ import annotations

import threading
from typing import Any, Callable


class LatestFrameWorker:
    """Worker thread that runs ``process(item)`` on the newest submitted item."""

    def __init__(self, process: Callable[[Any], None],
                 on_error: Callable[[BaseException], None] | None = None,
                 name: str = "latest-frame-worker") -> None:
        self._process = process
        self._on_error = on_error
        self._cond = threading.Condition()
        self._item: Any = None
        self._has_item = False
        self._stopping = False
        self._busy = False
        self.submitted = 0
        self.processed = 0
        self.dropped = 0
        self.errors = 0
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> "LatestFrameWorker":
        self._thread.start()
        return self

    def submit(self, item: Any) -> bool:
        """Offer ``item``; returns True when it replaced an item that was never processed."""
        with self._cond:
            replaced = self._has_item
            self._item = item
            self._has_item = True
            self.submitted += 1
            if replaced:
                self.dropped += 1
            self._cond.notify()
        return replaced

    def counts(self) -> tuple[int, int, int]:
        """``(submitted, processed, dropped)`` read together, so that they add up:
        submitted = processed + dropped + (item in progress) + (item waiting)."""
        with self._cond:
            return self.submitted, self.processed, self.dropped

    def idle(self) -> bool:
        """True when nothing is waiting and nothing is being processed."""
        with self._cond:
            return not self._has_item and not self._busy

    def wait_idle(self, timeout: float) -> bool:
        """Block until :meth:`idle` (or ``timeout`` seconds); returns :meth:`idle`."""
        with self._cond:
            return self._cond.wait_for(lambda: not self._has_item and not self._busy,
                                       timeout=timeout)

    def stop(self, timeout: float = 5.0) -> None:
        """Ask the thread to finish (after the item in progress) and join it."""
        with self._cond:
            self._stopping = True
            self._cond.notify_all()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(timeout)

    def _run(self) -> None:
        while True:
            with self._cond:
                self._cond.wait_for(lambda: self._has_item or self._stopping)
                if self._stopping:
                    return
                item, self._item, self._has_item = self._item, None, False
                self._busy = True
            try:
                self._process(item)
            except BaseException as exc:  # noqa: BLE001 - the thread must survive anything
                self.errors += 1
                if self._on_error is not None:
                    try:
                        self._on_error(exc)
                    except Exception:  # noqa: BLE001
                        pass
            finally:
                with self._cond:
                    self.processed += 1
                    self._busy = False
                    self._cond.notify_all()
