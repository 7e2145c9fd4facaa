"""ROS 2 parameters generated from mk_tracker's config dataclasses.

Naming scheme
-------------
Every config is declared under a *prefix*, and nested config fields keep their dotted path
(:func:`mk_tracker.parameters.parameter_specs`), so a ROS parameter name is
``<prefix>.<field>[.<field>...]``:

* ``detector.*``  -- the sparse kernel covariance detector (``ThermalDetectorConfig``),
* ``threshold.*`` -- the threshold baseline detector,
* ``tracker.*``   -- the multi-object tracker, e.g. ``tracker.kalman.sigma_u``;
* node parameters (QoS, debug image, detection wait ...) use the empty prefix and are
  flat or grouped by a nested dataclass, e.g. ``detection_wait``, ``image_qos.depth``.
  Topic names are not parameters: they are remapped (``-r image_raw:=/camera/image_raw``).

In a ``--params-file`` YAML file the dotted names can be written flat
(``tracker.kalman.sigma_u: 2.0``) or nested; :func:`config_yaml` writes them nested.

Each declared parameter carries a ``ParameterDescriptor`` with the description, a
``FloatingPointRange``/``IntegerRange`` built from the declared minimum/maximum (an open side
becomes +-inf or the int64 limit), the admissible choices in ``additional_constraints``, and
``read_only`` where the field is declared read-only (start-up only).

Whole numbers are accepted where a double is declared: ``sigma_u: 30`` in a parameters file,
``-p tracker.kalman.sigma_u:=30`` or a run-time ``set_parameters`` with the integer 30 all
store the double 30.0, and an integer list is stored as a double array (``homography: [1,
0, 0, 0, 1, 0, 0, 0, 1]``).  The descriptors stay statically typed with their ranges:
a start-up integer is declared once with ``dynamic_typing`` to read it, then the parameter is
declared again as the double it stands for (:meth:`ParameterBridge.add_config`); at run time a
pre-set callback (:func:`as_declared_type`) turns the integer into a double before rclpy
checks the type.  A YAML list mixing integers and doubles (``[1, 0.5]``) is refused by the
ROS parameters-file parser itself, before the node starts.

Run-time changes are checked by an on-set-parameters callback with
:func:`mk_tracker.parameters.updated` (plus an optional extra check per config, e.g. that a
homography is invertible).  A bad value is rejected with ``SetParametersResult(successful=
False, reason=...)`` and the node keeps its old value; an accepted change is handed to the
owner's ``on_change`` callback after ROS has stored it (post-set callback).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Iterable, Mapping

from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)
from rclpy.exceptions import InvalidParameterTypeException
from rclpy.node import Node
from rclpy.parameter import Parameter

from mk_tracker.parameters import (ParameterError, ParameterSpec, get_value, parameter_specs,
                                   updated)

INT64_MIN = -(2 ** 63)
INT64_MAX = 2 ** 63 - 1


def ros_name(prefix: str, spec_name: str) -> str:
    """ROS parameter name of config field ``spec_name`` declared under ``prefix``."""
    return f"{prefix}.{spec_name}" if prefix else spec_name


def to_ros_value(spec: ParameterSpec, value: Any) -> Any:
    """A config value as rclpy wants it: tuples become lists with one element type.

    A tuple default with any float in it is declared as a double array, so ``(1.0, 0, 0)``
    does not turn into an integer array by accident.
    """
    if spec.type is tuple:
        items = list(value)
        if any(isinstance(v, float) for v in items):
            return [float(v) for v in items]
        return items
    return value


def from_ros_value(spec: ParameterSpec, value: Any) -> Any:
    """A value received from ROS converted back to the config's type (arrays -> tuple)."""
    if spec.type is tuple and value is not None and not isinstance(value, (str, bytes)):
        try:
            return tuple(value)
        except TypeError:
            return value
    return value


