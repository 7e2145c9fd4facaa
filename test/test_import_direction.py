"""The direction of imports inside mk_tracker (issue #18).

The rule, as checked here:

* **Libraries** -- the top-level modules (``boxes``, ``kalman``, ``frame_processing`` ...)
  and the subpackages ``detection``, ``tracking``, ``messages``, ``bags``, ``synthetic``,
  ``evaluation`` and ``drawing`` -- import neither ``mk_tracker.ros`` nor
  ``mk_tracker.tools``, nor any ROS 2 runtime module.  A ROS 2 runtime module is a
  top-level module named ``rclpy``, ``launch``, ``launch_ros`` or ``ament_index_python``,
  one whose name starts with ``rcl``, ``rmw`` or ``rosidl`` (``rcl_interfaces``,
  ``rosidl_runtime_py`` ...), or a generated interface package, i.e. one whose name ends
  with ``_msgs``, ``_srvs`` or ``_interfaces`` (``sensor_msgs``, ``vision_msgs``,
  ``builtin_interfaces`` ...).  ``rosbags`` is not one: it is pure Python and reads bags
  without ROS.
* **Adapters** -- ``ros`` and ``tools`` -- may import anything.

Every ``import`` statement counts, wherever it stands (module level, inside a function,
under ``if TYPE_CHECKING``), and relative imports are resolved.  Imports by a computed
name (``__import__``, ``importlib.import_module``) cannot be read statically, so in the
libraries each one must be listed in :data:`DYNAMIC_IMPORTS_ALLOWED`.  The only one today is
:func:`mk_tracker.messages.message_types._lazy_ros_class`, which imports ``<package>.msg``
(never rclpy) when :func:`~mk_tracker.messages.message_types.ros_message_types` is called
-- and only the nodes in ``ros/`` call it.  A second test imports every library module in
a fresh interpreter and checks that no ROS runtime module was loaded on the way, which
also covers imports made by third-party packages.
"""

from __future__ import annotations

import ast
import json
import subprocess
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path

import pytest

PACKAGE_DIR = Path(__file__).resolve().parent.parent / "mk_tracker"

LIBRARY_SUBPACKAGES = frozenset(
    {"detection", "tracking", "messages", "bags", "synthetic", "evaluation", "drawing"})
ADAPTER_SUBPACKAGES = frozenset({"ros", "tools"})

ROS_RUNTIME_NAMES = frozenset({"rclpy", "launch", "launch_ros", "ament_index_python"})
ROS_RUNTIME_PREFIXES = ("rcl", "rmw", "rosidl")
ROS_INTERFACE_SUFFIXES = ("_msgs", "_srvs", "_interfaces")

#: (path relative to the package folder, enclosing function) of each dynamic import
#: allowed in a library module.
DYNAMIC_IMPORTS_ALLOWED = frozenset({("messages/message_types.py", "_lazy_ros_class")})


@dataclass(frozen=True)
class Violation:
    path: str      # relative to the package folder, with "/" separators
    line: int
    imported: str  # the imported module, or the dynamic call's text
    reason: str


def is_ros_runtime(module: str) -> bool:
    """Whether the dotted module name belongs to the ROS 2 runtime (see the module doc)."""
    top = module.split(".")[0]
    return (top in ROS_RUNTIME_NAMES or top.startswith(ROS_RUNTIME_PREFIXES)
            or top.endswith(ROS_INTERFACE_SUFFIXES))


def _module_name(package: str, rel: Path) -> tuple[str, bool]:
    """Dotted name of the file ``rel`` and whether it is a package ``__init__``."""
    parts = [package, *rel.with_suffix("").parts]
    is_init = parts[-1] == "__init__"
    if is_init:
        parts.pop()
    return ".".join(parts), is_init


def _imported_names(node: ast.AST, module: str, is_init: bool) -> list[str]:
    """Absolute dotted names an ``import`` / ``from ... import`` statement may load."""
    if isinstance(node, ast.Import):
        return [alias.name for alias in node.names]
    assert isinstance(node, ast.ImportFrom)
    if node.level:
        base = module.split(".") if is_init else module.split(".")[:-1]
        base = base[:len(base) - (node.level - 1)]
        source = ".".join(base + ([node.module] if node.module else []))
    else:
        source = node.module or ""
    # ``from mk_tracker import ros`` imports the subpackage mk_tracker.ros
    return [source] + [f"{source}.{alias.name}" for alias in node.names if alias.name != "*"]


