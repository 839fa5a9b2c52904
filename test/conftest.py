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

"""Fixtures of the ROS tests: ROS 2 Jazzy found from outside, a colcon workspace, a domain.

``ros`` is the ROS 2 environment (:func:`rosenv.find`; the tests that need it skip with the
reason where none is found), ``ros_ws`` this package built with ``colcon build
--symlink-install`` into a temporary workspace once per session, ``domain`` a
``ROS_DOMAIN_ID`` held by this test alone (tests may run side by side). ``test_node_ros.py``
drives the rclpy node in-process: where this interpreter cannot import rclpy (the project's
venv, numpy 2) but ROS 2 is found, its tests run in ROS's python, once per session, and each
reports its own outcome here (:class:`RclpyModule`).
"""
import ast
from pathlib import Path
import xml.etree.ElementTree as ET

import pytest

import rosenv

IN_ROS_PYTHON = ("test_node_ros.py",)


def rclpy_in_process() -> bool:
    """True when this interpreter imports rclpy and the message packages (ROS's python)."""
    try:
        import rclpy  # noqa: F401
        import sensor_msgs.msg  # noqa: F401
    except Exception:   # ImportError, or numpy-ABI errors of rosidl's C extensions
        return False
    return True


@pytest.fixture(scope="session")
def ros():
    env, why = rosenv.find()
    if env is None:
        pytest.skip(why)
    return env


@pytest.fixture(scope="session")
def ros_ws(ros, tmp_path_factory):
    return rosenv.Workspace.build(ros, tmp_path_factory.mktemp("ws_symlink"), symlink_install=True)


@pytest.fixture
def domain():
    with rosenv.domain_lock() as d:
        yield d


# ---- test_node_ros.py in ROS's python ------------------------------------------------------
@pytest.hookimpl(tryfirst=True)
def pytest_pycollect_makemodule(module_path: Path, parent):
    """Every test module is collected here, as pytest does: an rclpy module as
    :class:`RclpyModule` where it cannot run in-process, the others as ``pytest.Module``.

    Taking the hook first keeps launch_testing's plugin (loaded by ROS's pytest, ``colcon
    test``) from importing each module outside pytest's collector, where one module-level skip
    (``pytest.importorskip``) skipped the whole session ("no tests collected", exit 5); this suite
    has no launch_testing module (the launch tests run ``ros2 launch`` from outside).
    """
    if module_path.name in IN_ROS_PYTHON and not rclpy_in_process() and rosenv.find()[0] is not None:
        return RclpyModule.from_parent(parent, path=module_path)
    return pytest.Module.from_parent(parent, path=module_path)


class RclpyModule(pytest.File):
    """The test functions of an rclpy module, run together in ROS's python (one subprocess)."""

    def collect(self):
        tree = ast.parse(self.path.read_text())
        for node in tree.body:
            if isinstance(node, ast.FunctionDef) and node.name.startswith("test"):
                yield RclpyItem.from_parent(self, name=node.name)

    def outcomes(self) -> dict:
        if not hasattr(self, "_outcomes"):
            ros, _ = rosenv.find()
            xml = self.config._tmp_path_factory.mktemp("rclpy") / "junit.xml"
            with rosenv.domain_lock() as domain:
                p = ros.run([ros.python, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(self.path),
                             f"--junitxml={xml}", "-o", "junit_family=xunit1"],
                            domain=domain, cwd=rosenv.REPO, timeout=1800,
                            env={"PYTHONPATH": f"{rosenv.REPO}:" + ros.environ.get("PYTHONPATH", "")})
            self._outcomes = {"_log": p.stdout[-6000:] + p.stderr[-3000:]}
            if xml.is_file():
                for case in ET.parse(xml).getroot().iter("testcase"):
                    bad = [c for c in case if c.tag in ("failure", "error", "skipped")]
                    self._outcomes[case.get("name")] = (bad[0].tag, (bad[0].get("message") or "") + "\n" +
                                                        (bad[0].text or "")) if bad else ("passed", "")
        return self._outcomes


class RclpyItem(pytest.Item):
    """One test of an :class:`RclpyModule`: its outcome in ROS's python."""

    def runtest(self):
        outcomes = self.parent.outcomes()
        if self.name not in outcomes:
            raise AssertionError(f'{self.name} did not run in ROS python:\n{outcomes["_log"]}')
        kind, text = outcomes[self.name]
        if kind == "skipped":
            pytest.skip(text.strip().splitlines()[0] if text.strip() else "skipped in ROS python")
        if kind != "passed":
            raise AssertionError(f"{kind} in ROS python:\n{text}")

    def repr_failure(self, excinfo):
        return str(excinfo.value)

    def reportinfo(self):
        return self.path, None, f"{self.name} (in ROS python)"


def pytest_configure(config):
    for mark in ("linter", "flake8", "pep257", "copyright", "xmllint"):
        config.addinivalue_line("markers", f"{mark}: an ament linter test (ROS 2 package convention)")
