"""mk_tracker.ros.node_runner: the start/spin/stop scaffolding both node processes share."""

import os
import signal
import time

import pytest

rclpy = pytest.importorskip("rclpy", reason="rclpy (ROS 2 Jazzy wheels) is not installed")
from rclpy.node import Node  # noqa: E402

from mk_tracker.parameters import ParameterError  # noqa: E402
from mk_tracker.ros.node_runner import (ReportTimer, StartupInterrupted,  # noqa: E402
                                        log_shutdown, logged_warm_up, run_node)
from mk_tracker.warm_up import WarmUp  # noqa: E402


@pytest.fixture
def keep_sigterm():
    previous = signal.getsignal(signal.SIGTERM)
    yield
    signal.signal(signal.SIGTERM, previous)


def test_report_timer_is_due_once_per_period():
    now = [100.0]
    timer = ReportTimer(clock=lambda: now[0])
    assert not timer.due(5.0)
    now[0] = 104.9
    assert not timer.due(5.0)
    now[0] = 105.0
    assert timer.due(5.0)
    assert not timer.due(5.0)           # the schedule restarted at 105
    now[0] = 109.0
    assert not timer.due(5.0)
    assert timer.due(4.0)


def test_construction_error_exits_1_with_the_message(keep_sigterm, capsys):
    seen = {}

    def broken():
        seen["handlers"] = [signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)]
        raise ParameterError("tracker.homography: singular")

    before = [signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)]
    assert run_node(broken, "some_node", []) == 1
    assert "some_node: tracker.homography: singular" in capsys.readouterr().err
    assert not rclpy.ok()                 # the context was shut down again
    # while the node ran, run_node's handler let it stop cleanly instead of the default
    # (SIGTERM: the end of the process at once); afterwards the process's own are back
    assert all(callable(h) and h not in (signal.SIG_DFL, signal.SIG_IGN)
               and h not in before for h in seen["handlers"])
    assert [signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)] == before


def test_node_is_spun_until_shutdown_then_destroyed_and_statistics_logged(keep_sigterm, capsys):
    seen = {}

    class Stopping(Node):
        def __init__(self):
            super().__init__("runner_test_node")
            self.ticks = 0
            self.create_timer(0.01, self._tick)

        def _tick(self):
            self.ticks += 1
            if self.ticks == 3:
                rclpy.shutdown()          # like SIGTERM: the context goes away

        def destroy_node(self):
            seen["ticks"] = self.ticks
            log_shutdown(self, {"frames": self.ticks})
            super().destroy_node()

    assert run_node(Stopping, "runner_test_node") == 0
    assert seen["ticks"] == 3
    # the context is gone, so the statistics go to stderr with the node's name
    assert "[runner_test_node] shutting down: {'frames': 3}" in capsys.readouterr().err
    assert not rclpy.ok()


def _raising_spin(monkeypatch, shut_down_first: bool):
    """rclpy.spin replaced by one that fails as rclpy's executor does when the context is
    shut down while it builds its wait set (seen in a fresh-clone run: a SIGTERM at the end
    of a demo made detector_node exit 1 with this error after its clean shutdown log)."""
    from rclpy.impl.implementation_singleton import rclpy_implementation as impl

    def spin(node):
        if shut_down_first:
            rclpy.shutdown()
        raise impl.RCLError("failed to initialize wait set: the given context is not valid")

    monkeypatch.setattr(rclpy, "spin", spin)


def test_context_invalid_error_after_shutdown_is_a_clean_stop(keep_sigterm, monkeypatch):
    destroyed = []

    class Plain(Node):
        def __init__(self):
            super().__init__("runner_race_node")

        def destroy_node(self):
            destroyed.append(True)
            super().destroy_node()

    _raising_spin(monkeypatch, shut_down_first=True)
    assert run_node(Plain, "runner_race_node") == 0
    assert destroyed == [True]


def test_context_invalid_error_while_running_is_not_hidden(keep_sigterm, monkeypatch):
    from rclpy.impl.implementation_singleton import rclpy_implementation as impl

    _raising_spin(monkeypatch, shut_down_first=False)
    with pytest.raises(impl.RCLError):
        run_node(lambda: Node("runner_error_node"), "runner_error_node")
    assert not rclpy.ok()                 # still shut down on the way out


