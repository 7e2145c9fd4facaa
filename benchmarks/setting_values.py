"""Values of ``--set NAME=VALUE`` / ``--grid NAME=V1,V2`` options of the benchmark scripts."""

from __future__ import annotations

from typing import Any, Iterable


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


def setting_changes(items: Iterable[str]) -> dict[str, Any]:
    """``NAME=VALUE`` strings as ``{NAME: value}`` (values read by :func:`setting_value`).

    An item without ``=`` is refused: a typo must not silently become an empty change.
    """
    changes: dict[str, Any] = {}
    for item in items:
        name, sep, text = item.partition("=")
        if not sep or not name.strip():
            raise SystemExit(f"expected NAME=VALUE, got {item!r}")
        changes[name.strip()] = setting_value(text)
    return changes
