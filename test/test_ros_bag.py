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

"""``ros2 bag play --clock`` into the launched node with ``use_sim_time``, ``ros2 bag record`` of
its outputs, read back with rosbags (Jazzy typestore).

The input bag is written here with rosbags: 200 Hz Imu whose header stamps are 0 (a recording
without stamps), bag times from 1000 s. With ``use_sim_time:=true`` the node's receive time is
the ``/clock`` that ``ros2 bag play --clock`` publishes, so every output must be stamped in bag
time (1000–1004 s), not wall time; ``ros2 bag record`` of two output topics must give a bag
that rosbags reads with the outputs at the launch's output rate.
"""
import signal
import time

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.typesys import get_typestore, Stores

from imubag import write_imu_bag
import rosenv

RATE = 200.0
SECONDS = 3.0


@pytest.fixture(scope="module")
def replayed(ros_ws, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("bags")
    write_imu_bag(tmp / "input", int(RATE * SECONDS), RATE, w=(0.02, 0.0, 0.1), stamped=False)
    with rosenv.domain_lock() as domain:
        launch = ros_ws.start("ros2 launch gyro_platform platform.launch.py use_sim_time:=true output_rate:=20.0",
                              domain=domain)
        try:
            assert launch.wait_for("ready:", rosenv.READY_TIMEOUT), launch.output[-3000:]
            rec = ros_ws.start(f'ros2 bag record -o {tmp / "out"} /drift/angle /gimbal/joint_states', domain=domain)
            try:
                assert rec.wait_for("Recording", 60), rec.output[-3000:]
                assert rec.wait_for("Subscribed to topic '/drift/angle'", 30), rec.output[-3000:]
                play = ros_ws.run(f'ros2 bag play --clock 200 {tmp / "input"}', domain=domain, timeout=120)
                assert play.returncode == 0, play.stdout + play.stderr
                time.sleep(1.5)
            finally:
                rec_code = rec.stop(signal.SIGINT)
        finally:
            launch_code = launch.stop(signal.SIGINT)
    return tmp / "out", rec_code, launch_code, launch.output


def test_outputs_are_stamped_in_bag_time_and_the_recording_reads_back(replayed):
    out, rec_code, launch_code, log = replayed
    assert rec_code == 0 and launch_code == 0, log[-3000:]
    with AnyReader([out], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        stamps = {c.topic: [] for c in reader.connections}
        for conn, _, raw in reader.messages():
            m = reader.deserialize(raw, conn.msgtype)
            stamps[conn.topic].append(m.header.stamp.sec + m.header.stamp.nanosec * 1e-9)
    assert set(stamps) == {"/drift/angle", "/gimbal/joint_states"}
    for topic, t in stamps.items():
        t = np.array(t)
        assert len(t) >= 0.7 * 20 * SECONDS, f"{topic}: {len(t)} outputs for {SECONDS} s at 20 Hz"
        assert 1000.0 <= t.min() and t.max() <= 1000.0 + SECONDS + 0.5, f"{topic}: not bag time: {t[:3]}"
        assert np.all(np.diff(t) > 0)
        assert np.median(np.diff(t)) == pytest.approx(0.05, abs=1e-4)   # the 20 Hz grid
