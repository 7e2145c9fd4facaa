"""What every mk_tracker node process does around its node: start, spin, stop, report.

* :func:`run_node` is the body of a node's ``main()``: a SIGINT / SIGTERM handler that lets
  the node stop cleanly, ``rclpy.init``, construction (a bad parameter or a missing message package
  -> message on stderr and exit status 1), spinning until Ctrl-C / SIGTERM /
  ``rclpy.shutdown`` (also when the shutdown lands while the executor builds its wait set,
  where rclpy raises ``RCLError``), then ``destroy_node`` and shutdown.
* :class:`ReportTimer` says when the next periodic report (every ``report_period``
  seconds of wall time) is due.
* :func:`log_shutdown` logs the node's statistics at shutdown, also after Ctrl-C when the
  context (and with it /rosout) is already gone.
* :func:`shutdown_once` shuts rclpy down, also when a signal raced it to it.
* :func:`logged_warm_up` runs one of :mod:`mk_tracker.warm_up`'s functions while a node
  starts, with a log line before and after; a failure is a warning, never the node's end.

A Ctrl-C or SIGTERM while the node is being constructed -- typically during the warm-up,
which compiles numba kernels for tens of seconds on a machine's first run -- ends the
process with status 0 and one line saying so, not a traceback.  While the node is
constructed, :func:`run_node`'s handler of both signals raises :class:`StartupInterrupted`
(again, 20 ms later, when a ctypes callback swallowed it: :class:`_StartGuard`; after the
construction the handler does nothing and rclpy's own handler stops the spin);
:func:`logged_warm_up` turns it into "warm-up of the ... interrupted after N s; stopping",
and :func:`run_node` says "interrupted while starting; stopping" when it came elsewhere.
Not ``KeyboardInterrupt``: when one passes through code that ``exec`` runs from a string
(numba's compiler does), CPython (3.11) ends a ``python -m`` process through SIGINT
(status -2) even if the exception was caught.  The context also goes away without an
exception (rclpy's handler shuts it down first, and alone when Python ignores SIGINT): the
warm-up then checks the context when it returns, and a later ``create_*`` call's
``RCLError`` on a shut-down context is the same clean stop.
"""

from __future__ import annotations

import os
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


class StartupInterrupted(BaseException):
    """SIGINT or SIGTERM while the node was being constructed (see the module docstring);
    ``logged`` once a line has said so.  A BaseException, so that no ``except Exception``
    on the way (numba's, the warm-up's) swallows it."""

    def __init__(self, logged: bool = False) -> None:
        super().__init__("interrupted while starting")
        self.logged = logged


def _log_info(node: Node, text: str) -> None:
    """Log ``text`` on /rosout while the context is up, else on stderr with the node's name
    (after Ctrl-C the context is gone and /rosout cannot be published to)."""
    if node.context.ok():
        node.get_logger().info(text)
    else:
        print(f"[{node.get_name()}] {text}", file=sys.stderr, flush=True)


def log_shutdown(node: Node, statistics: dict[str, Any]) -> None:
    """Log ``shutting down: {statistics}`` (on stderr once the context is gone)."""
    _log_info(node, f"shutting down: {statistics}")


def logged_warm_up(node: Node, what: str, warm_up: Callable[[], Any]) -> None:
    """Compile / load ``what``'s numba kernels now (``warm_up()``), not on the first frame."""
    logger = node.get_logger()
    logger.info(f"preparing the compiled kernels of the {what} (the first run on a machine "
                f"compiles them: tens of seconds; later runs load them from numba's cache)")
    start = time.monotonic()
    interrupted = False
    try:
        seconds = warm_up().seconds
    except Exception as exc:
        if not caused_by_interrupt(exc):
            # a warm-up problem must not stop the node; frames will show it
            logger.warning(f"warm-up of the {what} failed ({type(exc).__name__}: {exc}); "
                           f"the first frames may be slow")
            return
        interrupted = True
    except (StartupInterrupted, KeyboardInterrupt):
        interrupted = True
    if interrupted:           # Ctrl-C / SIGTERM: stop, quietly
        _log_info(node, f"warm-up of the {what} interrupted after "
                        f"{time.monotonic() - start:.1f} s; stopping")
        raise StartupInterrupted(logged=True) from None
    if not node.context.ok():     # shut down meanwhile (a SIGINT Python ignores)
        _log_info(node, f"shut down during the warm-up of the {what}; stopping")
        raise StartupInterrupted(logged=True)
    logger.info(f"{what} ready ({seconds:.1f} s)")


