"""Config dataclasses -> declared ROS parameters: descriptors, overrides, run-time checks."""

from __future__ import annotations

import math
from dataclasses import dataclass

import pytest
import yaml

rclpy = pytest.importorskip("rclpy")
from rclpy.context import Context  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from mk_tracker.parameters import ParameterError, parameter  # noqa: E402
from mk_tracker.ros.parameter_bridge import (ParameterBridge, config_yaml,  # noqa: E402
                                             descriptor_for)
from mk_tracker.parameters import parameter_specs  # noqa: E402


@dataclass(frozen=True)
class InnerConfig:
    sigma: float = parameter(1.5, "Noise std", minimum=0.0, maximum=10.0)
    steps: int = parameter(3, "Iterations", minimum=1)


@dataclass(frozen=True)
class ToyConfig:
    inner: InnerConfig = parameter(InnerConfig(), "Nested group")
    mode: str = parameter("fast", "Mode", choices=("fast", "slow"))
    buffer: int = parameter(4, "Buffer size", minimum=1, maximum=64, read_only=True)
    weights: tuple = parameter((1.0, 2.0, 3.0), "Weights", minimum=0.0)
    enabled: bool = parameter(True, "On/off")


@pytest.fixture
def context():
    ctx = Context()
    rclpy.init(context=ctx, args=[])
    yield ctx
    rclpy.shutdown(context=ctx)


def _node(context, overrides=None, name="toy"):
    return Node(name, context=context, parameter_overrides=overrides or [])


def _refused_at_start_up(context, overrides, name, match):
    """A node started with ``overrides`` cannot build ToyConfig: ParameterError ``match``."""
    node = _node(context, overrides, name=name)
    try:
        with pytest.raises(ParameterError, match=match):
            ParameterBridge(node).add_config("toy", ToyConfig())
    finally:
        node.destroy_node()


def test_descriptor_carries_description_range_and_read_only():
    specs = {s.name: s for s in parameter_specs(ToyConfig())}
    d = descriptor_for(specs["inner.sigma"], "toy.inner.sigma")
    assert d.description == "Noise std"
    assert d.floating_point_range[0].from_value == 0.0
    assert d.floating_point_range[0].to_value == 10.0
    d = descriptor_for(specs["inner.steps"])
    assert d.integer_range[0].from_value == 1 and d.integer_range[0].to_value == 2 ** 63 - 1
    assert descriptor_for(specs["buffer"]).read_only
    assert "'slow'" in descriptor_for(specs["mode"]).additional_constraints
    assert "[0.0, inf]" in descriptor_for(specs["weights"]).additional_constraints


def test_declares_dotted_names_with_defaults(context):
    node = _node(context)
    try:
        bridge = ParameterBridge(node)
        cfg = bridge.add_config("toy", ToyConfig())
        assert cfg == ToyConfig()
        assert node.get_parameter("toy.inner.sigma").value == 1.5
        assert node.get_parameter("toy.inner.steps").value == 3
        assert list(node.get_parameter("toy.weights").value) == [1.0, 2.0, 3.0]
        desc = node.describe_parameter("toy.inner.sigma")
        assert desc.floating_point_range[0].to_value == 10.0
        assert set(bridge.names()) == {"toy.inner.sigma", "toy.inner.steps", "toy.mode",
                                       "toy.buffer", "toy.weights", "toy.enabled"}
    finally:
        node.destroy_node()


def test_overrides_are_applied_and_validated(context):
    node = _node(context, [Parameter("toy.inner.sigma", value=2.5),
                           Parameter("toy.weights", value=[0.5, 0.5])])
    try:
        cfg = ParameterBridge(node).add_config("toy", ToyConfig())
        assert cfg.inner.sigma == 2.5 and cfg.weights == (0.5, 0.5)
    finally:
        node.destroy_node()
    _refused_at_start_up(context, [Parameter("toy.mode", value="medium")], "toy2", "medium")
    _refused_at_start_up(context, [Parameter("toy.inner.sigma", value=11.0)], "toy3", "sigma")


