"""Values of ``--set NAME=VALUE`` / ``--grid NAME=V1,V2`` options of the benchmark scripts."""

from __future__ import annotations

from typing import Any


def setting_value(text: str) -> Any:
    """A YAML value; numbers YAML reads as strings (``-1e12``) become floats."""
    import yaml
    value = yaml.safe_load(text)
    if isinstance(value, str):
        try:
            return float(value)
        except ValueError:
            pass
    return value