def caused_by_interrupt(exc: BaseException) -> bool:
    """Whether ``exc`` is a start-up interrupt or was raised because of one.

    numba's dispatcher runs Python code (unpickling a cached kernel, say) from C; an
    interrupt raised there comes back out of the dispatcher as ``SystemError: ... returned a
    result with an exception set`` whose cause is the :class:`StartupInterrupted` (seen once
    in a fresh-clone test run, test/ros/test_nodes_interrupt.py).  So the cause and context
    chain is searched, not only the exception's own type."""
    seen: set[int] = set()
    current: BaseException | None = exc
    while current is not None and id(current) not in seen:
        if isinstance(current, (StartupInterrupted, KeyboardInterrupt)):
            return True
        seen.add(id(current))
        current = current.__cause__ or current.__context__
    return False


class _StartGuard:
    """The signal handling of :func:`run_node` (see the module docstring).

    rclpy shuts the context down on SIGINT / SIGTERM and then calls the previous handler:
    by default a KeyboardInterrupt / the end of the process at once.  One handler for both
    (installed before rclpy.init, which chains to it; replacing it later would remove
    rclpy's) raises :class:`StartupInterrupted` while ``starting`` and otherwise lets rclpy
    stop the spin, so the node stops cleanly (worker joined, statistics logged).

    An exception raised in a signal handler surfaces in whatever Python code runs next; in
    a ctypes callback (llvmlite calls one while numba compiles) Python prints it as
    "Exception ignored" and goes on, which left a compile running for 15 s more in 1 of 10
    runs.  The guard's ``sys.unraisablehook`` therefore keeps such a swallowed interrupt quiet
    and raises it again 20 ms later (SIGALRM), until it lands in ordinary code.

    An interrupt that lands inside the constructor of an llvmlite object (numba's compiler)
    leaves that object half built; when it is collected, maybe only at the process's end,
    its ``__del__`` fails with ``AttributeError: ... '_as_parameter_'`` and Python printed a
    traceback after the clean "interrupted" line (seen once, in a fresh-clone test run).  Once a
    start was interrupted the guard's hook stays installed for the rest of the process and
    drops exactly that teardown error (:func:`half_built_llvm_object`); everything else still
    reaches the previous hook.
    """

    RETRY_S = 0.02

    def __init__(self) -> None:
        self.starting = True
        self.interrupted = False
        self._retry = hasattr(signal, "setitimer")
        self._signals = [signal.SIGINT, signal.SIGTERM] + (
            [signal.SIGALRM] if self._retry else [])
        self._previous = {sig: signal.getsignal(sig) for sig in self._signals}
        self._previous_hook = sys.unraisablehook
        for sig in self._signals:
            signal.signal(sig, self._on_signal)
        sys.unraisablehook = self._on_unraisable

    def _on_signal(self, signum: int, frame: Any) -> None:
        if self.starting:
            self.interrupted = True
            raise StartupInterrupted()

    def _on_unraisable(self, unraisable: Any) -> None:
        if isinstance(unraisable.exc_value, StartupInterrupted) and self.starting:
            if self._retry:
                signal.setitimer(signal.ITIMER_REAL, self.RETRY_S)
            return
        if self.interrupted and half_built_llvm_object(unraisable):
            return
        self._previous_hook(unraisable)

    def started(self) -> None:
        """The node is constructed (or gave up): signals no longer raise."""
        self.starting = False
        if self._retry:
            signal.setitimer(signal.ITIMER_REAL, 0.0)

    def restore(self) -> None:
        self.started()
        if not self.interrupted:       # else: the half-built objects are collected later
            sys.unraisablehook = self._previous_hook
        for sig, handler in self._previous.items():
            if handler is not None:
                signal.signal(sig, handler)


