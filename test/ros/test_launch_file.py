"""launch/mk_tracker.launch.py executed against stand-ins of ``launch`` and ``launch_ros``.

The ROS 2 launch packages have no PyPI wheels, so ``ros2 launch`` cannot run here.  This
test executes the launch file's ``generate_launch_description()`` with minimal stand-in
modules that record every action's arguments, and then drives the file's own event handlers
with process-output events as launch would deliver them (bytes, a line possibly split
across reads, ROS logs on stderr).  It checks the start-up order of issue #14: the bag
player (and the recorder) are not started with the nodes but only from the handler, once
*both* nodes have logged their ready line, and only once; and the namespace argument
reaches both nodes.
"""

from __future__ import annotations

import runpy
import sys
import types
from pathlib import Path

import pytest

from mk_tracker.ros import launcher

LAUNCH_FILE = Path(__file__).resolve().parents[2] / "launch" / "mk_tracker.launch.py"

STUB_NAMES = {
    "launch": ["LaunchDescription"],
    "launch.actions": ["DeclareLaunchArgument", "ExecuteProcess", "GroupAction",
                       "RegisterEventHandler", "SetEnvironmentVariable"],
    "launch.conditions": ["IfCondition"],
    "launch.event_handlers": ["OnProcessIO"],
    "launch.substitutions": ["EnvironmentVariable", "LaunchConfiguration",
                             "PathJoinSubstitution", "PythonExpression"],
    "launch_ros.actions": ["Node"],
    "launch_ros.substitutions": ["FindPackageShare"],
}


class Recorded:
    """A stand-in action or substitution: keeps its arguments."""

    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs

    def __repr__(self):
        return f"{type(self).__name__}{self.args}"


class Event:
    """What launch hands an OnProcessIO handler: the output chunk as bytes."""

    def __init__(self, text: bytes):
        self.text = text


@pytest.fixture
def launch_module(monkeypatch):
    for module_name, names in STUB_NAMES.items():
        module = types.ModuleType(module_name)
        for name in names:
            setattr(module, name, type(name, (Recorded,), {}))
        monkeypatch.setitem(sys.modules, module_name, module)
    monkeypatch.setitem(sys.modules, "launch_ros", types.ModuleType("launch_ros"))
    return runpy.run_path(str(LAUNCH_FILE))


def _of(entities, kind: str):
    return [e for e in entities if type(e).__name__ == kind]


def _config_name(substitution) -> str:
    assert type(substitution).__name__ == "LaunchConfiguration", substitution
    return substitution.args[0]


def test_player_starts_only_after_both_nodes_are_ready(launch_module):
    description = launch_module["generate_launch_description"]()
    entities = description.args[0]
    nodes = _of(entities, "Node")
    handlers = _of(entities, "RegisterEventHandler")
    assert [n.kwargs["executable"] for n in nodes] == ["detector_node", "tracker_node"]
    # nothing but the nodes is started at once: player and recorder wait in the handlers
    assert not _of(entities, "ExecuteProcess")
    assert len(handlers) == 2
    ons = [h.args[0] for h in handlers]
    assert [o.kwargs["target_action"] for o in ons] == nodes
    # the Fast DDS variables are set before any process starts
    kinds = [type(e).__name__ for e in entities]
    assert kinds.index("GroupAction") < kinds.index("RegisterEventHandler") < kinds.index("Node")

    on_detector, on_tracker = ons
    det_err, trk_err = on_detector.kwargs["on_stderr"], on_tracker.kwargs["on_stderr"]
    det_out = on_detector.kwargs["on_stdout"]
    # output of a warming-up node starts nothing
    assert det_err(Event(b"[INFO] [detector_node]: sparse kernel covariance detector "
                         b"warmed up in 9.1 s\n")) is None
    # the detector is ready, the tracker not yet
    assert det_out(Event(b"[INFO] [1.0] [cam1.detector_node]: detecting people "
                         b"(kernel_covariance) in /cam1/thermal/image_raw -> "
                         b"/cam1/thermal/detections\n")) is None
    # the tracker's ready line, split over two reads
    assert trk_err(Event(b"[INFO] [2.0] [cam1.tracker_node]: tracking /cam1/image_raw wi"))\
        is None
    started = trk_err(Event(b"th detections from /cam1/thermal/detections -> /cam1/tracks; "
                            b"2 kernels per target\n"))
    assert started is not None
    commands = [[getattr(part, "args", (part,))[0] if not isinstance(part, str) else part
                 for part in action.kwargs["cmd"]] for action in started]
    assert [c[:3] for c in commands] == [["ros2", "bag", "record"], ["ros2", "bag", "play"]]
    play = started[1].kwargs["cmd"]
    assert "--delay" in play
    assert _config_name(play[play.index("--delay") + 1]) == "play_delay"
    # once only: more ready lines (a node logging it again) start nothing more
    assert trk_err(Event(b"tracking /x with detections from /y\n")) is None
    assert det_err(Event(b"detecting people (threshold) in /z\n")) is None


def test_the_tracker_alone_does_not_start_the_player(launch_module):
    entities = launch_module["generate_launch_description"]().args[0]
    on_tracker = _of(entities, "RegisterEventHandler")[1].args[0]
    for _ in range(3):
        assert on_tracker.kwargs["on_stderr"](
            Event(b"tracking /image_raw with detections from /thermal/detections\n")) is None


