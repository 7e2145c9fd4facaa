"""Static checks of the test suite against the project's test standard (docs/test_audit.md).

    python3 scripts/audit_tests.py [test]        # prints candidates; exit status always 0

Candidates, each to be read by a person (a listed line is not necessarily a defect):

* ``no-assert``: a test function with no ``assert``, ``raise``, ``pytest.raises/warns/fail``
  or ``assert_*`` call, that calls no helper (of any test module) doing one of those;
* ``constant-assert``: ``assert <constant>``, ``assert x == x``, ``assert len(x) >= 0``;
* ``weak-only``: every assert of the test is ``isinstance``/``is not None``/bare truthiness;
* ``skip``: every ``skip``/``skipif``/``xfail``/``importorskip`` (check what each is for);
* ``sleep``: every ``time.sleep`` and test-peer ``spin_for`` (a poll, a grace period or a
  pause that is the scenario is fine; a fixed wait for an outcome is not);
* ``wall-clock``: a comparison of ``monotonic()``/``perf_counter()``/``elapsed`` with a
  number (a bound that may assume the machine's speed);
* ``magic``: a float literal with five or more significant digits (an expected value that
  may have been pasted from the code's own output).

Standard library only (runs without the venv); no test is imported or run.
"""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

ASSERTING_CALLS = re.compile(r"(^|\.)(raises|warns|fail|approx|deprecated_call|assert\w*)$")
WEAK = re.compile(r"^(isinstance\(|callable\(|hasattr\(|[\w.]+ is not None$|[\w.]+$)")
TIMING = re.compile(r"(monotonic|perf_counter|time\.time|elapsed)")


def _call_name(call: ast.Call) -> str:
    return ast.unparse(call.func)


def _checks_itself(fn: ast.AST) -> bool:
    for node in ast.walk(fn):
        if isinstance(node, (ast.Assert, ast.Raise)):
            return True
        if isinstance(node, ast.Call) and ASSERTING_CALLS.search(_call_name(node)):
            return True
    return False


def _called_names(fn: ast.AST) -> set[str]:
    return {_call_name(c).split(".")[-1] for c in ast.walk(fn) if isinstance(c, ast.Call)}


def asserting_helpers(trees: dict[Path, ast.Module]) -> set[str]:
    """Names of non-test functions that check something, directly or through another."""
    functions: dict[str, list[ast.AST]] = {}
    for tree in trees.values():
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                functions.setdefault(node.name, []).append(node)
    found = {name for name, defs in functions.items()
             if not name.startswith("test") and any(_checks_itself(d) for d in defs)}
    grew = True
    while grew:
        grew = False
        for name, defs in functions.items():
            if name not in found and not name.startswith("test") and any(
                    _called_names(d) & found for d in defs):
                found.add(name)
                grew = True
    return found


def _constant_assert(test: ast.expr) -> bool:
    if isinstance(test, ast.Constant):
        return True
    if isinstance(test, ast.Compare) and len(test.ops) == 1:
        left, right = ast.unparse(test.left), ast.unparse(test.comparators[0])
        if left == right:
            return True
        if isinstance(test.ops[0], ast.GtE) and left.startswith("len(") and right == "0":
            return True
    return False


def _significant_digits(text: str) -> int:
    mantissa = re.split(r"[eE]", text)[0].replace("_", "").replace(".", "")
    return len(mantissa.strip("0"))


def audit(root: Path) -> list[tuple[str, str]]:
    trees = {p: ast.parse(p.read_text(), str(p)) for p in sorted(root.rglob("*.py"))}
    helpers = asserting_helpers(trees)
    found: list[tuple[str, str]] = []
    for path, tree in trees.items():
        lines = path.read_text().splitlines()
        for node in ast.walk(tree):
            where = f"{path}:{getattr(node, 'lineno', 0)}"
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) \
                    and node.name.startswith("test"):
                asserts = [a for a in ast.walk(node) if isinstance(a, ast.Assert)]
                if not _checks_itself(node) and not _called_names(node) & helpers:
                    found.append(("no-assert", f"{where} {node.name}"))
                elif asserts and not any(isinstance(c, ast.Call) and ASSERTING_CALLS.search(
                        _call_name(c)) for c in ast.walk(node)) and all(
                        WEAK.match(ast.unparse(a.test)) for a in asserts):
                    found.append(("weak-only", f"{where} {node.name}"))
            elif isinstance(node, ast.Assert) and _constant_assert(node.test):
                found.append(("constant-assert", f"{where} assert {ast.unparse(node.test)}"))
            elif isinstance(node, ast.Call):
                name = _call_name(node)
                if re.search(r"(^|\.)(skip|skipif|xfail|importorskip)$", name):
                    found.append(("skip", f"{where} {ast.unparse(node)[:120]}"))
                elif name in ("time.sleep", "sleep") or name.endswith(".spin_for"):
                    found.append(("sleep", f"{where} {ast.unparse(node)}"))
            elif isinstance(node, ast.Compare) and TIMING.search(ast.unparse(node)) and any(
                    isinstance(x, ast.Constant) and isinstance(x.value, (int, float))
                    for x in (node.left, *node.comparators)):
                found.append(("wall-clock", f"{where} {ast.unparse(node)[:120]}"))
            elif isinstance(node, ast.Constant) and isinstance(node.value, float):
                text = lines[node.lineno - 1][node.col_offset:node.end_col_offset]
                if _significant_digits(text) >= 5:
                    found.append(("magic", f"{where} {text}"))
    return found


def main(argv: list[str]) -> int:
    root = Path(argv[0] if argv else "test")
    found = audit(root)
    kinds = ("no-assert", "constant-assert", "weak-only", "skip", "sleep", "wall-clock", "magic")
    for kind in kinds:
        rows = [text for k, text in found if k == kind]
        print(f"== {kind}: {len(rows)}")
        for text in rows:
            print(f"   {text}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