class _StopsAtOnce(Node):
    def __init__(self):
        super().__init__("numba_warning_node")
        self.create_timer(0.01, rclpy.shutdown)


@pytest.mark.parametrize("disabled", [True, False])
def test_one_warning_line_when_the_numpy_fallback_is_used(keep_sigterm, monkeypatch, capfd,
                                                          disabled):
    """Issue #14: a node says once, at start-up, that numba's compiled paths are off (here
    switched off as the library allows, MK_TRACKER_NO_NUMBA) and that it runs the slower
    numpy fallback; with numba available (this venv has it) it says nothing."""
    pytest.importorskip("numba")
    if disabled:
        monkeypatch.setenv("MK_TRACKER_NO_NUMBA", "1")
    else:
        monkeypatch.delenv("MK_TRACKER_NO_NUMBA", raising=False)
    assert run_node(_StopsAtOnce, "numba_warning_node", []) == 0
    err = capfd.readouterr().err
    lines = [line for line in err.splitlines() if "numpy fallback" in line]
    if disabled:
        assert len(lines) == 1, err
        assert "WARN" in lines[0] and "MK_TRACKER_NO_NUMBA" in lines[0]
        assert "slower" in lines[0] and "python3-numba" in lines[0]
    else:
        assert lines == [], err


def _busy(seconds: float) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        sum(range(100))


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_while_the_node_is_constructed_ends_the_run_with_0(keep_sigterm, capsys, sig):
    reached = []

    class Slow(Node):
        def __init__(self):
            super().__init__("runner_slow_node")
            os.kill(os.getpid(), sig)
            _busy(5.0)                    # a start that would go on (a compile)
            reached.append("end of construction")

    assert run_node(Slow, "runner_slow_node") == 0
    # the construction was cut short: the 5 s busy loop did not run to its end (a marker,
    # not a wall-clock bound, which would assume how fast start-up and shutdown are)
    assert reached == []
    assert capsys.readouterr().err.count("[runner_slow_node] interrupted while starting; "
                                         "stopping") == 1
    assert not rclpy.ok()


def test_an_interrupted_warm_up_says_so_once_and_stops_the_start(keep_sigterm, capfd):
    calls = []

    def warm_up():
        calls.append("warm-up")
        os.kill(os.getpid(), signal.SIGINT)
        _busy(5.0)
        calls.append("finished")

    class Warming(Node):
        def __init__(self):
            super().__init__("runner_warming_node")
            logged_warm_up(self, "test kernels", warm_up)
            calls.append("constructed")

    assert run_node(Warming, "runner_warming_node") == 0
    assert calls == ["warm-up"]
    err = capfd.readouterr().err      # rclpy's logger writes to the file descriptor
    assert "warm-up of the test kernels interrupted after" in err
    assert "interrupted while starting" not in err     # one line, not two


def _wrapped_interrupt():
    """What numba's dispatcher makes of an interrupt raised in Python code it called from C:
    a SystemError whose cause is the interrupt."""
    try:
        raise StartupInterrupted()
    except StartupInterrupted as interrupt:
        raise SystemError("CPUDispatcher(<function f>) returned a result with an exception "
                          "set") from interrupt


def test_an_interrupt_wrapped_by_a_compiled_call_is_still_an_interrupt(keep_sigterm, capsys):
    class Wrapped(Node):
        def __init__(self):
            super().__init__("runner_wrapped_node")
            _wrapped_interrupt()

    assert run_node(Wrapped, "runner_wrapped_node") == 0
    err = capsys.readouterr().err
    assert err.count("[runner_wrapped_node] interrupted while starting; stopping") == 1
    assert "SystemError" not in err and "Traceback" not in err
    assert not rclpy.ok()


def test_an_error_not_caused_by_an_interrupt_still_surfaces(keep_sigterm):
    class Broken(Node):
        def __init__(self):
            super().__init__("runner_broken_node")
            raise SystemError("a real bug")

    with pytest.raises(SystemError, match="a real bug"):
        run_node(Broken, "runner_broken_node")
    assert not rclpy.ok()