def test_whole_numbers_for_doubles_are_taken_as_doubles_at_start_up(context):
    """Issue #14: ``sigma: 3`` in a parameters file (an INTEGER override) must not stop the
    node; the stored value is the double, and the descriptor keeps its type and range."""
    node = _node(context, [Parameter("toy.inner.sigma", value=3),
                           Parameter("toy.weights", value=[1, 2])])
    try:
        cfg = ParameterBridge(node).add_config("toy", ToyConfig())
        assert cfg.inner.sigma == 3.0 and isinstance(cfg.inner.sigma, float)
        assert cfg.weights == (1.0, 2.0) and all(isinstance(v, float) for v in cfg.weights)
        stored = node.get_parameter("toy.inner.sigma")
        assert stored.type_ == Parameter.Type.DOUBLE and stored.value == 3.0
        weights = node.get_parameter("toy.weights")
        assert weights.type_ == Parameter.Type.DOUBLE_ARRAY and list(weights.value) == [1.0, 2.0]
        desc = node.describe_parameter("toy.inner.sigma")
        assert not desc.dynamic_typing and desc.type == Parameter.Type.DOUBLE.value
        assert desc.floating_point_range[0].to_value == 10.0
        assert desc.description == "Noise std"
    finally:
        node.destroy_node()
    # a whole number out of range is still refused, naming the parameter
    _refused_at_start_up(context, [Parameter("toy.inner.sigma", value=30)], "toy_range", "sigma")
    # a string for a double is refused with a readable reason
    _refused_at_start_up(context, [Parameter("toy.inner.sigma", value="three")], "toy_str",
                         "toy.inner.sigma: expected a number")
    # a double for an integer parameter is not rounded silently
    _refused_at_start_up(context, [Parameter("toy.inner.steps", value=2.5)], "toy_int",
                         "toy.inner.steps")


def test_whole_numbers_for_doubles_are_taken_as_doubles_at_run_time(context):
    node = _node(context)
    try:
        seen = []
        bridge = ParameterBridge(node)
        bridge.add_config("toy", ToyConfig(), on_change=seen.append)
        bridge.activate()
        result = node.set_parameters([Parameter("toy.inner.sigma", value=4)])[0]
        assert result.successful, result.reason
        stored = node.get_parameter("toy.inner.sigma")
        assert stored.type_ == Parameter.Type.DOUBLE and stored.value == 4.0
        assert isinstance(bridge.config("toy").inner.sigma, float)
        assert len(seen) == 1
        result = node.set_parameters_atomically([Parameter("toy.weights", value=[3, 4, 5])])
        assert result.successful, result.reason
        assert node.get_parameter("toy.weights").type_ == Parameter.Type.DOUBLE_ARRAY
        assert bridge.config("toy").weights == (3.0, 4.0, 5.0)
        # the range still applies to a whole number
        result = node.set_parameters([Parameter("toy.inner.sigma", value=11)])[0]
        assert not result.successful
        assert node.get_parameter("toy.inner.sigma").value == 4.0
        # integer parameters stay integers: a double is still refused
        result = node.set_parameters([Parameter("toy.inner.steps", value=2.0)])[0]
        assert not result.successful
        assert node.get_parameter("toy.inner.steps").value == 3
    finally:
        node.destroy_node()


def test_runtime_change_rejected_with_reason_keeps_old_value(context):
    node = _node(context)
    try:
        seen = []
        bridge = ParameterBridge(node)
        bridge.add_config("toy", ToyConfig(), on_change=seen.append)
        bridge.activate()
        # a choice not in the list: only our callback can reject it
        result = node.set_parameters([Parameter("toy.mode", value="turbo")])[0]
        assert not result.successful and "turbo" in result.reason
        assert node.get_parameter("toy.mode").value == "fast"
        # a negative array element: below the declared minimum
        result = node.set_parameters([Parameter("toy.weights", value=[1.0, -1.0])])[0]
        assert not result.successful and "minimum" in result.reason
        assert list(node.get_parameter("toy.weights").value) == [1.0, 2.0, 3.0]
        # NaN passes ROS's range check only if the range is open; ours rejects it
        result = node.set_parameters([Parameter("toy.inner.sigma", value=math.nan)])[0]
        assert not result.successful
        assert node.get_parameter("toy.inner.sigma").value == 1.5
        # read-only
        result = node.set_parameters([Parameter("toy.buffer", value=8)])[0]
        assert not result.successful and "read-only" in result.reason
        assert seen == [] and bridge.config("toy") == ToyConfig()
        # a good value is applied to the node, the config and the owner
        result = node.set_parameters([Parameter("toy.inner.sigma", value=4.0)])[0]
        assert result.successful
        assert node.get_parameter("toy.inner.sigma").value == 4.0
        assert bridge.config("toy").inner.sigma == 4.0
        assert len(seen) == 1 and seen[0].inner.sigma == 4.0
        # parameters the bridge does not own pass through
        assert node.set_parameters([Parameter("use_sim_time", value=True)])[0].successful
    finally:
        node.destroy_node()


