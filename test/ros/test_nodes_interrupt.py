"""Ctrl-C (SIGINT) or SIGTERM while a node compiles its kernels at start-up ends it cleanly
(#14, item 7): exit status 0, one line saying so, no traceback.

Each node starts with an empty numba cache (``NUMBA_CACHE_DIR`` in the test's tmp_path), so
it has to compile its kernels: several seconds.  numba writes a function's cache files when
that function is compiled, so the first file in the empty cache shows that the node is
compiling and more is to come; the signal goes to the node's process group (as a
terminal's Ctrl-C does) at that moment.  The test checks the premise instead of assuming it:
the node must never have said it was ready, and must say where it was interrupted --
detector_node in its warm-up (it compiles on the first frames, which the warm-up pushes
through), tracker_node while starting (its library compiles when the node checks the
``tracker.*`` parameters by building a tracker, before the warm-up, which then only loads).
"""

from __future__ import annotations

import os
import signal
import subprocess
import time

import pytest

pytest.importorskip("rclpy")
pytest.importorskip("vision_msgs.msg", reason="vision_msgs is not built into this venv")

from nodes_harness import READY, NodeProcess, domain, ros_env  # noqa: E402,F401

NODES = [("mk_tracker.ros.detector_node",
          "warm-up of the sparse kernel covariance detector interrupted after"),
         ("mk_tracker.ros.tracker_node", "interrupted while starting; stopping")]

#: Bounds of waits for things that must happen: a node process starts in 2-5 s here and
#: writes its first compiled kernel 3-10 s after starting.
COMPILE_TIMEOUT_S = 120.0
EXIT_TIMEOUT_S = 30.0


def _compiling(node: NodeProcess, cache) -> bool:
    """True once the node wrote its first compiled kernel (or ended)."""
    return not node.alive() or (cache.is_dir() and any(
        p.is_file() for p in cache.rglob("*")))


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
@pytest.mark.parametrize("module,interrupted", NODES, ids=["detector_node", "tracker_node"])
def test_a_signal_while_the_kernels_compile_stops_the_node_cleanly(module, interrupted, sig,
                                                                   domain, tmp_path):
    cache = tmp_path / "numba_cache"
    env = ros_env(domain)
    env["NUMBA_CACHE_DIR"] = str(cache)          # empty: the node has to compile
    env.pop("MK_TRACKER_NO_NUMBA", None)
    node = NodeProcess(module, [], env, tmp_path / "node.log")
    try:
        deadline = time.monotonic() + COMPILE_TIMEOUT_S
        while not _compiling(node, cache) and time.monotonic() < deadline:
            time.sleep(0.02)
        assert node.alive() and _compiling(node, cache), node.output()
        os.killpg(node.proc.pid, sig)
        try:
            status = node.proc.wait(EXIT_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            pytest.fail(f"the node did not stop within {EXIT_TIMEOUT_S} s:\n{node.output()}")
        out = node.output()
    finally:
        node.stop()
    # the premise: the signal came while the node was starting, here:
    assert READY[module] not in out, out
    assert interrupted in out, out
    # and the outcome
    assert status == 0, out
    assert "Traceback" not in out, out
    lines = [line for line in out.splitlines() if "stopping" in line or "interrupted" in line]
    assert len(lines) == 1, out
    assert " ready (" not in out, out             # the warm-up never finished


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_after_the_start_stops_the_spin_with_the_statistics(sig, domain, tmp_path):
    module = "mk_tracker.ros.tracker_node"
    node = NodeProcess(module, ["-p", "warm_up:=false"], ros_env(domain),
                       tmp_path / "node.log")
    try:
        assert node.wait_for_output(READY[module], COMPILE_TIMEOUT_S), node.output()
        os.killpg(node.proc.pid, sig)
        try:
            status = node.proc.wait(EXIT_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            pytest.fail(f"the node did not stop within {EXIT_TIMEOUT_S} s:\n{node.output()}")
        out = node.output()
    finally:
        node.stop()
    assert status == 0, out
    assert "Traceback" not in out, out
    assert out.count("shutting down: {'frames': 0") == 1, out
    assert "interrupted" not in out, out
