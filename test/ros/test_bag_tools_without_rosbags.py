"""bag_player and bag_recorder without the ``rosbags`` package (issue #14: a rosdep install
has no package for it): both modules still import, and each tool exits with status 2 and one
readable line naming the fix instead of a traceback.

``rosbags`` is hidden in a child interpreter by ``sys.modules["rosbags"] = None``, which makes
every ``import rosbags...`` fail as if it were not installed.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
HIDE = "import sys; sys.modules['rosbags'] = None; "


def run_hidden(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", HIDE + code], cwd=str(REPO),
                          capture_output=True, text=True, timeout=120)


def test_rosbags_is_really_hidden():
    result = run_hidden("import rosbags.typesys")
    assert result.returncode != 0 and "ModuleNotFoundError" in result.stderr


def test_nodes_and_bag_tools_import_without_rosbags():
    result = run_hidden("import mk_tracker.ros.bag_player, mk_tracker.ros.bag_recorder, "
                        "mk_tracker.ros.detector_node, mk_tracker.ros.tracker_node, "
                        "mk_tracker.ros.launcher; print('imported')")
    assert result.returncode == 0, result.stderr
    assert "imported" in result.stdout


@pytest.mark.parametrize("module, argv", [
    ("bag_player", ["some_bag"]),
    ("bag_recorder", ["-o", "some_out", "/tracks"]),
])
def test_each_tool_names_the_missing_package(tmp_path, module, argv):
    argv = [a if not a.startswith("some_") else str(tmp_path / a) for a in argv]
    result = run_hidden(f"from mk_tracker.ros.{module} import main; "
                        f"sys.exit(main({argv!r}))")
    assert result.returncode == 2, result.stdout + result.stderr
    assert "Traceback" not in result.stderr, result.stderr
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith(f"{module}: error: {module} needs the Python package rosbags")
    assert "pip install rosbags" in lines[0]
    assert not (tmp_path / "some_out").exists()
