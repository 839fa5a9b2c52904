# Copyright 2026 gyro_platform developers
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.

"""The ROS manifest as colcon, ament and rosdep read it (``catkin_pkg``, what colcon uses).

colcon identifies an ``ament_python`` package only if ``package.xml`` parses with catkin_pkg
and exports that build type; rosdep installs exactly the declared dependencies. So: the
manifest must parse, be format 3, export ``ament_python``, agree with ``setup.py`` on name and
version, and declare every third-party module the package imports at run time.
"""
from __future__ import annotations

import ast
from pathlib import Path
import re
import sys

import pytest

catkin_pkg = pytest.importorskip(
    "catkin_pkg.package", reason="catkin_pkg (pip install catkin_pkg) parses package.xml as colcon does"
)

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "gyro_platform"

#: no rosdep key on Ubuntu 24.04 (checked against ros/rosdistro rosdep/python.yaml): pip-installed,
#: so not an exec_depend (rosdep would fail on it) but in setup.py and named in package.xml's comment
PIP = "pip"
# top-level import name -> the rosdep key (or ROS package) that provides it, or PIP
PROVIDERS = {
    "numpy": "python3-numpy",
    "scipy": "python3-scipy",
    "yaml": "python3-yaml",
    "matplotlib": "python3-matplotlib",
    "numba": PIP,
    "llvmlite": PIP,            # numba's own, imported by physics/kernel_loading.py
    "rosbags": PIP,
    "apsw": PIP,
    "threadpoolctl": PIP,
    "cyclonedds": PIP,
    "rclpy": "rclpy",
    "ament_index_python": "ament_index_python",
    "rcl_interfaces": "rcl_interfaces",
    "diagnostic_updater": "diagnostic_updater",
    "diagnostic_msgs": "diagnostic_msgs",
    "std_msgs": "std_msgs",
    "std_srvs": "std_srvs",
    "sensor_msgs": "sensor_msgs",
    "geometry_msgs": "geometry_msgs",
    "rosgraph_msgs": "rosgraph_msgs",
    "tf2_msgs": "tf2_msgs",
    "launch": "launch",
    "launch_ros": "launch_ros",
    "tqdm": "python3-tqdm",
    "mcap": PIP,
    "dask": "python3-dask",
    "distributed": PIP,
    "pandas": "python3-pandas",
    "pyarrow": PIP,
    "mujoco": PIP,
    "lz4": PIP,
    "backports": PIP,           # backports.zstd, before Python 3.14
    "zstandard": PIP,           # mcap's own; bags compressed message by message (bags/fast.py)
}
#: standard-library modules of a later Python than some this package runs on (imported in a
#: try/except beside their backport): compression.zstd from 3.14
LATER_STDLIB = {"compression"}


def _manifest():
    return catkin_pkg.parse_package(str(ROOT / "package.xml"))


def _imported_modules() -> set[str]:
    """Top-level names of every non-stdlib module imported anywhere in the package."""
    names: set[str] = set()
    for path in SRC.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                names.update(a.name.split(".")[0] for a in node.names)
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names.add(node.module.split(".")[0])
    return {n for n in names
            if n not in sys.stdlib_module_names and n not in LATER_STDLIB and n not in {"gyro_platform", "__future__"}}


def test_manifest_parses_as_colcon_reads_it():
    pkg = _manifest()
    pkg.validate()  # raises InvalidPackage on anything catkin_pkg rejects
    assert pkg.package_format == 3
    assert pkg.name == "gyro_platform"
    assert pkg.get_build_type() == "ament_python"


def test_manifest_agrees_with_setup_py():
    setup_py = (ROOT / "setup.py").read_text()
    version = re.search(r'version="([^"]+)"', setup_py).group(1)
    assert _manifest().version == version
    assert (ROOT / "resource" / "gyro_platform").is_file(), "ament index marker missing"


def test_every_runtime_import_is_declared():
    pkg = _manifest()
    declared = {d.name for d in pkg.exec_depends}
    missing = []
    setup_py = (ROOT / "setup.py").read_text().lower()
    manifest_text = (ROOT / "package.xml").read_text()
    for module in sorted(_imported_modules()):
        assert module in PROVIDERS, f"no rosdep key known for imported module {module!r}: add it to PROVIDERS"
        if PROVIDERS[module] == PIP:
            assert f'"{module}' in setup_py, f"{module} is pip-installed but not in setup.py"
            assert "pip install" in manifest_text and module in manifest_text, \
                f"{module} is pip-installed: say so in package.xml's comment"
        elif PROVIDERS[module] not in declared:
            missing.append(f"{module} -> {PROVIDERS[module]}")
    assert not missing, f"imported but not declared as exec_depend: {missing}"
    assert not declared & {"python3-numba-pip", "python3-rosbags-pip", "python3-cyclonedds-pip"}, \
        "rosdep keys that do not exist"


def test_launch_file_dependencies_declared():
    declared = {d.name for d in _manifest().exec_depends}
    for launch_file in (ROOT / "launch").glob("*.py"):
        tree = ast.parse(launch_file.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module:
                top = node.module.split(".")[0]
                if top not in sys.stdlib_module_names and top != "gyro_platform":
                    assert PROVIDERS.get(top, top) in declared, f"{launch_file.name} imports {top}"
            # packages started by the launch file (Node(package=...)) must be run-time dependencies
            if isinstance(node, ast.keyword) and node.arg == "package" and isinstance(node.value, ast.Constant):
                if node.value.value != "gyro_platform":
                    assert node.value.value in declared, f"{launch_file.name} starts {node.value.value}"
