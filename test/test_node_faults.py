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

"""The node core under a ROS graph's faults (issue 33), ROS-free: what the launched node's
tests (test_ros_faults.py) see from outside, pinned down at the core.

A looped ``ros2 bag play --clock`` moves the input stamps and /clock back together, in either
order: one reset per loop. Input frame_ids are counted by name in the diagnostics.
"""
from __future__ import annotations

import numpy as np
import pytest

from gyro_platform.messages import jazzy_typestore, MessageTypes
from gyro_platform.ros.config import NodeConfig
from gyro_platform.ros.core import MAX_FRAMES, NodeCore

T = jazzy_typestore().types
TYPES = MessageTypes.rosbags()
BASE = 1000 * 10**9
MS = 10**6


def imu(t_ns: int, frame: str = "base_link"):
    sec, nsec = divmod(t_ns, 10**9)
    v = T["geometry_msgs/msg/Vector3"]
    return T["sensor_msgs/msg/Imu"](
        header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec),
                                        frame_id=frame),
        orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=np.zeros(9), angular_velocity=v(x=0.0, y=0.0, z=0.05),
        angular_velocity_covariance=np.zeros(9), linear_acceleration=v(x=0.0, y=0.0, z=9.81),
        linear_acceleration_covariance=np.zeros(9))


def make_core(**params) -> NodeCore:
    return NodeCore(NodeConfig.from_ros_params({"output_rate": 10.0, **params}), TYPES, clock_ns=lambda: 0)


def loop(core: NodeCore, n: int = 200, k0: int = 0):
    """One loop of a 100 Hz bag from BASE (receive time = sim time = the stamps)."""
    for k in range(k0, n):
        t = BASE + k * 10 * MS
        core.on_message(imu(t), t)


@pytest.mark.parametrize("samples_before_clock", [0, 1, 5])
def test_a_loop_whose_stamps_jump_before_the_clock_resets_once(samples_before_clock):
    """The new loop's first samples come before /clock's jump back: the stamps' jump back
    restarts the simulation, the clock's (same loop) does not restart it again."""
    core = make_core()
    loop(core)
    loop(core, samples_before_clock)                  # stamps back 2 s: reset jump_back
    said = core.take_notices()
    done = core.on_clock_jump(True, -2 * 10**9)
    loop(core, 200, samples_before_clock)
    snap = core.snapshot()
    if samples_before_clock:
        assert done == "same_loop" and snap["resets_by_reason"] == {"jump_back": 1}
        assert len(said) == 1 and "simulation restarted" in said[0] and "jumped back" in said[0]
    else:
        assert done == "reset" and snap["resets_by_reason"] == {"clock_jump_back": 1}
    assert snap["resets"] == 1 and snap["clock_jumps"]["back"] == 1


def test_a_clock_jump_long_after_a_stamp_reset_is_its_own_reset():
    core = make_core()
    loop(core)
    loop(core)                                        # stamps jump back: reset
    core.take_notices()
    assert core.on_clock_jump(True, -5 * 10**9) == "reset"   # 2 s of stamps later (> max_gap 1 s)
    assert core.snapshot()["resets_by_reason"] == {"jump_back": 1, "clock_jump_back": 1}


def test_looped_with_clock_first_then_stamps_resets_once_per_loop():
    core = make_core()
    for _ in range(3):
        loop(core)
        core.on_clock_jump(True, -2 * 10**9)
    assert core.snapshot()["resets_by_reason"] == {"clock_jump_back": 3}


def _published(core, t_ns):
    """Every number the core publishes for one sample at t_ns (receive time = stamp), or None."""
    out = core.on_message(imu(t_ns), t_ns)
    return [[*m.position] if topic == "gimbal/joint_states" else str(m) for topic, m in out] or None


