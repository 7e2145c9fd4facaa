"""Tests of the parameter declaration convention shared by every config."""

from dataclasses import dataclass

import pytest

from mk_tracker.parameters import (ParameterError, as_flat_dict, parameter, parameter_specs,
                                   updated, validate_config)


@dataclass(frozen=True)
class Inner:
    sigma: float = parameter(1.0, "a std", minimum=0.0, maximum=10.0)


@dataclass(frozen=True)
class Outer:
    count: int = parameter(3, "a count", minimum=1)
    mode: str = parameter("a", "a mode", choices=("a", "b"))
    inner: Inner = parameter(Inner(), "nested")


def test_specs_are_flattened_with_dotted_names():
    names = [s.name for s in parameter_specs(Outer)]
    assert names == ["count", "mode", "inner.sigma"]
    assert parameter_specs(Outer)[2].maximum == 10.0


def test_updated_applies_valid_changes_and_coerces_int_to_float():
    cfg = updated(Outer(), {"inner.sigma": 2, "mode": "b"})
    assert cfg.inner.sigma == 2.0 and isinstance(cfg.inner.sigma, float)
    assert cfg.mode == "b"
    assert as_flat_dict(cfg) == {"count": 3, "mode": "b", "inner.sigma": 2.0}


@pytest.mark.parametrize("changes, fragment", [
    ({"count": 0}, "below the minimum"),
    ({"count": 1.5}, "expected int"),
    ({"inner.sigma": float("nan")}, "NaN"),
    ({"inner.sigma": 11.0}, "above the maximum"),
    ({"mode": "c"}, "not one of"),
    ({"nope": 1}, "unknown parameter"),
    ({"count": True}, "expected int"),
])
def test_bad_values_are_rejected_with_a_reason(changes, fragment):
    with pytest.raises(ParameterError, match=fragment):
        updated(Outer(), changes)


def test_validate_config_catches_a_bad_constructed_config():
    with pytest.raises(ParameterError, match="count"):
        validate_config(Outer(count=-1))
