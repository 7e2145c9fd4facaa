"""Shared fixtures.  ``shared_data`` locates the real data folder ``<repo>/../shared/data``
(present in CI, absent in a user's fresh clone) and skips the test when it is missing."""

from __future__ import annotations

from pathlib import Path

import pytest

SHARED_DATA = Path(__file__).resolve().parent.parent.parent / "shared" / "data"


@pytest.fixture
def shared_data() -> Path:
    """Path of ``../shared/data``; skips the test when that folder is absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"real data folder {SHARED_DATA} is absent")
    return SHARED_DATA


# Tests that start real processes and talk to them over DDS.  On a loaded 2-core machine
# they occasionally lose a message or a discovery race (seen in about a third of full runs
# while other jobs shared the machine), so each is re-run up to twice on failure with
# pytest-rerunfailures; pytest's summary counts every rerun ("R"), so a flake stays
# visible.  A test that fails three times in a row still fails the run.
DDS_PROCESS_MODULES = {
    "test_nodes_detector", "test_nodes_tracker", "test_nodes_pipeline",
    "test_faults_nodes", "test_load_nodes", "test_parameters_runtime",
    "test_bag_player", "test_recorder", "test_launcher", "test_demo", "test_colcon_build",
    "test_nodes_tud_campus", "test_nodes_detection_wait",
}


# The fault tests SIGKILL node processes and start new ones in the same domain.  A tracker
# (restarted or not) sometimes received nothing from the detector for a whole attempt: the
# two processes had not discovered each other yet (1 s to over 2.5 s after the tracker
# started in 4 of 9 local runs of the kill/restart test on a loaded machine, found with the
# nodes' matched-event log lines); the tests now wait for the tracker's
# "/thermal/detections: 1 publisher matched" line (18/18 passes after).  The module keeps
# four reruns from before that diagnosis, when one CI run needed two.
EXTRA_RERUNS = {"test_faults_nodes": 4}


def pytest_collection_modifyitems(config, items):
    if not config.pluginmanager.hasplugin("rerunfailures"):
        return
    for item in items:
        module = item.module.__name__.rsplit(".", 1)[-1]
        if module in DDS_PROCESS_MODULES:
            item.add_marker(pytest.mark.flaky(reruns=EXTRA_RERUNS.get(module, 2),
                                              reruns_delay=2))


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


def pytest_runtest_logreport(report):
    if report.outcome == "rerun":
        crash = getattr(report.longrepr, "reprcrash", None)
        message = crash.message if crash is not None else str(report.longrepr)
        _RERUN_FAILURES.append((report.nodeid, message))


def pytest_terminal_summary(terminalreporter):
    if not _RERUN_FAILURES:
        return
    terminalreporter.section("why each rerun was needed (first lines of the failure)")
    for nodeid, message in _RERUN_FAILURES:
        lines = message.strip().splitlines() or [""]
        terminalreporter.write_line(f"{nodeid}: {' | '.join(lines[:4])[:600]}")
    # the reruns are a safety net, not a pass: say so where nobody can miss it
    terminalreporter.write_line(
        f"WARNING: {len(_RERUN_FAILURES)} rerun(s) were needed: the suite is meant to pass "
        "with none (issue #12); the failures above are flakes to diagnose", yellow=True,
        bold=True)
