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

"""Parameters and services of ``ros2 run gyro_platform platform_node``, through the ``ros2`` CLI.

The node runs from the colcon workspace (conftest ``ros_ws``) with the package's params file;
``ros2 param describe / get / set / dump`` and ``ros2 service call`` talk to it as a user's shell
does. Checked: descriptors (type, range, read-only, description), a live change that the node
applies to the next samples, refusals of a read-only parameter and of an out-of-range value (the
value stays), a dump the node restarts from with the changed value, and ``~/reset``.
"""
import re
import signal

import pytest

import rosenv

NODE = "/gyro_platform_node"
CLI = "--no-daemon --spin-time 3 --timeout 20"


def start_node(ws, domain, extra=""):
    params = ws.share / "config" / "platform.yaml"
    proc = ws.start(f"ros2 run gyro_platform platform_node --ros-args --params-file {params} {extra}",
                    domain=domain)
    assert proc.wait_for("ready:", rosenv.READY_TIMEOUT), proc.output[-3000:]
    return proc


def cli(ws, domain, verb, *args):
    p = ws.run(f"ros2 param {verb} {CLI} {NODE} " + " ".join(args), domain=domain, timeout=90)
    return p.returncode, p.stdout + p.stderr


@pytest.fixture(scope="module")
def session(ros_ws, tmp_path_factory):
    """One node: a scripted session of CLI calls; every output kept for the tests below."""
    out = {}
    with rosenv.domain_lock() as domain:
        proc = start_node(ros_ws, domain)
        try:
            out["describe"] = cli(ros_ws, domain, "describe", "gate.max_rate")
            out["get_before"] = cli(ros_ws, domain, "get", "gate.max_rate")
            out["set_live"] = cli(ros_ws, domain, "set", "gate.max_rate", "20.0")
            out["get_after"] = cli(ros_ws, domain, "get", "gate.max_rate")
            out["set_read_only"] = cli(ros_ws, domain, "set", "input_type", "twist")
            out["set_out_of_range"] = cli(ros_ws, domain, "set", "gate.max_rate", "1.0e9")
            out["get_kept"] = cli(ros_ws, domain, "get", "gate.max_rate")
            # the live change applies: |ω| = 25 rad/s > 20 is now dropped, 10 rad/s is taken
            probe = {"wait_subscriber": "/imu", "collect": {"/drift/angle": "geometry_msgs/msg/Vector3Stamped"},
                     "publish": {"topic": "/imu", "count": 50, "rate": 100.0, "w": [0.0, 0.0, 25.0]},
                     "settle": 1.0}
            out["fast"] = ros_ws.ros.probe(probe, domain=domain)
            probe["publish"]["w"] = [0.0, 0.0, 10.0]
            out["slow"] = ros_ws.ros.probe(probe, domain=domain)
            code, dump = cli(ros_ws, domain, "dump")
            out["dump"] = (code, dump)
            reset = ros_ws.run(f"ros2 service call {NODE}/reset std_srvs/srv/Trigger", domain=domain, timeout=90)
            out["reset"] = (reset.returncode, reset.stdout + reset.stderr)
        finally:
            out["exit"] = proc.stop(signal.SIGINT)
            out["log"] = proc.output
        # restart from the dump: the changed value is back
        dump_file = tmp_path_factory.mktemp("dump") / "dump.yaml"
        dump_file.write_text(out["dump"][1])
        proc = ros_ws.start(f"ros2 run gyro_platform platform_node --ros-args --params-file {dump_file}",
                            domain=domain)
        try:
            out["restart_ready"] = proc.wait_for("ready:", rosenv.READY_TIMEOUT)
            out["get_restarted"] = cli(ros_ws, domain, "get", "gate.max_rate")
        finally:
            proc.stop(signal.SIGINT)
            out["restart_log"] = proc.output
    return out


def test_describe_shows_type_range_and_description(session):
    code, text = session["describe"]
    assert code == 0, text
    assert "Type: double" in text
    assert re.search(r"Min value: 0\.001\s*$", text, re.M), text
    assert re.search(r"Max value: 10000(\.0)?\s*$", text, re.M), text
    assert "rad/s" in text


def test_get_then_live_set_is_applied_to_the_next_samples(session):
    assert "Double value is: 35.0" in session["get_before"][1]
    assert session["set_live"][0] == 0 and "Set parameter successful" in session["set_live"][1]
    assert "Double value is: 20.0" in session["get_after"][1]
    assert session["fast"]["topics"]["/drift/angle"] == []       # 25 rad/s > 20: every sample dropped
    assert len(session["slow"]["topics"]["/drift/angle"]) > 0    # 10 rad/s: taken


def test_read_only_and_out_of_range_are_refused_and_the_value_stays(session):
    text = session["set_read_only"][1]
    assert "Setting parameter failed" in text and "read-only" in text.lower(), text
    text = session["set_out_of_range"][1]
    assert "Setting parameter failed" in text, text
    assert "Double value is: 20.0" in session["get_kept"][1]


def test_param_dump_restarts_the_node_with_the_changed_value(session):
    code, dump = session["dump"]
    assert code == 0 and "gyro_platform_node" in dump and "ros__parameters" in dump, dump
    assert session["restart_ready"], session["restart_log"][-3000:]
    assert "Double value is: 20.0" in session["get_restarted"][1], session["restart_log"][-3000:]


def test_reset_service(session):
    code, text = session["reset"]
    assert code == 0 and "success=True" in text, text


def test_the_node_stops_on_sigint_with_exit_0(session):
    assert session["exit"] == 0, session["log"][-3000:]
    assert "Traceback" not in session["log"]
