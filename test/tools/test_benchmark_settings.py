"""``--set NAME=VALUE`` parsing shared by the benchmark scripts (benchmarks/setting_values.py)."""

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

from setting_values import setting_changes, setting_value  # noqa: E402


def test_values_are_read_as_yaml_and_numbers_yaml_leaves_as_text_become_floats():
    assert setting_value("true") is True
    assert setting_value("3") == 3
    assert setting_value("-1e12") == -1.0e12          # YAML 1.1 reads this as a string
    assert setting_value("[0, 0, 110, 50]") == [0, 0, 110, 50]
    assert setting_value("hsv") == "hsv"


def test_changes_keep_dotted_names_and_split_at_the_first_equals_sign():
    assert setting_changes(["lifecycle.min_hits=2", " a = 0.5", "expr=x=1"]) == {
        "lifecycle.min_hits": 2, "a": 0.5, "expr": "x=1"}
    assert setting_changes([]) == {}


@pytest.mark.parametrize("item", ["min_hits", "=3", ""])
def test_an_item_without_a_name_and_value_is_refused(item):
    with pytest.raises(SystemExit, match="NAME=VALUE"):
        setting_changes([item])
