"""Declared, validated algorithm parameters.

Every algorithm constant in mk_tracker lives in a frozen dataclass ("a config") whose fields
are declared with :func:`parameter`: a default, a description, and a range or a set of
choices.  The same declaration serves three users:

* the libraries, which validate a config once with :func:`validate_config`;
* the ROS 2 nodes, which turn each field into a declared ROS parameter with a
  ``ParameterDescriptor`` (description, range) via :func:`parameter_specs`, and validate
  run-time changes with :func:`validate_value` before applying them with :func:`updated`;
* the offline tools, which read the same YAML parameter files.

Nested configs are allowed: a field whose default is itself a config dataclass is flattened
with dotted names (``multi_kernel.num_kernels``), as ROS 2 parameter files do.

Example::

    @dataclass(frozen=True)
    class KalmanConfig:
        sigma_u: float = parameter(1.0, "Process noise std (2.3), px/s^1.5", minimum=0.0)
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, Iterable, Mapping, Sequence


class ParameterError(ValueError):
    """A parameter value is out of range, of the wrong type, or unknown."""


@dataclass(frozen=True)
class ParameterSpec:
    """Everything a user needs to know about one parameter."""

    name: str
    default: Any
    type: type
    description: str
    minimum: float | None = None
    maximum: float | None = None
    choices: tuple | None = None
    read_only: bool = False


def parameter(default: Any, description: str, *, minimum: float | None = None,
              maximum: float | None = None, choices: Sequence | None = None,
              read_only: bool = False) -> Any:
    """Declare a config field with its documentation and admissible range.

    ``minimum``/``maximum`` are inclusive.  ``read_only`` marks parameters that can only be
    set at start-up (for example a buffer size).  Lists and tuples are stored as tuples.
    """
    meta = {"description": description, "minimum": minimum, "maximum": maximum,
            "choices": tuple(choices) if choices is not None else None,
            "read_only": read_only}
    if isinstance(default, list):
        default = tuple(default)
    if dataclasses.is_dataclass(default):
        return field(default_factory=lambda d=default: d, metadata=meta)
    return field(default=default, metadata=meta)


def _value_type(value: Any) -> type:
    if isinstance(value, bool):
        return bool
    if isinstance(value, int):
        return int
    if isinstance(value, float):
        return float
    if isinstance(value, str):
        return str
    if isinstance(value, tuple):
        return tuple
    return type(value)


def parameter_specs(config: Any, prefix: str = "") -> list[ParameterSpec]:
    """Flattened specs of a config class or instance (defaults taken from the instance)."""
    specs: list[ParameterSpec] = []
    instance = config if not isinstance(config, type) else config()
    for f in dataclasses.fields(instance):
        value = getattr(instance, f.name)
        name = f"{prefix}{f.name}"
        if dataclasses.is_dataclass(value):
            specs.extend(parameter_specs(value, prefix=name + "."))
            continue
        meta = f.metadata
        if "description" not in meta:
            raise TypeError(f"config field {name} is not declared with parameter()")
        specs.append(ParameterSpec(name=name, default=value, type=_value_type(value),
                                   description=meta["description"], minimum=meta["minimum"],
                                   maximum=meta["maximum"], choices=meta["choices"],
                                   read_only=meta["read_only"]))
    return specs


def validate_value(spec: ParameterSpec, value: Any) -> Any:
    """Return ``value`` coerced to the spec's type, or raise :class:`ParameterError`.

    Integers are accepted for float parameters; nothing else is coerced.  NaN is never a
    valid value.
    """
    expected = spec.type
    if expected is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if expected is tuple and isinstance(value, list):
        value = tuple(value)
    if _value_type(value) is not expected:
        raise ParameterError(f"{spec.name}: expected {expected.__name__}, got "
                             f"{type(value).__name__} {value!r}")
    numbers: Iterable = value if expected is tuple else (value,)
    for v in numbers:
        if isinstance(v, float) and math.isnan(v):
            raise ParameterError(f"{spec.name}: NaN is not a valid value")
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            if spec.minimum is not None and v < spec.minimum:
                raise ParameterError(f"{spec.name}: {v} is below the minimum {spec.minimum}")
            if spec.maximum is not None and v > spec.maximum:
                raise ParameterError(f"{spec.name}: {v} is above the maximum {spec.maximum}")
    if spec.choices is not None and value not in spec.choices:
        raise ParameterError(f"{spec.name}: {value!r} is not one of {list(spec.choices)}")
    return value


def validate_config(config: Any) -> None:
    """Raise :class:`ParameterError` naming the first field of ``config`` out of its range."""
    for spec in parameter_specs(config):
        validate_value(spec, get_value(config, spec.name))


def get_value(config: Any, dotted_name: str) -> Any:
    """Value of a (possibly nested) field, e.g. ``get_value(cfg, "kalman.sigma_u")``."""
    obj = config
    for part in dotted_name.split("."):
        obj = getattr(obj, part)
    return obj


def updated(config: Any, changes: Mapping[str, Any]) -> Any:
    """A copy of ``config`` with dotted-name ``changes`` applied, each validated.

    Raises :class:`ParameterError` (and changes nothing) if any name is unknown or any value
    is invalid, so a caller can keep its old config.
    """
    specs = {s.name: s for s in parameter_specs(config)}
    checked: dict[str, Any] = {}
    for name, value in changes.items():
        if name not in specs:
            raise ParameterError(f"unknown parameter {name!r}")
        checked[name] = validate_value(specs[name], value)
    result = config
    for name, value in checked.items():
        result = _replace_dotted(result, name.split("."), value)
    validate_config(result)
    return result


def _replace_dotted(config: Any, parts: list[str], value: Any) -> Any:
    if len(parts) == 1:
        return dataclasses.replace(config, **{parts[0]: value})
    child = getattr(config, parts[0])
    return dataclasses.replace(config, **{parts[0]: _replace_dotted(child, parts[1:], value)})


def as_flat_dict(config: Any) -> dict[str, Any]:
    """``{dotted_name: value}`` for every parameter of ``config``."""
    return {s.name: get_value(config, s.name) for s in parameter_specs(config)}