def _is_dynamic_import(call: ast.Call) -> bool:
    func = call.func
    if isinstance(func, ast.Name):
        return func.id in {"__import__", "import_module"}
    return isinstance(func, ast.Attribute) and func.attr in {"__import__", "import_module"}


def _enclosing_functions(tree: ast.AST) -> dict[ast.AST, str]:
    """Each node -> name of the innermost function around it ("" at module level)."""
    owner: dict[ast.AST, str] = {}

    def visit(node: ast.AST, name: str) -> None:
        for child in ast.iter_child_nodes(node):
            inner = child.name if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)) \
                else name
            owner[child] = inner
            visit(child, inner)

    visit(tree, "")
    return owner


def import_violations(package_dir: Path, library_subpackages=LIBRARY_SUBPACKAGES,
                      adapter_subpackages=ADAPTER_SUBPACKAGES,
                      dynamic_allowed=DYNAMIC_IMPORTS_ALLOWED) -> list[Violation]:
    """Every import in a library module of ``package_dir`` that breaks the rule."""
    package = package_dir.name
    forbidden_prefixes = tuple(f"{package}.{name}" for name in sorted(adapter_subpackages))
    found: list[Violation] = []
    for path in sorted(package_dir.rglob("*.py")):
        rel = path.relative_to(package_dir)
        top = rel.parts[0] if len(rel.parts) > 1 else None
        if top in adapter_subpackages:
            continue
        assert top is None or top in library_subpackages, f"{rel}: unclassified subpackage"
        module, is_init = _module_name(package, rel)
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        owner = _enclosing_functions(tree)
        rel_text = rel.as_posix()
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                for name in _imported_names(node, module, is_init):
                    if is_ros_runtime(name):
                        found.append(Violation(rel_text, node.lineno, name, "ROS runtime"))
                    elif any(name == p or name.startswith(p + ".") for p in forbidden_prefixes):
                        found.append(Violation(rel_text, node.lineno, name, "adapter layer"))
            elif isinstance(node, ast.Call) and _is_dynamic_import(node):
                if (rel_text, owner.get(node, "")) not in dynamic_allowed:
                    found.append(Violation(rel_text, node.lineno, ast.unparse(node),
                                           "dynamic import"))
    # one statement can name the same module twice (``from x import y`` -> x, x.y)
    return sorted(set(found), key=lambda v: (v.path, v.line, v.imported))


# --------------------------------------------------------------------------- the package


def test_every_subpackage_is_classified_as_library_or_adapter():
    on_disk = {p.parent.name for p in PACKAGE_DIR.glob("*/__init__.py")}
    assert on_disk == LIBRARY_SUBPACKAGES | ADAPTER_SUBPACKAGES


def test_library_modules_import_neither_ros_runtime_nor_adapters():
    assert import_violations(PACKAGE_DIR) == []


def test_the_allowed_dynamic_import_still_exists():
    # If it moved, the allowance must move with it (and a stale allowance hides nothing).
    path = PACKAGE_DIR / "messages" / "message_types.py"
    tree = ast.parse(path.read_text(encoding="utf-8"))
    owner = _enclosing_functions(tree)
    calls = [owner[n] for n in ast.walk(tree) if isinstance(n, ast.Call) and _is_dynamic_import(n)]
    assert calls == ["_lazy_ros_class"]


def test_importing_every_library_module_loads_no_ros_runtime_module():
    modules = []
    for path in sorted(PACKAGE_DIR.rglob("*.py")):
        rel = path.relative_to(PACKAGE_DIR)
        if len(rel.parts) > 1 and rel.parts[0] in ADAPTER_SUBPACKAGES:
            continue
        modules.append(_module_name("mk_tracker", rel)[0])
    assert "mk_tracker.detection.thermal_detector" in modules
    script = textwrap.dedent("""
        import importlib, json, sys
        for name in json.loads(sys.argv[1]):
            importlib.import_module(name)
        print(json.dumps(sorted(sys.modules)))
    """)
    out = subprocess.run([sys.executable, "-c", script, json.dumps(modules)],
                         capture_output=True, text=True, timeout=300, check=True)
    loaded = json.loads(out.stdout.strip().splitlines()[-1])
    assert set(modules) <= set(loaded)
    assert [m for m in loaded if is_ros_runtime(m)] == []
    assert [m for m in loaded if m.startswith(("mk_tracker.ros", "mk_tracker.tools"))] == []