def test_a_wrapped_interrupt_in_the_warm_up_is_reported_as_an_interrupt(keep_sigterm, capfd):
    class Warming(Node):
        def __init__(self):
            super().__init__("runner_wrapped_warm_up")
            logged_warm_up(self, "test kernels", _wrapped_interrupt)

    assert run_node(Warming, "runner_wrapped_warm_up") == 0
    err = capfd.readouterr().err
    assert "warm-up of the test kernels interrupted after" in err
    assert "failed" not in err and "SystemError" not in err
    assert "interrupted while starting" not in err     # one line, not two


def test_a_warm_up_that_ends_after_a_shutdown_stops_the_start(keep_sigterm):
    class Warming(Node):
        def __init__(self):
            super().__init__("runner_shutdown_node")
            # as a SIGINT Python ignores: rclpy shuts the context down, no exception
            logged_warm_up(self, "test kernels", lambda: rclpy.shutdown() or WarmUp(0.0, None))

    with pytest.raises(StartupInterrupted) as info:
        rclpy.init()
        try:
            Warming()
        finally:
            rclpy.try_shutdown()
    assert info.value.logged


def test_an_interrupt_swallowed_by_a_ctypes_callback_is_raised_again(keep_sigterm, capfd):
    """llvmlite calls Python through ctypes while numba compiles; an exception raised there
    (the signal handler's) is printed as "Exception ignored" and dropped.  run_node raises it
    again once the callback returned, quietly."""
    import ctypes

    steps = []

    def in_callback():
        steps.append("in the callback")
        os.kill(os.getpid(), signal.SIGTERM)
        _busy(0.2)                        # the handler raises in here: swallowed
        steps.append("callback went on")

    callback = ctypes.CFUNCTYPE(None)(in_callback)

    class Compiling(Node):
        def __init__(self):
            super().__init__("runner_ctypes_node")
            callback()
            _busy(5.0)                    # the rest of a compile
            steps.append("constructed")

    assert run_node(Compiling, "runner_ctypes_node") == 0
    # the callback was cut short and the construction did not go on to its end (markers,
    # not a wall-clock bound)
    assert steps == ["in the callback"]
    err = capfd.readouterr().err
    assert "Exception ignored" not in err and "Traceback" not in err, err
    assert err.count("interrupted while starting") == 1, err


def _llvm_like_half_built():
    """An object whose ``__del__`` fails as a half-built llvmlite ObjectRef's does (its
    constructor never set ``_as_parameter_``), defined in a module named like llvmlite's."""
    scope = {"__name__": "llvmlite.binding.ffi"}
    exec("class ObjectRef:\n"
         "    def __del__(self):\n"
         "        del self._as_parameter_\n", scope)
    return scope["ObjectRef"]()


@pytest.fixture
def keep_unraisablehook():
    import sys
    previous = sys.unraisablehook
    yield
    sys.unraisablehook = previous


def test_a_half_built_llvm_object_collected_after_an_interrupted_start_is_quiet(
        keep_sigterm, keep_unraisablehook, capfd):
    import gc
    import sys

    kept = []

    class Compiling(Node):
        def __init__(self):
            super().__init__("runner_half_built_node")
            kept.append(_llvm_like_half_built())     # cut short in its constructor
            os.kill(os.getpid(), signal.SIGTERM)
            _busy(5.0)

    assert run_node(Compiling, "runner_half_built_node") == 0
    # the guard's hook stays for the objects collected after the run ...
    guard = getattr(sys.unraisablehook, "__self__", None)
    assert type(guard).__name__ == "_StartGuard", sys.unraisablehook
    passed_on = []
    guard._previous_hook = passed_on.append            # what it would print
    kept.clear()
    gc.collect()
    # ... and drops their teardown error, which Python would print as a traceback
    assert passed_on == []
    err = capfd.readouterr().err
    assert err.count("interrupted while starting") == 1, err
    assert "Traceback" not in err and "Exception ignored" not in err, err


