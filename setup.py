"""Build description of the ``mk_tracker`` ament_python package.

The same file serves colcon on a ROS 2 system (``colcon build``) and the pip
environment made by ``scripts/setup_env.sh`` (``pip install -e .``).
"""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = "mk_tracker"

# Executables, as ``name = module:function``; ``ros2 run mk_tracker <name>`` finds them.
CONSOLE_SCRIPTS = [
    "detector_node = mk_tracker.ros.detector_node:main",
    "tracker_node = mk_tracker.ros.tracker_node:main",
    "bag_player = mk_tracker.ros.bag_player:main",
    "bag_recorder = mk_tracker.ros.bag_recorder:main",
    "mk_launch = mk_tracker.ros.launcher:main",
    "mk_tracker = mk_tracker.tools.cli:main",
]


def _share(subdir: str, pattern: str) -> tuple[str, list[str]]:
    """One ``data_files`` entry installing ``subdir/pattern`` under share/<package>/subdir."""
    return (f"share/{PACKAGE}/{subdir}", sorted(glob(f"{subdir}/{pattern}")))


setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test", "test.*"]),
    package_data={f"{PACKAGE}.messages.definitions": ["**/*.msg"]},
    include_package_data=False,
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        _share("config", "*"),
        _share("launch", "*"),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="mk_tracker team",
    maintainer_email="mk_tracker@example.com",
    description="Thermal detection and multiple-kernel tracking of people through occlusion",
    license="Apache-2.0",
    extras_require={"test": ["pytest"]},
    entry_points={"console_scripts": CONSOLE_SCRIPTS},
)
