"""Pack an installed ROS interface package (a CMake install prefix) into a wheel.

Used by ``scripts/setup_env.sh`` after ``cmake --install`` of an interface package of
``interfaces/`` (vision_msgs, mk_tracker_msgs): the files below
``<prefix>/lib/python3.X/site-packages`` become the wheel's importable content, every other
file (``lib/*.so``, ``share/<package>``, ``include``, the ament resource index) goes to the wheel's ``.data/data`` scheme, which pip installs relative
to the environment's prefix -- the same layout the ros-jazzy-* wheels use.  Installing
the wheel is then a plain ``pip install``, and pip can uninstall it again.

Usage::

    python scripts/interface_wheel.py --package vision_msgs \
        --distribution mk_tracker_vision_msgs --prefix STAGE --out DIR --version 4.1.1+abc
"""

from __future__ import annotations

import argparse
import base64
import hashlib
import os
import sys
import sysconfig
import zipfile
from pathlib import Path

# Build by-products that must not be shipped: byte code (pip compiles on install) and
# the egg-info that ament writes (pip would see a second distribution).
_SKIPPED_PARTS = ("__pycache__",)
_SKIPPED_SUFFIXES = (".pyc", ".egg-info")


def _record_hash(data: bytes) -> str:
    digest = hashlib.sha256(data).digest()
    return "sha256=" + base64.urlsafe_b64encode(digest).rstrip(b"=").decode("ascii")


def _skipped(relative: Path) -> bool:
    return any(part in _SKIPPED_PARTS or part.endswith(_SKIPPED_SUFFIXES)
               for part in relative.parts)


def _wheel_tag() -> str:
    interpreter = f"cp{sys.version_info.major}{sys.version_info.minor}"
    platform = sysconfig.get_platform().replace("-", "_").replace(".", "_")
    return f"{interpreter}-{interpreter}-{platform}"


def wheel_entries(prefix: Path, data_dir: str) -> list[tuple[str, Path]]:
    """Return (archive name, source file) pairs for every shippable file below ``prefix``."""
    site_packages = Path("lib") / f"python{sys.version_info.major}.{sys.version_info.minor}" \
        / "site-packages"
    entries = []
    for path in sorted(prefix.rglob("*")):
        if path.is_dir():
            continue
        relative = path.relative_to(prefix)
        if _skipped(relative):
            continue
        if relative.parts[:len(site_packages.parts)] == site_packages.parts:
            name = Path(*relative.parts[len(site_packages.parts):]).as_posix()
        else:
            name = f"{data_dir}/data/{relative.as_posix()}"
        entries.append((name, path))
    return entries


def build_wheel(prefix: Path, out_dir: Path, version: str, package: str,
                distribution: str) -> Path:
    """Write the wheel ``distribution`` for the install tree ``prefix`` of the interface
    package ``package`` into ``out_dir`` and return its path."""
    if not (prefix / "share" / package / "package.xml").is_file():
        raise SystemExit(f"{prefix} does not look like a {package} install prefix")
    tag = _wheel_tag()
    dist_info = f"{distribution}-{version}.dist-info"
    data_dir = f"{distribution}-{version}.data"
    out_dir.mkdir(parents=True, exist_ok=True)
    target = out_dir / f"{distribution}-{version}-{tag}.whl"
    metadata = (
        "Metadata-Version: 2.1\n"
        f"Name: {distribution}\n"
        f"Version: {version}\n"
        f"Summary: {package} interfaces (C, C++, Python type support) built by mk_tracker\n"
        "License: Apache-2.0\n"
    )
    wheel_file = (
        "Wheel-Version: 1.0\n"
        "Generator: mk_tracker scripts/interface_wheel.py\n"
        "Root-Is-Purelib: false\n"
        f"Tag: {tag}\n"
    )
    records = []
    partial = target.with_suffix(".partial")
    with zipfile.ZipFile(partial, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name, path in wheel_entries(prefix, data_dir):
            data = path.read_bytes()
            info = zipfile.ZipInfo(name, date_time=(2020, 1, 1, 0, 0, 0))
            info.external_attr = (path.stat().st_mode & 0o777 | 0o100000) << 16
            info.compress_type = zipfile.ZIP_DEFLATED
            archive.writestr(info, data)
            records.append(f"{name},{_record_hash(data)},{len(data)}")
        for name, text in (("METADATA", metadata), ("WHEEL", wheel_file)):
            data = text.encode("utf-8")
            archive.writestr(f"{dist_info}/{name}", data)
            records.append(f"{dist_info}/{name},{_record_hash(data)},{len(data)}")
        records.append(f"{dist_info}/RECORD,,")
        archive.writestr(f"{dist_info}/RECORD", "\n".join(records) + "\n")
    os.replace(partial, target)
    return target


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--package", required=True, help="ROS package name, e.g. vision_msgs")
    parser.add_argument("--distribution", required=True,
                        help="wheel distribution name, e.g. mk_tracker_vision_msgs")
    parser.add_argument("--prefix", type=Path, required=True, help="cmake install prefix")
    parser.add_argument("--out", type=Path, required=True, help="folder for the wheel")
    parser.add_argument("--version", required=True, help="wheel version, e.g. 4.1.1+<key>")
    args = parser.parse_args(argv)
    print(build_wheel(args.prefix.resolve(), args.out, args.version, args.package,
                      args.distribution))
    return 0


if __name__ == "__main__":
    sys.exit(main())
