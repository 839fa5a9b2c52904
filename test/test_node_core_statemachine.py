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

"""A state-machine property test of the ROS-free node core (:class:`gyro_platform.ros.core.NodeCore`).

Hypothesis drives one core, as the rclpy node and the DDS adapter do (one message per call with
its receive time), through random interleavings of Imu messages — good ones, late ones (a stamp
a little back), repeated stamps, stamps jumped forward past ``gate.max_gap`` or back past
``gate.reset_on_jump_back``, NaN rates, rates over the limit, zero stamps, a frame without
mounting, a message of the wrong type — with ``~/reset``, clock jumps, live parameter changes
(accepted and refused) and output-rate changes between them. After every step:

* every published number is finite;
* output stamps increase strictly between resets;
* every input is counted exactly once: ``messages = accepted + dropped``, every drop under a
  reason, every input one simulator outcome (pushed, reset, restarted, rejected, dropped),
  ``accepted = pushed + reset + restarted``; no internal error; the input-loss count (samples
  missing from the stamps, never received) is its parts' sum;
* a reset is a fresh start: from each reset on (``~/reset``, a clock jump back, a gap or a jump
  back in the stamps) a new core with the same configuration, fed the same messages and
  parameter changes, publishes exactly the same messages.

Example counts are modest (CI is slow): well under a minute. What the machine found is pinned
by plain tests below.
"""
from __future__ import annotations

import itertools
import math

from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from hypothesis.stateful import initialize, invariant, rule, RuleBasedStateMachine
from test_node_core import _published, BASE, imu, MS, STABILISED_BIAS

from gyro_platform.messages import MessageTypes
from gyro_platform.ros.config import NodeConfig
from gyro_platform.ros.core import NodeCore

TYPES = MessageTypes.rosbags()
S = 10**9
OUTCOMES = ("pushed", "reset", "restarted", "rejected", "dropped")
RATES = st.tuples(*[st.floats(-0.5, 0.5, allow_nan=False)] * 3)
LATENCY = st.one_of(st.none(), st.integers(0, 5 * MS))        # receive time = stamp + latency, or unknown
#: live parameter changes, accepted and refused (a bad value, a read-only parameter, an unknown name)
CHANGES = [
    {"gate.max_gap": 0.5}, {"gate.max_gap": 2.0}, {"gate.reset_on_jump_back": 0.2}, {"gate.reset_on_jump_back": 1.0},
    {"gate.max_rate": 1.0}, {"gate.max_rate": 35.0}, {"gate.on_gap": "integrate"}, {"gate.on_gap": "reset"},
    {"unknown_frame": "identity"}, {"unknown_frame": "reject"},
    {"effects": ["rotor_gyroscopic", "coriolis", "servo"]}, {"effects": ["defaults", "bias_torque"]},
    {"physics.servo_kp": 800.0}, {"physics.servo_kp": 1500.0}, {"sensor_mountings": ["imu_link=0.0,0.0,0.3"]},
    {"gate.max_gap": math.inf}, {"gate.max_rate": -1.0}, {"mode": "carried"}, {"no_such": 1.0},
]
OUTPUT_RATES = [0.0, 5.0, 10.0, 100.0, 1000.0, -1.0, 2.0e4, math.nan]


def new_core(config: NodeConfig) -> NodeCore:
    return NodeCore(config, TYPES, clock_ns=itertools.count(0, 25_000).__next__)


def numbers(published: dict[str, list[float]]) -> list[float]:
    return [x for values in published.values() for x in values]


