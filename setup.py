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

"""Build script: a plain setuptools package that is also an ament_python ROS 2 package.

Under ``colcon build`` (colcon sets ``COLCON=1``) the install step ends with
``gyro-platform compile``: the kernels of the default scene, the node and the replay compiled
into the shared kernel cache, so that the first ``ros2 launch`` of the workspace loads them
instead of compiling them (once per code version and machine; a later build loads them in a
few seconds). ``GYRO_PLATFORM_COMPILE_ON_BUILD=0`` skips it; a failure is a warning only. It
also writes the package's bytecode (of the source tree, which a ``--symlink-install`` imports,
and of a copied install) where ``PYTHONDONTWRITEBYTECODE=1`` would leave every process to
compile each module from source.
"""
import compileall
from glob import glob
import os
import subprocess
import sys

from setuptools import find_packages, setup
from setuptools.command.develop import develop
from setuptools.command.install import install

PACKAGE = "gyro_platform"
HERE = os.path.dirname(os.path.realpath(__file__))      # the source tree (colcon may run a symlink)


def compile_kernels() -> None:
    """``python -m gyro_platform compile`` from this source tree, under colcon only."""
    if os.environ.get("COLCON") != "1" or os.environ.get("GYRO_PLATFORM_COMPILE_ON_BUILD", "1") == "0":
        return
    print(f"{PACKAGE}: compiling the kernels of the default scene, the node and the replay into the kernel cache "
          "(once per code version and machine; GYRO_PLATFORM_COMPILE_ON_BUILD=0 skips)", flush=True)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in (HERE, os.environ.get("PYTHONPATH")) if p))
    try:
        rc = subprocess.run([sys.executable, "-m", PACKAGE, "compile"], cwd=HERE, env=env,
                            stderr=subprocess.STDOUT).returncode    # colcon: stderr would read as a warning
    except OSError as e:
        rc = str(e)
    if rc != 0:
        print(f"{PACKAGE}: warning: the kernels were not all compiled ({rc}); they compile at first use",
              flush=True)


class InstallThenCompile(install):
    """``setup.py install`` (colcon build), the installed modules' bytecode (setuptools skips it
    under ``PYTHONDONTWRITEBYTECODE``, and every process would then compile them from source),
    then :func:`compile_kernels`."""

    def run(self):
        super().run()
        compileall.compile_dir(os.path.join(self.install_lib, PACKAGE), quiet=2)
        compile_kernels()


class DevelopThenCompile(develop):
    """``setup.py develop`` (colcon build --symlink-install), then :func:`compile_kernels`."""

    def run(self):
        super().run()
        compile_kernels()


setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + PACKAGE]),
        ("share/" + PACKAGE, ["package.xml"]),
        ("share/" + PACKAGE + "/config", glob("config/*.yaml") + glob("config/*.xml") + glob("config/*.rviz")),
        ("share/" + PACKAGE + "/config/scenes", glob("config/scenes/*.yaml")),
        ("share/" + PACKAGE + "/launch", glob("launch/*.py")),
    ],
    python_requires=">=3.10",
    install_requires=[
        "numpy>=1.24",
        "scipy>=1.10",
        "numba>=0.58",
        "llvmlite",         # numba's own: physics/kernel_loading.py parses a cached kernel's bitcode when needed
        "matplotlib>=3.6",
        "pyyaml>=6",
        "rosbags>=0.11.6,<0.12",  # the range tested (test/rosbags_range.sh); internals used: bags/__init__.py
        "ruamel.yaml.clib>=0.2.7",  # rosbags reads metadata.yaml with ruamel: its C parser, 5x faster
        "apsw>=3.40",       # the sqlite3 output bag's writer (rosbags reads with it too)
        "mcap>=1.1",        # damaged-bag salvage: bags/salvage.py reads MCAP records in file order
        # a cut MCAP chunk decompressed as far as it goes (bags/salvage.py); both are rosbags' own
        "lz4>=4",
        "backports.zstd>=1.0; python_version < '3.14'",     # from 3.14 the standard library's compression.zstd
        "zstandard>=0.21",  # bags compressed message by message: one decompression context (bags/fast.py)
        "tqdm>=4.60",       # replay progress bar
        "threadpoolctl>=3.1",  # one BLAS thread per process (engine/blas.py)
    ],
    extras_require={
        "dds": ["cyclonedds>=11.0.1"],
        # gyro-platform sweep: Dask scheduling, Parquet tables
        "sweep": ["dask>=2024.1", "distributed>=2024.1", "pyarrow>=14,<26"],  # 26 needs numpy 2 (ROS Jazzy: 1.26)
        # gyro-platform bench peer: the same carried platform in MuJoCo (bench/peer_mujoco.py)
        "bench": ["mujoco>=3.1"],
        # the test suite: pytest, the manifest parser colcon uses, a URDF parser, property tests,
        # MuJoCo (test_bench checks the model against this second multibody engine)
        "test": ["pytest>=7", "catkin_pkg>=1.0", "urdf-parser-py>=0.0.4", "hypothesis>=6", "mujoco>=3.1",
                 "sphinx>=7", "myst-parser>=2"],   # test_docs builds the docs with sphinx-build -W
        # the documentation site: sphinx-build -W -b html docs docs/_build/html
        "docs": ["sphinx>=7", "myst-parser>=2"],
    },
    cmdclass={"install": InstallThenCompile, "develop": DevelopThenCompile},
    zip_safe=True,
    maintainer="gyro_platform developers",
    maintainer_email="gyro-platform@example.com",
    description="Gyro-stabilised three-gyro platform simulator (ROS 2 Jazzy node + ROS-free core)",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "gyro-platform = gyro_platform.cli:entry",
            "platform_node = gyro_platform.cli:platform_node",
        ],
    },
)
