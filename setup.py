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

"""Build script: a plain setuptools package that is also an ament_python ROS 2 package."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = "gyro_platform"

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
        "matplotlib>=3.6",
        "pyyaml>=6",
        "rosbags>=0.11.6,<0.12",  # the range tested (test/rosbags_range.sh); internals used: bags/__init__.py
        "ruamel.yaml.clib>=0.2.7",  # rosbags reads metadata.yaml with ruamel: its C parser, 5x faster
        "apsw>=3.40",       # the sqlite3 output bag's writer (rosbags reads with it too)
        "mcap>=1.1",        # damaged-bag salvage: bags/salvage.py reads MCAP records in file order
        "tqdm>=4.60",       # replay progress bar
        "threadpoolctl>=3.1",  # one BLAS thread per process (engine/blas.py)
    ],
    extras_require={
        "dds": ["cyclonedds>=11.0.1"],
        # gyro-platform sweep: Dask scheduling, Parquet tables
        "sweep": ["dask>=2024.1", "distributed>=2024.1", "pyarrow>=14,<26"],  # 26 needs numpy 2 (ROS Jazzy: 1.26)
        # gyro-platform bench peer: the same carried platform in MuJoCo (bench/peer_mujoco.py)
        "bench": ["mujoco>=3.1"],
        # the test suite: pytest, the manifest parser colcon uses, a URDF parser, property tests
        "test": ["pytest>=7", "catkin_pkg>=1.0", "urdf-parser-py>=0.0.4", "hypothesis>=6",
                 "sphinx>=7", "myst-parser>=2"],   # test_docs builds the docs with sphinx-build -W
        # the documentation site: sphinx-build -W -b html docs docs/_build/html
        "docs": ["sphinx>=7", "myst-parser>=2"],
    },
    zip_safe=True,
    maintainer="gyro_platform developers",
    maintainer_email="gyro-platform@example.com",
    description="Gyro-stabilised three-gyro platform simulator (ROS 2 Jazzy node + ROS-free core)",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "gyro-platform = gyro_platform.cli:main",
            "platform_node = gyro_platform.ros.node:main",
        ],
    },
)
