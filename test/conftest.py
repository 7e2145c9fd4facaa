"""Shared fixtures.  ``shared_data`` locates the real data folder ``<repo>/../shared/data``
(present in CI, absent in a user's fresh clone) and skips the test when it is missing."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

SHARED_DATA = Path(__file__).resolve().parent.parent.parent / "shared" / "data"


@pytest.fixture
def shared_data() -> Path:
    """Path of ``../shared/data``; skips the test when that folder is absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"real data folder {SHARED_DATA} is absent")
    return SHARED_DATA


# Tests that start real processes and talk to them over DDS.  They used to fail now and
# then on a loaded 2-core machine (about a third of full runs while other jobs shared it)
# and were re-run up to twice, the fault tests up to four times.  The causes found (issue
# #12) were DDS discovery and arrival order, not speed: a test streamed once *its own*
# publisher had matched, before the node's reader had matched it (the first reliable
# sample then came seconds late, after a heartbeat), or before the tracker and detector
# processes had matched each other; after a restart the killed node's endpoint still
# counted as matched; and the tracker's copy of a frame's detections could arrive after the
# image.  The tests now wait for both ends of every connection (nodes_harness.Peer
# .wait_matched: the nodes log their readers' matches) and the lock-step fault tests run the
# tracker with detection_wait.  Measured with reruns disabled afterwards: see the commit
# that set RERUNS.  One rerun stays as a safety net against what has not been found yet;
# pytest's summary counts every rerun ("R") and pytest_terminal_summary below prints a
# WARNING line with the first failure's message, so a rerun never passes unnoticed.
DDS_PROCESS_MODULES = {
    "test_nodes_detector", "test_nodes_tracker", "test_nodes_pipeline",
    "test_faults_nodes", "test_load_nodes", "test_parameters_runtime",
    "test_bag_player", "test_recorder", "test_launcher", "test_demo", "test_colcon_build",
    "test_nodes_tud_campus", "test_nodes_detection_wait", "test_nodes_diagnostics",
    "test_nodes_namespaces", "test_nodes_tracks_detailed",
}
RERUNS = 1


def pytest_collection_modifyitems(config, items):
    if not config.pluginmanager.hasplugin("rerunfailures"):
        return
    for item in items:
        module = item.module.__name__.rsplit(".", 1)[-1]
        if module in DDS_PROCESS_MODULES:
            item.add_marker(pytest.mark.flaky(reruns=RERUNS, reruns_delay=2))


@pytest.fixture(scope="session", autouse=True)
def compiled_kernels_ready(request):
    """Before any test that starts node processes: compile the numba kernels once (or load
    them from numba's cache), so a node does not spend its start-up (or, with
    ``warm_up:=false``, its first frames) compiling -- tens of seconds in a fresh clone,
    longer than the tests wait for a node to be ready."""
    modules = {item.module.__name__.rsplit(".", 1)[-1] for item in request.session.items}
    if modules & DDS_PROCESS_MODULES:
        from mk_tracker.warm_up import warm_up_detector, warm_up_tracker
        warm_up_tracker()
        warm_up_detector()


# Why did a rerun test fail the first time?  pytest-rerunfailures keeps the report of every
# failed attempt (outcome "rerun") but -rR prints only the test's name; the message of each
# failed attempt is collected here and printed at the end of the run, so a flake in CI's
# output can be diagnosed instead of guessed at.
_RERUN_FAILURES: list[tuple[str, str]] = []


#: Every failed attempt's whole report (traceback, the failing line, captured output) is
#: appended here, because the summary line alone does not say which assertion of a long test
#: failed, and an assertion whose message is a process log hides its own line.
RERUN_LOG = Path(__file__).resolve().parents[1] / "out" / "test_reruns.log"


def pytest_runtest_logreport(report):
    if report.outcome == "rerun":
        crash = getattr(report.longrepr, "reprcrash", None)
        message = crash.message if crash is not None else str(report.longrepr)
        where = f"{Path(crash.path).name}:{crash.lineno}: " if crash is not None else ""
        _RERUN_FAILURES.append((report.nodeid, where + message))
        RERUN_LOG.parent.mkdir(parents=True, exist_ok=True)
        with RERUN_LOG.open("a") as log:
            log.write(f"==== {time.strftime('%Y-%m-%d %H:%M:%S')} {report.nodeid} "
                      f"failed ({report.when}); it was rerun\n{report.longreprtext}\n")
            for title, content in report.sections:
                log.write(f"---- {title}\n{content}\n")


def pytest_terminal_summary(terminalreporter):
    if not _RERUN_FAILURES:
        return
    terminalreporter.section("why each rerun was needed (first lines of the failure)")
    for nodeid, message in _RERUN_FAILURES:
        lines = message.strip().splitlines() or [""]
        terminalreporter.write_line(f"{nodeid}: {' | '.join(lines[:4])[:600]}")
    terminalreporter.write_line(f"the whole report of each failed attempt: {RERUN_LOG}")
    # the reruns are a safety net, not a pass: say so where nobody can miss it
    terminalreporter.write_line(
        f"WARNING: {len(_RERUN_FAILURES)} rerun(s) were needed: the suite is meant to pass "
        "with none (issue #12); the failures above are flakes to diagnose", yellow=True,
        bold=True)