class NodeCoreMachine(RuleBasedStateMachine):
    """One core, and from each reset on its twin: a fresh core fed the same since."""

    @initialize(output_rate=st.sampled_from([0.0, 10.0, 50.0]))
    def start(self, output_rate):
        self.core = new_core(NodeConfig.from_ros_params(dict(output_rate=output_rate, unknown_frame="reject",
                                                             **STABILISED_BIAS)))
        self.twin: NodeCore | None = None
        self.last = BASE                 # stamp of the last in-order message sent
        self.sent = 0
        self.stamps: list[int] = []      # output stamps since the last reset

    # ---- messages ----------------------------------------------------------------------
    def send(self, msg, stamp: int, latency: int | None) -> None:
        core = self.core
        before = sum(core.resets.values())
        rx = None if latency is None else stamp + latency
        out = _published(core.on_message(msg, rx))
        self.sent += 1
        if sum(core.resets.values()) != before:          # a gap, a jump back, a failed integration
            self.fresh_twin()
        if self.twin is not None:
            assert _published(self.twin.on_message(msg, rx)) == out, "a reset is not a fresh start"
        assert all(math.isfinite(x) for x in numbers(out)), out
        if out:
            t = {v[-1] for v in out.values()}           # every output of an instant carries its stamp
            assert len(t) == 1, out
            t = t.pop()
            assert not self.stamps or t > self.stamps[-1], (self.stamps[-3:], t)
            self.stamps.append(t)

    def fresh_twin(self) -> None:
        self.twin = new_core(self.core.config)
        self.stamps = []

    @rule(dt_ms=st.integers(1, 40), w=RATES, latency=LATENCY)
    def good(self, dt_ms, w, latency):
        self.last += dt_ms * MS
        self.send(imu(self.last, w), self.last, latency)

    @rule(back_ms=st.integers(1, 900), latency=LATENCY)
    def late(self, back_ms, latency):
        t = self.last - back_ms * MS
        self.send(imu(t, (0.0, 0.0, 0.01)), t, latency)

    @rule(latency=LATENCY)
    def repeated_stamp(self, latency):
        self.send(imu(self.last, (0.0, 0.01, 0.0)), self.last, latency)

    @rule(s=st.floats(1.5, 30.0), latency=LATENCY)
    def jumped_forward(self, s, latency):
        self.last += int(s * S)
        self.send(imu(self.last, (0.01, 0.0, 0.0)), self.last, latency)

    @rule(s=st.floats(1.5, 60.0), latency=LATENCY)
    def jumped_back(self, s, latency):
        self.last -= int(s * S)
        self.send(imu(self.last, (0.0, 0.0, -0.01)), self.last, latency)

    @rule(which=st.integers(0, 2), bad=st.sampled_from([math.nan, math.inf, 100.0]), latency=LATENCY)
    def bad_rate(self, which, bad, latency):
        w = [0.0, 0.0, 0.0]
        w[which] = bad
        self.send(imu(self.last + MS, tuple(w)), self.last + MS, latency)

    @rule(latency=LATENCY)
    def wrong_frame(self, latency):
        self.send(imu(self.last + MS, (0.0, 0.0, 0.02), frame="nowhere"), self.last + MS, latency)

    @rule(latency=LATENCY)
    def zero_stamp(self, latency):
        self.send(imu(0, (0.0, 0.0, 0.02)), self.last + MS, latency)

    @rule()
    def wrong_type(self):
        self.send("not a message", self.last + MS, 0)

    # ---- control -------------------------------------------------------------------------
    @rule()
    def reset(self):
        self.core.reset("service")
        self.fresh_twin()

    @rule(backward=st.booleans())
    def clock_jump(self, backward):
        done = self.core.on_clock_jump(backward, -60 * S if backward else 5 * S)
        if done == "reset":
            self.fresh_twin()
        elif self.twin is not None and done != "same_loop":
            # "same_loop": the jump belongs to the stamps' jump-back reset the twin started from
            # (a looped bag with /clock): it is no input of the twin's
            self.twin.on_clock_jump(backward, -60 * S if backward else 5 * S)

    def change(self, changes) -> None:
        ok, why = self.core.set_parameters(changes)
        assert ok or (why and "\n" not in why), why
        if self.twin is not None:
            assert self.twin.set_parameters(changes) == (ok, why)
            assert self.twin.config.values == self.core.config.values

    @rule(changes=st.sampled_from(CHANGES))
    def parameter_change(self, changes):
        self.change(changes)

    @rule(rate=st.sampled_from(OUTPUT_RATES))
    def output_rate_change(self, rate):
        before = self.core.config["output_rate"]
        self.change({"output_rate": rate})
        assert self.core.config["output_rate"] == (rate if 0.0 <= rate <= 1e4 else before)

    # ---- invariants ----------------------------------------------------------------------
    @invariant()
    def every_input_counted_once(self):
        for core, sent in ((self.core, self.sent), (self.twin, None)):
            if core is None:
                continue
            snap = core.snapshot()
            assert snap["internal_errors"] == 0, snap["last_error"]
            n = snap["messages"]
            assert sent is None or n == sent
            assert snap["accepted"] + snap["dropped"] == n, snap
            assert sum(snap["dropped_by_reason"].values()) == snap["dropped"], snap["dropped_by_reason"]
            o = core.outcomes
            assert sum(o.get(k, 0) for k in OUTCOMES) == n, dict(o)
            assert snap["accepted"] == o.get("pushed", 0) + o.get("reset", 0) + o.get("restarted", 0), dict(o)
            tr, gaps = snap["input_lost_transport"], snap["input_lost_stamp_gaps"]
            assert 0 <= max(tr, gaps) <= snap["input_lost"] <= tr + gaps     # each sample counted once
            assert snap["outputs_published"] <= snap["accepted"]

    @invariant()
    def diagnostics_never_fail(self):
        arr = self.core.diagnostics(self.last + S)
        assert len(arr.status) >= 3
        for s in arr.status:
            for kv in s.values:
                assert kv.value not in ("nan", "inf", "-inf"), (s.name, kv.key)


NodeCoreMachine.TestCase.settings = settings(max_examples=80, stateful_step_count=50, deadline=None,
                                             suppress_health_check=[HealthCheck.too_slow,
                                                                    HealthCheck.filter_too_much])
test_node_core_state_machine = NodeCoreMachine.TestCase


def test_a_reset_after_a_start_on_receive_times_chooses_the_time_source_again():
    """Found by the machine: the first message had stamp 0, so ``gate.time_source: auto`` timed
    the stream by receive times; a jump back then reset the core, which kept timing by receive
    times while a fresh core (and ``~/reset``) chooses header stamps for a stamped message: the
    outputs after the reset were stamped 1 ns apart from a fresh start's."""
    config = NodeConfig.from_ros_params(dict(output_rate=0.0, **STABILISED_BIAS))
    core = new_core(config)
    assert core.on_message(imu(0, (0.0, 0.0, 0.02)), BASE + MS)             # timed by its receive time
    assert core.gate.time_source == "receive"
    t = BASE - 2 * S
    got = _published(core.on_message(imu(t, (0.0, 0.0, -0.01)), t + 1))   # received 1 ns after its stamp
    assert core.snapshot()["resets_by_reason"] == {"jump_back": 1}
    want = _published(new_core(config).on_message(imu(t, (0.0, 0.0, -0.01)), t + 1))
    assert got == want and {v[-1] for v in got.values()} == {t}
    assert core.gate.time_source == "header"