def shutdown_once() -> None:
    """``rclpy.try_shutdown()``, also when a signal shuts the context down meanwhile.

    ``try_shutdown`` checks that the context is up and then shuts it down; rclpy's signal
    handler (SIGINT / SIGTERM) shuts the context down from its own thread, and when it does
    so between the check and the shutdown, ``try_shutdown`` raises ``RCLError: failed to
    shutdown: rcl_shutdown already called`` (a fresh-clone CI run: a Ctrl-C during a node's
    start).  The context is then down, which is all that was asked for; an ``RCLError``
    while the context is still up is a real error."""
    try:
        rclpy.try_shutdown()
    except _rclpy_impl.RCLError:
        if rclpy.ok():
            raise


def half_built_llvm_object(unraisable: Any) -> bool:
    """Whether a ``sys.unraisablehook`` report is the teardown of an llvmlite object whose
    constructor an interrupt cut short: an ``AttributeError`` about ``_as_parameter_`` (the
    handle its constructor never set) raised in an ``llvmlite`` ``__del__``."""
    exc = getattr(unraisable, "exc_value", None)
    where = getattr(getattr(unraisable, "object", None), "__module__", None) or ""
    return (isinstance(exc, AttributeError) and "_as_parameter_" in str(exc)
            and where.startswith("llvmlite"))


def run_node(node_class: Callable[[], Node], name: str,
             args: Sequence[str] | None = None, *,
             end_process_after_interrupted_start: bool = False) -> int:
    """Run one node until shutdown; returns the process exit status (0, or 1 when the node
    cannot be constructed).  The process's signal handlers are restored at the end.

    With ``end_process_after_interrupted_start`` (the nodes' console scripts) a process
    whose start was interrupted ends here (:func:`end_process`) instead of returning."""
    guard = _StartGuard()
    try:
        status = _run(node_class, name, args, guard)
    finally:
        guard.restore()
    if end_process_after_interrupted_start and guard.interrupted:
        end_process(status)
    return status


def end_process(status: int) -> None:
    """End the process with ``status`` without Python's finalization (the streams are
    flushed first; rclpy is already shut down).

    A signal during numba's compile can cut an llvmlite / LLVM object's construction short.
    Collecting such objects at the interpreter's end printed a teardown traceback once
    (:func:`half_built_llvm_object`) and once crashed the process with SIGSEGV (exit status
    -11 instead of 0, test/ros/test_nodes_interrupt.py in a fresh-clone CI run): the native
    state under them is not consistent any more, so no finalizer of the process is safe to
    run.  Nothing is left to save at this point: the node never started."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):   # a closed or broken stream: nothing to flush into
            pass
    os._exit(status)


def _run(node_class: Callable[[], Node], name: str, args: Sequence[str] | None,
         guard: _StartGuard) -> int:
    rclpy.init(args=list(args) if args is not None else None)
    try:
        node = node_class()
    except (ParameterError, ImportError) as exc:
        print(f"{name}: {exc}", file=sys.stderr)
        shutdown_once()
        return 1
    except (Exception, StartupInterrupted, KeyboardInterrupt) as exc:
        # an RCLError while the context is up is a real error; after a shutdown (rclpy's
        # signal handler) the node's next create_* call fails with "context is invalid".
        # Any other error is the node's own, unless an interrupt caused it.
        after_shutdown = isinstance(exc, _rclpy_impl.RCLError) and not rclpy.ok()
        if not (after_shutdown or caused_by_interrupt(exc)):
            shutdown_once()
            raise
        if not getattr(exc, "logged", False):
            print(f"[{name}] interrupted while starting; stopping", file=sys.stderr,
                  flush=True)
        shutdown_once()
        return 0
    finally:
        guard.started()
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
        shutdown_once()
    return 0