def test_extra_check_rejects_at_start_and_at_run_time(context):
    def no_large_steps(cfg):
        if cfg.inner.steps > 10:
            raise ParameterError("inner.steps: more than 10 steps is too slow")

    node = _node(context)
    try:
        bridge = ParameterBridge(node)
        bridge.add_config("toy", ToyConfig(), extra_check=no_large_steps)
        bridge.activate()
        result = node.set_parameters([Parameter("toy.inner.steps", value=20)])[0]
        assert not result.successful and "too slow" in result.reason
        assert bridge.config("toy").inner.steps == 3
    finally:
        node.destroy_node()
    node = _node(context, [Parameter("toy.inner.steps", value=50)], name="toy4")
    try:
        with pytest.raises(ParameterError, match="too slow"):
            ParameterBridge(node).add_config("toy", ToyConfig(), extra_check=no_large_steps)
    finally:
        node.destroy_node()


def test_flat_prefix_and_two_groups(context):
    node = _node(context)
    try:
        bridge = ParameterBridge(node)
        bridge.add_config("", InnerConfig())
        bridge.add_config("toy", ToyConfig())
        bridge.activate()
        assert node.get_parameter("sigma").value == 1.5
        assert node.set_parameters([Parameter("sigma", value=3.0)])[0].successful
        assert bridge.config("").sigma == 3.0 and bridge.config("toy").inner.sigma == 1.5
        with pytest.raises(ValueError):
            bridge.add_config("toy", ToyConfig())
    finally:
        node.destroy_node()


def test_generated_yaml_loads_as_a_params_file(tmp_path):
    text = config_yaml("toy", {"toy": ToyConfig()})
    data = yaml.safe_load(text)
    assert list(data) == ["/**/toy"]           # the node in any namespace
    params = data["/**/toy"]["ros__parameters"]["toy"]
    assert params["inner"]["sigma"] == 1.5 and params["mode"] == "fast"
    assert params["weights"] == [1.0, 2.0, 3.0] and params["enabled"] is True
    assert "# Noise std [0.0, 10.0]" in text
    # change a value in the file and load it through rcl's own parser, into a node at the
    # root and into one in a namespace (the /** wildcard)
    path = tmp_path / "toy.yaml"
    path.write_text(text.replace("sigma: 1.5", "sigma: 7.25"))
    ctx = Context()
    rclpy.init(context=ctx, args=["--ros-args", "--params-file", str(path)])
    try:
        for namespace in ("", "/cam1", "/robot/cam2"):
            node = Node("toy", namespace=namespace, context=ctx)
            try:
                cfg = ParameterBridge(node).add_config("toy", ToyConfig())
                assert cfg.inner.sigma == 7.25 and cfg.weights == (1.0, 2.0, 3.0), namespace
            finally:
                node.destroy_node()
    finally:
        rclpy.shutdown(context=ctx)


@pytest.mark.parametrize("node_name, module_name, path", [
    ("tracker_node", "mk_tracker.ros.tracker_node", "config/tracker.yaml"),
    ("detector_node", "mk_tracker.ros.detector_node", "config/detector.yaml"),
])
def test_shipped_params_files_set_every_parameter_to_a_valid_value(node_name, module_name,
                                                                   path):
    """The shipped files name exactly the declared parameters, each with a value the node
    accepts (values may be tuned away from the defaults)."""
    import importlib
    from pathlib import Path

    from mk_tracker.parameters import validate_value

    module = importlib.import_module(module_name)     # an ImportError is a failure, not a skip
    shipped = yaml.safe_load((Path(__file__).resolve().parents[2] / path).read_text())
    params = shipped[f"/**/{node_name}"]["ros__parameters"]

    def flat(tree, prefix=""):
        for key, value in tree.items():
            if isinstance(value, dict):
                yield from flat(value, f"{prefix}{key}.")
            else:
                yield f"{prefix}{key}", value

    found = dict(flat(params))
    specs = {}
    for prefix, config in module.default_configs().items():
        for spec in parameter_specs(config):
            specs[f"{prefix}.{spec.name}" if prefix else spec.name] = spec
    hint = (f"{path} is out of date: regenerate it with "
            f"`.venv/bin/python -m mk_tracker.ros.parameter_bridge {node_name} > {path}`")
    assert set(found) == set(specs), (hint, set(found) ^ set(specs))
    for name, value in found.items():
        spec = specs[name]
        if spec.type is float and isinstance(value, int):
            pytest.fail(f"{path}: {name}: {value} must be written as a double ({hint})")
        validate_value(spec, tuple(value) if isinstance(value, list) else value)
