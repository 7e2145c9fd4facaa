"""mk_tracker.ros.node_runner: the start/spin/stop scaffolding both node processes share."""

import signal

import pytest

rclpy = pytest.importorskip("rclpy", reason="rclpy (ROS 2 Jazzy wheels) is not installed")
from rclpy.node import Node  # noqa: E402

from mk_tracker.parameters import ParameterError  # noqa: E402
from mk_tracker.ros.node_runner import ReportTimer, log_shutdown, run_node  # noqa: E402


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
    def broken():
        raise ParameterError("tracker.homography: singular")

    assert run_node(broken, "some_node", []) == 1
    assert "some_node: tracker.homography: singular" in capsys.readouterr().err
    assert not rclpy.ok()                 # the context was shut down again
    # the SIGTERM handler lets the node stop cleanly instead of killing the process
    handler = signal.getsignal(signal.SIGTERM)
    assert callable(handler) and handler is not signal.SIG_DFL


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