# --------------------------------------------------------------------------- the checker


def test_ros_runtime_names():
    for name in ("rclpy", "rclpy.node", "rcl_interfaces.msg", "rosidl_runtime_py.convert",
                 "rmw_fastrtps_cpp", "sensor_msgs.msg", "vision_msgs", "builtin_interfaces.msg",
                 "std_srvs.srv", "launch_ros.actions"):
        assert is_ros_runtime(name), name
    for name in ("rosbags.rosbag2", "numpy", "mk_tracker.messages.message_types", "cv2",
                 "launcher", "msgs"):
        assert not is_ros_runtime(name), name


def _write(root: Path, rel: str, text: str) -> None:
    path = root / rel
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(textwrap.dedent(text), encoding="utf-8")


def test_checker_finds_each_kind_of_violation_in_a_fake_package(tmp_path):
    pkg = tmp_path / "fakepkg"
    _write(pkg, "__init__.py", '"""fake"""\n')
    _write(pkg, "ros/__init__.py", "")
    _write(pkg, "ros/node.py", "import rclpy\nfrom sensor_msgs.msg import Image\n")
    _write(pkg, "tools/__init__.py", "")
    _write(pkg, "tools/cli.py", "import importlib\nimportlib.import_module('rclpy')\n")
    _write(pkg, "core/__init__.py", "from . import good\n")
    _write(pkg, "core/good.py", """\
        import numpy
        from rosbags.typesys import Stores
        from fakepkg import boxes
        from .. import boxes as b2
        from ..core import good
    """)
    _write(pkg, "core/bad.py", """\
        import numpy

        def later():
            import rclpy.node
            return rclpy

        from ..ros import node
        from fakepkg import tools
        import fakepkg.tools.cli as cli
        from vision_msgs.msg import Detection2D
    """)
    _write(pkg, "boxes.py", """\
        from typing import TYPE_CHECKING
        if TYPE_CHECKING:
            from fakepkg.ros.node import Image
        import importlib

        def load(name):
            return importlib.import_module(name)

        def allowed(name):
            return __import__(name)
    """)
    found = import_violations(pkg, library_subpackages={"core"},
                              dynamic_allowed={("boxes.py", "allowed")})
    assert [(v.path, v.line, v.imported, v.reason) for v in found] == [
        ("boxes.py", 3, "fakepkg.ros.node", "adapter layer"),
        ("boxes.py", 3, "fakepkg.ros.node.Image", "adapter layer"),
        ("boxes.py", 7, "importlib.import_module(name)", "dynamic import"),
        ("core/bad.py", 4, "rclpy.node", "ROS runtime"),
        ("core/bad.py", 7, "fakepkg.ros", "adapter layer"),
        ("core/bad.py", 7, "fakepkg.ros.node", "adapter layer"),
        ("core/bad.py", 8, "fakepkg.tools", "adapter layer"),
        ("core/bad.py", 9, "fakepkg.tools.cli", "adapter layer"),
        ("core/bad.py", 10, "vision_msgs.msg", "ROS runtime"),
        ("core/bad.py", 10, "vision_msgs.msg.Detection2D", "ROS runtime"),
    ]
    # without the allowance the second dynamic import is reported too
    found = import_violations(pkg, library_subpackages={"core"}, dynamic_allowed=set())
    assert ("boxes.py", 10) in {(v.path, v.line) for v in found}


def test_checker_rejects_an_unclassified_subpackage(tmp_path):
    pkg = tmp_path / "fakepkg"
    _write(pkg, "__init__.py", "")
    _write(pkg, "newpart/__init__.py", "")
    with pytest.raises(AssertionError, match="newpart/__init__.py: unclassified subpackage"):
        import_violations(pkg, library_subpackages=set())