@pytest.mark.parametrize("queued", [1, 30])
def test_a_clock_jump_that_overtakes_queued_samples_restarts_at_the_new_loop_once(queued):
    """A node behind a looped bag: /clock jumps back to the loop's start while the old loop's last
    ``queued`` samples are still in its input queue. They are integrated in their run (as an
    uninterrupted core does), and the new loop's first sample is the one restart (the stamps'):
    its outputs are a fresh core's. Before, the clock's reset started a run of the old loop's
    tail (outputs of a fresh state stamped at the old loop's end), and the stamps restarted again."""
    core, straight, fresh = make_core(output_rate=0.0), make_core(output_rate=0.0), make_core(output_rate=0.0)
    stamps = [BASE + k * 10 * MS for k in range(200)]
    for t in stamps[:-queued]:
        core.on_message(imu(t), t)
        straight.on_message(imu(t), t)
    assert core.on_clock_jump(True, -2 * 10**9, now_ns=BASE) == "deferred"
    for t in stamps[-queued:]:                              # the old loop's tail, after the clock's jump
        assert _published(core, t) == _published(straight, t)
    for t in stamps[:50]:                                   # the new loop
        assert _published(core, t) == _published(fresh, t)
    snap = core.snapshot()
    assert snap["resets_by_reason"] == {"jump_back": 1} and snap["clock_jumps"] == {"back": 1, "back_same_loop": 1}


def test_a_deferred_clock_reset_without_a_stamp_jump_restarts_at_the_new_times_first_sample():
    """The clock goes back 0.5 s, the stamps only 0.45 s (less than reset_on_jump_back, which the gate
    would drop as backward): the clock's reset comes at that sample, which starts a fresh run."""
    core, fresh = make_core(output_rate=0.0, gate={"max_gap": 0.1}), make_core(output_rate=0.0, gate={"max_gap": 0.1})
    for k in range(200):
        core.on_message(imu(BASE + k * 10 * MS), BASE + k * 10 * MS)
    assert core.on_clock_jump(True, -5 * 10**8, now_ns=BASE + 15 * 10**8) == "deferred"
    core.on_message(imu(BASE + 1995 * MS), BASE + 1995 * MS)     # still the old run's (after 1.5 s + 0.1 s)
    assert core.snapshot()["resets"] == 0
    for k in range(20):
        t = BASE + 1545 * MS + k * 10 * MS
        assert _published(core, t) == _published(fresh, t)
    assert core.snapshot()["resets_by_reason"] == {"clock_jump_back": 1}
    assert "restarted at the first sample of the new time" in core.take_notices()[-1]


def test_input_frames_are_counted_by_name():
    core = make_core(sensor_mountings=["imu_link=0.0,0.0,1.5707963267948966"])
    frames = ["base_link"] * 5 + ["camera_link"] * 3 + ["imu_link"] * 4
    for k, f in enumerate(frames):
        core.on_message(imu(BASE + k * 10 * MS, f), BASE + k * 10 * MS)
    snap = core.snapshot()
    assert snap["input_frames"] == {"base_link": 5, "camera_link": 3, "imu_link": 4}
    assert snap["frames_taken_as_base_link"] == "camera_link"
    notes = [n for n in core.take_notices() if "camera_link" in n]
    assert len(notes) == 1
    for k in range(MAX_FRAMES + 10):                    # many names: the first ones, then 'other'
        t = BASE + (100 + k) * 10 * MS
        core.on_message(imu(t, f"f{k}"), t)
    counted = core.snapshot()["input_frames"]
    assert len(counted) == MAX_FRAMES + 1 and sum(counted.values()) == 12 + MAX_FRAMES + 10


def test_samples_dropped_for_their_values_are_no_stamp_gap():
    """A sample the gate drops (over max_rate) was received: between two taken samples its
    stamp is no loss. taken + dropped + lost = sent, with some samples lost for real."""
    core = make_core(**{"gate.max_rate": 1.0})
    rng = np.random.default_rng(4)
    sent = 3000
    for k in range(sent):
        if k % 7 == 3:
            continue                                           # lost
        t = BASE + k * MS
        m = imu(t)
        m.angular_velocity.z = 2.0 if rng.random() < 0.4 else 0.05     # 40 % over max_rate
        core.on_message(m, t)
    snap = core.snapshot()
    assert snap["dropped_by_reason"]["over_rate"] > 800
    assert snap["accepted"] + snap["dropped"] + snap["input_lost"] == sent - 1   # the last one (k = 2999) is lost
