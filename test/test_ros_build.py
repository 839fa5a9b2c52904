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

"""``colcon build`` of this package, plain and ``--symlink-install``, and the installed node.

A user's first steps with a ROS 2 package: build it into a workspace, source the overlay, find
it in the ament index (``ros2 pkg prefix``, ``ros2 pkg executables``), its launch file, params
file and scenes installed under ``share/``, and the node of a *plain* install (a copy of the
sources; its kernels come from the content-keyed cache when the same code compiled them before)
starting: the time from ``ros2 run`` to its ``ready:`` line is printed (speed is the bench's,
not asserted here).
"""
import os
import re
import signal
import subprocess
import sys
import time

import pytest

import rosenv


@pytest.fixture(scope="module")
def plain_ws(ros, tmp_path_factory):
    return rosenv.Workspace.build(ros, tmp_path_factory.mktemp("ws_plain"), symlink_install=False)


@pytest.mark.parametrize("which", ["plain", "symlink"])
def test_colcon_build_installs_the_package_into_the_ament_index(which, plain_ws, ros_ws):
    ws = plain_ws if which == "plain" else ros_ws
    # the install step ends with ``gyro-platform compile`` (setup.py): every step compiled or loaded
    assert "gyro-platform compile: 4 of 4 steps" in ws.build_log, ws.build_log[-3000:]
    prefix = ws.run("ros2 pkg prefix gyro_platform", check=True).stdout.strip()
    assert prefix == str(ws.root / "install" / "gyro_platform")
    exes = ws.run("ros2 pkg executables gyro_platform", check=True).stdout.split()
    assert "platform_node" in exes
    for f in ("launch/platform.launch.py", "config/platform.yaml", "config/scenes/default.yaml",
              "config/scenes/husky_replay.yaml", "package.xml"):
        assert (ws.share / f).is_file(), f
    module = ws.run("python3 -c 'import gyro_platform, os; print(os.path.realpath(gyro_platform.__file__))'",
                    check=True, cwd=ws.root).stdout.strip()
    if which == "symlink":
        assert module == str(rosenv.REPO / "gyro_platform" / "__init__.py")    # edits need no rebuild
    else:
        assert module.startswith(str(ws.root / "install"))


def test_the_node_of_a_plain_install_starts_and_publishes(plain_ws, domain, capsys):
    """A copy of the sources, started with ``ros2 run`` as a user does."""
    params = plain_ws.share / "config" / "platform.yaml"
    t0 = time.monotonic()
    proc = plain_ws.start(f"ros2 run gyro_platform platform_node --ros-args --params-file {params}", domain=domain)
    try:
        assert proc.wait_for("ready:", rosenv.READY_TIMEOUT), proc.output[-3000:]
        ready_s = time.monotonic() - t0
        report = plain_ws.ros.probe({"wait_subscriber": "/imu", "publish": {"topic": "/imu", "count": 50},
                                     "collect": {"/drift/angle": "geometry_msgs/msg/Vector3Stamped"}},
                                    domain=domain)
    finally:
        code = proc.stop(signal.SIGINT)
    with capsys.disabled():
        print(f"\n  plain colcon install: ros2 run -> ready: {ready_s:.1f} s")
    assert report["topics"]["/drift/angle"]
    assert code == 0 and "Traceback" not in proc.output


def test_the_node_on_an_empty_kernel_cache_is_ready_while_its_kernels_compile(plain_ws, domain, tmp_path):
    """``ros2 run`` where the kernel cache has nothing (an image run on another CPU): the node
    logs that its kernels are not compiled yet, is ready while a background process compiles them,
    publishes from the interpreted kernels, and a Ctrl-C stops it (exit 0) and that process."""
    params = plain_ws.share / "config" / "platform.yaml"
    proc = plain_ws.start(f"ros2 run gyro_platform platform_node --ros-args --params-file {params}", domain=domain,
                          env={"NUMBA_CACHE_DIR": str(tmp_path / "numba")})
    try:
        assert proc.wait_for("ready:", rosenv.READY_TIMEOUT), proc.output[-3000:]
        assert "not compiled yet" in proc.output, proc.output[-3000:]
        pid = int(proc.output.split("(pid ")[1].split(")")[0])
        os.kill(pid, 0)                                 # still compiling when the node is ready
        report = plain_ws.ros.probe({"wait_subscriber": "/imu", "publish": {"topic": "/imu", "count": 50},
                                     "collect": {"/drift/angle": "geometry_msgs/msg/Vector3Stamped"}},
                                    domain=domain)
    finally:
        code = proc.stop(signal.SIGINT)
    assert report["topics"]["/drift/angle"]
    assert code == 0 and "Traceback" not in proc.output
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)                                 # stopped with the node


def test_gyro_platform_node_on_the_ros_transport_takes_its_options(ros_ws, domain):
    """``gyro-platform node --transport auto`` in ROS's environment runs the rclpy node, with
    --namespace, --node-name and --scene passed as ROS arguments; --duration stops it (exit 0)."""
    proc = ros_ws.start("python3 -m gyro_platform node --namespace veh --node-name gp --scene coning "
                        "--duration 60", domain=domain, cwd=ros_ws.root)
    try:
        assert proc.wait_for("ready:", rosenv.READY_TIMEOUT), proc.output[-3000:]
        assert "transport: ros (auto: rclpy found)" in proc.output
        nodes = ros_ws.run("ros2 node list --no-daemon --spin-time 3", domain=domain, check=True).stdout.split()
        scene = ros_ws.run("ros2 param get --no-daemon --spin-time 3 /veh/gp scene", domain=domain).stdout
    finally:
        code = proc.stop(signal.SIGINT)
    assert "/veh/gp" in nodes
    assert "String value is: coning" in scene
    assert code == 0 and "Traceback" not in proc.output


def test_colcon_test_collects_the_whole_suite(ros_ws):
    """``colcon test`` (ROS's python, numpy 1.26, ROS's pytest plugins) collects exactly the
    tests this interpreter collects: no module skipped for its environment, no session lost."""
    here = subprocess.run([sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider", "test"],
                          cwd=rosenv.REPO, capture_output=True, text=True, timeout=600)
    there = ros_ws.run("colcon test --packages-select gyro_platform --event-handlers console_direct+ "
                       "--pytest-args --collect-only -q -p no:cacheprovider", cwd=ros_ws.root, timeout=900)
    count = re.compile(r"(\d+) tests? collected")
    n_here = count.findall(here.stdout)
    n_there = count.findall(there.stdout + there.stderr)
    assert n_here and n_there, (here.stdout[-2000:], there.stdout[-4000:], there.stderr[-2000:])
    assert int(n_there[-1]) == int(n_here[-1]), (
        f"colcon test collects {n_there[-1]}, this venv {n_here[-1]}: install the pip-only dependencies "
        "into ROS's python as the README's ROS 2 section says\n" + there.stdout[-3000:])