def _is_whole(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def declared_as_double(spec: ParameterSpec) -> bool:
    """Whether ``spec`` is declared as a double or a double array."""
    default = to_ros_value(spec, spec.default)
    return spec.type is float or (isinstance(default, list) and bool(default)
                                  and all(isinstance(v, float) for v in default))


def as_double(spec: ParameterSpec, value: Any) -> Any:
    """``value`` with whole numbers turned into doubles where ``spec`` is declared as a double
    (array); any other value is returned unchanged for the usual checks to judge."""
    if not declared_as_double(spec):
        return value
    if spec.type is float:
        return float(value) if _is_whole(value) else value
    if not isinstance(value, (str, bytes)):
        try:
            items = list(value)
        except TypeError:
            return value
        if items and all(_is_whole(v) for v in items):
            return [float(v) for v in items]
    return value


def descriptor_for(spec: ParameterSpec, name: str | None = None) -> ParameterDescriptor:
    """The ``ParameterDescriptor`` for a spec: description, range, choices, read-only."""
    descriptor = ParameterDescriptor(name=name or spec.name, description=spec.description,
                                     read_only=bool(spec.read_only))
    if spec.choices is not None:
        descriptor.additional_constraints = "one of " + ", ".join(repr(c) for c in spec.choices)
    has_range = spec.minimum is not None or spec.maximum is not None
    if has_range and spec.type is float:
        descriptor.floating_point_range = [FloatingPointRange(
            from_value=float(spec.minimum) if spec.minimum is not None else -math.inf,
            to_value=float(spec.maximum) if spec.maximum is not None else math.inf,
            step=0.0)]
    elif has_range and spec.type is int:
        descriptor.integer_range = [IntegerRange(
            from_value=math.ceil(spec.minimum) if spec.minimum is not None else INT64_MIN,
            to_value=math.floor(spec.maximum) if spec.maximum is not None else INT64_MAX,
            step=0)]
    elif has_range and spec.type is tuple:
        low = spec.minimum if spec.minimum is not None else "-inf"
        high = spec.maximum if spec.maximum is not None else "inf"
        bound = f"every element in [{low}, {high}]"
        descriptor.additional_constraints = "; ".join(
            c for c in (descriptor.additional_constraints, bound) if c)
    return descriptor


ExtraCheck = Callable[[Any], None]
OnChange = Callable[[Any], None]


@dataclass
class _Group:
    prefix: str
    config: Any
    specs: dict[str, ParameterSpec]     # spec name -> spec
    on_change: OnChange | None
    extra_check: ExtraCheck | None


class ParameterBridge:
    """Declares configs as ROS parameters on a node and keeps them in sync.

    Usage::

        bridge = ParameterBridge(node)
        cfg = bridge.add_config("tracker", MultiObjectTrackerConfig(), on_change=apply)
        bridge.activate()          # from now on, run-time changes are validated
        bridge.config("tracker")   # the current config

    :meth:`add_config` applies overrides given with ``--ros-args -p`` or
    ``--params-file`` and raises :class:`ParameterError` if they are invalid.
    """

    def __init__(self, node: Node) -> None:
        self._node = node
        self._groups: dict[str, _Group] = {}
        self._owner: dict[str, tuple[str, str]] = {}   # ROS name -> (prefix, spec name)
        self._pending: dict[str, Any] = {}
        self._active = False

    # -- declaration -------------------------------------------------------------------
    def add_config(self, prefix: str, config: Any, *, on_change: OnChange | None = None,
                   extra_check: ExtraCheck | None = None) -> Any:
        """Declare every field of ``config`` under ``prefix``; return the effective config.

        ``extra_check(new_config)`` may raise :class:`ParameterError` for constraints a
        range cannot express; it runs on the start-up values and on every change.
        """
        if prefix in self._groups:
            raise ValueError(f"config prefix {prefix!r} is declared twice")
        specs = {s.name: s for s in parameter_specs(config)}
        changes: dict[str, Any] = {}
        for spec in specs.values():
            name = ros_name(prefix, spec.name)
            try:
                param = self._declare(spec, name)
            except ParameterError:
                raise
            except Exception as exc:  # rclpy raises several exception types here
                raise ParameterError(f"parameter {name}: {exc}") from exc
            self._owner[name] = (prefix, spec.name)
            value = from_ros_value(spec, param.value)
            if value != get_value(config, spec.name):
                changes[spec.name] = value
        try:
            effective = updated(config, changes) if changes else config
            if extra_check is not None:
                extra_check(effective)
        except ParameterError as exc:
            raise ParameterError(f"invalid start-up parameter under {prefix or 'node'}: "
                                 f"{exc}") from exc
        self._groups[prefix] = _Group(prefix, effective, specs, on_change, extra_check)
        return effective

    def _declare(self, spec: ParameterSpec, name: str) -> Parameter:
        """Declare one parameter, taking a start-up override that is a whole number (or a
        list of them) for a double (array) as that double."""
        default = to_ros_value(spec, spec.default)
        try:
            return self._node.declare_parameter(name, default, descriptor_for(spec, name))
        except InvalidParameterTypeException:
            if not declared_as_double(spec):
                raise
        # read the override with a dynamically typed declaration, then declare the
        # parameter again, statically typed, with the override as a double
        loose = descriptor_for(spec, name)
        loose.dynamic_typing = True
        loose.read_only = False           # so that it can be undeclared
        given = self._node.declare_parameter(name, default, loose).value
        self._node.undeclare_parameter(name)
        value = as_double(spec, given)
        if value is given:
            wanted = "a number" if spec.type is float else "a list of numbers"
            raise ParameterError(f"parameter {name}: expected {wanted}, got "
                                 f"{type(given).__name__} {given!r}")
        return self._node.declare_parameter(name, value, descriptor_for(spec, name),
                                            ignore_override=True)

    def activate(self) -> None:
        """Register the converting pre-set, the validating on-set and the applying post-set
        callbacks."""
        if self._active:
            return
        self._node.add_pre_set_parameters_callback(self._pre_set)
        self._node.add_on_set_parameters_callback(self._on_set)
        self._node.add_post_set_parameters_callback(self._post_set)
        self._active = True

    # -- access ------------------------------------------------------------------------
    def config(self, prefix: str) -> Any:
        """The current (last accepted) config declared under ``prefix``."""
        return self._groups[prefix].config

    def names(self) -> list[str]:
        """All ROS parameter names this bridge declared."""
        return list(self._owner)

    # -- callbacks ---------------------------------------------------------------------
    def check(self, parameters: Iterable[Parameter]) -> tuple[dict[str, Any], str | None]:
        """Validate a set of changes: ``(new configs by prefix, None)`` or ``({}, reason)``.

        Parameters this bridge did not declare (``use_sim_time``...) are ignored.
        """
        by_group: dict[str, dict[str, Any]] = {}
        for param in parameters:
            owner = self._owner.get(param.name)
            if owner is None:
                continue
            prefix, spec_name = owner
            spec = self._groups[prefix].specs[spec_name]
            by_group.setdefault(prefix, {})[spec_name] = from_ros_value(spec, param.value)
        result: dict[str, Any] = {}
        for prefix, changes in by_group.items():
            group = self._groups[prefix]
            try:
                candidate = updated(group.config, changes)
                if group.extra_check is not None:
                    group.extra_check(candidate)
            except ParameterError as exc:
                return {}, _with_prefix(prefix, str(exc))
            result[prefix] = candidate
        return result, None

    def _pre_set(self, parameters: list[Parameter]) -> list[Parameter]:
        """Whole numbers given for a declared double (array) become doubles (before rclpy
        compares the type with the descriptor)."""
        return [as_declared_type(self._spec_of(p.name), p) for p in parameters]

    def _spec_of(self, name: str) -> ParameterSpec | None:
        owner = self._owner.get(name)
        if owner is None:
            return None
        prefix, spec_name = owner
        return self._groups[prefix].specs[spec_name] if prefix in self._groups else None

    def _on_set(self, parameters: list[Parameter]) -> SetParametersResult:
        candidates, reason = self.check(parameters)
        if reason is not None:
            self._node.get_logger().warning(f"rejected parameter change: {reason}")
            return SetParametersResult(successful=False, reason=reason)
        self._pending = candidates
        return SetParametersResult(successful=True)

    def _post_set(self, parameters: list[Parameter]) -> None:
        pending, self._pending = self._pending, {}
        for prefix, config in pending.items():
            group = self._groups[prefix]
            group.config = config
            if group.on_change is not None:
                group.on_change(config)
        if pending:
            changed = ", ".join(f"{p.name}={p.value!r}" for p in parameters)
            self._node.get_logger().info(f"parameters changed: {changed}")


def as_declared_type(spec: ParameterSpec | None, param: Parameter) -> Parameter:
    """``param`` as a double (array) when it holds whole numbers for a double (array) spec;
    otherwise ``param`` itself (None: a parameter the bridge does not own)."""
    if spec is None or param.type_ not in (Parameter.Type.INTEGER,
                                           Parameter.Type.INTEGER_ARRAY):
        return param
    value = as_double(spec, param.value)
    if value is param.value:
        return param
    kind = Parameter.Type.DOUBLE if spec.type is float else Parameter.Type.DOUBLE_ARRAY
    return Parameter(param.name, kind, value)


def _with_prefix(prefix: str, message: str) -> str:
    return f"{prefix}.{message}" if prefix and not message.startswith("unknown") else message


def config_yaml(node_name: str, configs: Mapping[str, Any]) -> str:
    """A ``--params-file`` YAML text with every parameter of ``configs`` at its default.

    ``configs`` maps prefix -> config instance.  Each parameter is preceded by its
    description and range as a comment, so the shipped config/*.yaml files document
    themselves.  The section is keyed ``/**/<node_name>``: it applies to the node in any
    namespace (several camera pairs side by side), not only at the root.
    """
    lines = [f"/**/{node_name}:", "  ros__parameters:"]
    tree: dict = {}
    for prefix, config in configs.items():
        for spec in parameter_specs(config):
            parts = ros_name(prefix, spec.name).split(".")
            node = tree
            for part in parts[:-1]:
                node = node.setdefault(part, {})
            node[parts[-1]] = spec

    def emit(node: dict, indent: int) -> None:
        pad = " " * indent
        for key, item in node.items():
            if isinstance(item, dict):
                lines.append(f"{pad}{key}:")
                emit(item, indent + 2)
                continue
            lines.append(f"{pad}# {_comment(item)}")
            lines.append(f"{pad}{key}: {_yaml_scalar(to_ros_value(item, item.default))}")

    emit(tree, 4)
    return "\n".join(lines) + "\n"


def _comment(spec: ParameterSpec) -> str:
    parts = [spec.description.replace("\n", " ")]
    if spec.minimum is not None or spec.maximum is not None:
        low = spec.minimum if spec.minimum is not None else "-inf"
        high = spec.maximum if spec.maximum is not None else "inf"
        parts.append(f"[{low}, {high}]")
    if spec.choices is not None:
        parts.append("one of " + ", ".join(str(c) for c in spec.choices))
    if spec.read_only:
        parts.append("(read-only: start-up only)")
    return " ".join(parts)


def _yaml_scalar(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        if not math.isfinite(value):
            raise TypeError(f"cannot write the non-finite default {value!r} to a params file")
        text = repr(value)
        mantissa, _, exponent = text.partition("e")
        if "." not in mantissa:          # YAML 1.1 (PyYAML) needs the dot: 1.0e-06
            mantissa += ".0"
        return f"{mantissa}e{exponent}" if exponent else mantissa
    if isinstance(value, int):
        return str(value)
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, list):
        return "[" + ", ".join(_yaml_scalar(v) for v in value) + "]"
    raise TypeError(f"cannot write {value!r} as a ROS parameter")


NODES = {"tracker_node": "mk_tracker.ros.tracker_node",
         "detector_node": "mk_tracker.ros.detector_node"}


def main(argv: list[str] | None = None) -> int:
    """``python -m mk_tracker.ros.parameter_bridge NODE``: print NODE's default params file.

    The shipped config/tracker.yaml and config/detector.yaml are this output.
    """
    import argparse
    import importlib

    parser = argparse.ArgumentParser(description=main.__doc__.splitlines()[0])
    parser.add_argument("node", choices=sorted(NODES))
    args = parser.parse_args(argv)
    module = importlib.import_module(NODES[args.node])
    print(config_yaml(args.node, module.default_configs()), end="")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