def test_the_guard_drops_only_that_teardown_error_and_only_after_an_interrupt():
    import types

    from mk_tracker.ros.node_runner import _StartGuard, half_built_llvm_object

    llvm_del = _llvm_like_half_built().__class__.__del__
    report = types.SimpleNamespace(
        exc_value=AttributeError("'PassBuilder' object has no attribute '_as_parameter_'"),
        object=llvm_del)
    assert half_built_llvm_object(report)
    other_attr = types.SimpleNamespace(exc_value=AttributeError("'X' has no attribute 'y'"),
                                       object=llvm_del)
    ours = types.SimpleNamespace(exc_value=report.exc_value,
                                 object=test_report_timer_is_due_once_per_period)
    assert not half_built_llvm_object(other_attr) and not half_built_llvm_object(ours)
    guard = _StartGuard()
    try:
        passed = []
        guard._previous_hook = passed.append
        guard.started()
        guard._on_unraisable(report)                  # no interrupt: reported
        guard.interrupted = True
        guard._on_unraisable(report)                  # after one: dropped
        guard._on_unraisable(other_attr)              # anything else: reported
        assert passed == [report, other_attr]
    finally:
        guard._previous_hook = __import__("sys").unraisablehook
        guard.interrupted = False
        guard.restore()


_EXIT_SCRIPT = """
import atexit, os, signal, sys, time
from rclpy.node import Node
from mk_tracker.parameters import ParameterError
from mk_tracker.ros.node_runner import run_node

atexit.register(lambda: print("finalized", flush=True))   # skipped by os._exit only
MODE, END = sys.argv[1], sys.argv[2] == "end"


class Starting(Node):
    def __init__(self):
        super().__init__("runner_exit_node")
        if MODE == "bad parameter":
            raise ParameterError("some.value: out of range")
        os.kill(os.getpid(), signal.SIGINT)
        end = time.monotonic() + 5.0         # a start that would go on (a compile)
        while time.monotonic() < end:
            sum(range(100))


status = run_node(Starting, "runner_exit_node", [], end_process_after_interrupted_start=END)
print("returned", status, flush=True)
sys.exit(status)
"""


@pytest.mark.parametrize("mode,end,status,lines", [
    ("interrupted", "end", 0, []),
    ("interrupted", "return", 0, ["returned 0", "finalized"]),
    ("bad parameter", "end", 1, ["returned 1", "finalized"]),
], ids=["interrupted-ends-at-once", "interrupted-returns", "not-interrupted-returns"])
def test_a_node_process_whose_start_was_interrupted_skips_the_finalizers(tmp_path, mode, end,
                                                                       status, lines):
    """The console scripts end a process whose start was interrupted without Python's
    finalization (a half-built llvmlite object's teardown once crashed it: SIGSEGV); the
    "interrupted" line is still written, and a start that was not interrupted returns
    and finalizes as usual."""
    import subprocess
    import sys

    script = tmp_path / "node.py"
    script.write_text(_EXIT_SCRIPT)
    done = subprocess.run([sys.executable, str(script), mode, end], capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == status, (done.stdout, done.stderr)
    assert done.stdout.split("\n")[:-1] == lines, (done.stdout, done.stderr)
    if mode == "interrupted":
        assert "[runner_exit_node] interrupted while starting; stopping" in done.stderr
    else:
        assert "some.value: out of range" in done.stderr


def test_shutdown_once_accepts_a_signal_that_shut_the_context_down_first(monkeypatch):
    """rclpy's signal thread can shut the context down between try_shutdown's check and its
    shutdown (RCLError "rcl_shutdown already called", a fresh-clone CI run): that is the
    stop that was asked for.  The same error while the context is still up is raised."""
    from rclpy.impl.implementation_singleton import rclpy_implementation as impl

    from mk_tracker.ros import node_runner

    def raced():                    # the signal thread wins the race, then rcl complains
        rclpy.shutdown()
        raise impl.RCLError("failed to shutdown: rcl_shutdown already called")

    rclpy.init()
    try:
        monkeypatch.setattr(node_runner.rclpy, "try_shutdown", raced)
        node_runner.shutdown_once()
        assert not rclpy.ok()
        rclpy.init()
        monkeypatch.setattr(node_runner.rclpy, "try_shutdown",
                            lambda: (_ for _ in ()).throw(impl.RCLError("a real failure")))
        with pytest.raises(impl.RCLError, match="a real failure"):
            node_runner.shutdown_once()
        assert rclpy.ok()
    finally:
        monkeypatch.undo()
        rclpy.try_shutdown()