def test_ready_lines_and_namespace_argument(launch_module):
    assert launch_module["READY_LINES"] == launcher.READY_LINES
    entities = launch_module["generate_launch_description"]().args[0]
    declared = {a.args[0]: a.kwargs for a in _of(entities, "DeclareLaunchArgument")}
    assert declared["namespace"]["default_value"] == ""
    assert float(declared["play_delay"]["default_value"]) > 0
    defaults = {name: kwargs["default_value"] for name, kwargs in declared.items()}
    for node in _of(entities, "Node"):
        assert _config_name(node.kwargs["namespace"]) == "namespace"
        # relative remap targets by default: they resolve inside the namespace
        for source, target in node.kwargs["remappings"]:
            default = _render(target, defaults)
            assert not default.startswith("/") and default == source


def _render(substitution, values: dict) -> str:
    """What launch makes of a substitution with launch arguments ``values``: a
    LaunchConfiguration is its value, a PythonExpression the eval of its parts joined."""
    kind = type(substitution).__name__
    if isinstance(substitution, str):
        return substitution
    if kind == "LaunchConfiguration":
        return _render(values[substitution.args[0]], values)
    if kind == "PathJoinSubstitution":
        return "/".join(_render(p, values) for p in substitution.args[0])
    if kind == "FindPackageShare":
        return f"<share of {substitution.args[0]}>"
    assert kind == "PythonExpression", substitution
    return str(eval("".join(_render(p, values) for p in substitution.args[0])))


def _nodes_and_arguments(launch_module):
    """``(detector, tracker, declared)``: the two Node actions and the declared launch
    arguments (name -> DeclareLaunchArgument keywords)."""
    entities = launch_module["generate_launch_description"]().args[0]
    declared = {a.args[0]: a.kwargs for a in _of(entities, "DeclareLaunchArgument")}
    detector, tracker = _of(entities, "Node")
    return detector, tracker, declared


def _arguments(declared: dict, **changes) -> dict:
    """The launch arguments' values: the declared defaults, with ``changes``."""
    values = {name: kwargs["default_value"] for name, kwargs in declared.items()}
    values.update(changes)
    return values


def test_thermal_only_feeds_the_thermal_camera_to_the_tracker_alone(launch_module):
    detector, tracker, declared = _nodes_and_arguments(launch_module)
    assert declared["thermal_only"]["default_value"] == "false"

    def topics(node, **changes):
        values = _arguments(declared, **changes)
        return {source: _render(target, values) for source, target in node.kwargs["remappings"]}

    assert topics(tracker)["image_raw"] == "image_raw"
    assert topics(tracker, thermal_only="true")["image_raw"] == "thermal/image_raw"
    assert topics(tracker, thermal_only="True", thermal_image_topic="/flir/image_raw",
                  image_topic="/rgb")["image_raw"] == "/flir/image_raw"
    assert topics(tracker, thermal_only="false", image_topic="/rgb")["image_raw"] == "/rgb"
    # the detector keeps reading the thermal camera; the tracker's other topics are unchanged
    for mode in ("true", "false"):
        assert topics(detector, thermal_only=mode) == {"thermal/image_raw": "thermal/image_raw",
                                                       "thermal/detections":
                                                       "thermal/detections"}
        assert topics(tracker, thermal_only=mode)["thermal/detections"] == "thermal/detections"


def _parameter_files(declared, node, **changes):
    """The parameter files ``node`` loads, in order, with the launch arguments changed."""
    values = _arguments(declared, **changes)
    return [_render(entry, values) for entry in node.kwargs["parameters"]
            if not isinstance(entry, dict)]


def test_public_detections_loads_the_overlay_after_the_tracker_parameters(launch_module):
    detector, tracker, declared = _nodes_and_arguments(launch_module)
    assert declared["public_detections"]["default_value"] == "false"

    def files(node, **changes):
        return _parameter_files(declared, node, **changes)

    config = "<share of mk_tracker>/config"
    assert files(tracker) == [f"{config}/tracker.yaml"] * 3
    assert files(tracker, public_detections="True", tracker_params="mine.yaml") == [
        "mine.yaml", f"{config}/tracker_public_detections.yaml", "mine.yaml"]
    assert files(tracker, tracker_params="mine.yaml") == ["mine.yaml"] * 3
    # the overlay file is the one the offline pipeline uses, and it exists
    from mk_tracker.tools.pipeline_config import CONFIG_DIR, EXTERNAL_DETECTIONS_PARAMS_FILE
    assert (CONFIG_DIR / EXTERNAL_DETECTIONS_PARAMS_FILE).is_file()
    assert files(tracker, public_detections="true")[1].endswith(EXTERNAL_DETECTIONS_PARAMS_FILE)
    # the detector's parameters do not change
    assert files(detector, public_detections="true") == [f"{config}/detector.yaml"]


def test_background_detections_loads_its_overlay_after_the_tracker_parameters(launch_module):
    detector, tracker, declared = _nodes_and_arguments(launch_module)
    assert declared["background_detections"]["default_value"] == "false"

    def files(node, **changes):
        return _parameter_files(declared, node, **changes)

    config = "<share of mk_tracker>/config"
    assert files(tracker, background_detections="true", tracker_params="mine.yaml") == [
        "mine.yaml", "mine.yaml", f"{config}/tracker_background_detections.yaml"]
    # the overlay file is the one the offline pipeline uses, and it exists
    from mk_tracker.tools.pipeline_config import BACKGROUND_DETECTIONS_PARAMS_FILE, CONFIG_DIR
    assert (CONFIG_DIR / BACKGROUND_DETECTIONS_PARAMS_FILE).is_file()
    assert files(tracker, background_detections="True")[2].endswith(
        BACKGROUND_DETECTIONS_PARAMS_FILE)
    assert files(detector, background_detections="true") == [f"{config}/detector.yaml"]
