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

"""The input gate: every bad-input case gives its documented decision and counter, never raises."""
from __future__ import annotations

import math

import numpy as np
import pytest

from gyro_platform.messages import Reading, Rejected
from gyro_platform.pipeline import gate as timebase
from gyro_platform.pipeline.gate import TimeGate
from gyro_platform.pipeline.gate_rules import ACCEPT_REASONS, Action, DROP_REASONS, GateConfig, NOTES, RESET_REASONS

S = 1_000_000_000
T0 = 1_700_000_000 * S


def rd(stamp_ns, w=(0.1, 0.0, 0.0), f=(0.0, 0.0, 9.8), identity=False):
    return Reading(np.asarray(w, float), None if f is None else np.asarray(f, float), stamp_ns, "base_link",
                   identity)


def test_header_time_base_and_relative_sample_time():
    g = TimeGate()
    d = g.offer(rd(T0 + 5), receive_ns=T0 + 30_000_000)
    assert (d.action, d.reason, d.source, d.stamp_ns) == (Action.ACCEPT, "start", "header", T0 + 5)
    assert d.sample.t == 0.0 and g.origin_ns == T0 + 5
    d = g.offer(rd(T0 + 5 + S // 30), receive_ns=T0 + 60_000_000)
    assert (d.action, d.reason) == (Action.ACCEPT, "ok")
    assert d.sample.t == 0.033333333                                  # exact ns difference, not epoch floats
    np.testing.assert_array_equal(d.sample.omega, [0.1, 0.0, 0.0])
    np.testing.assert_array_equal(d.sample.specific_force, [0.0, 0.0, 9.8])


def test_zero_stamps_use_receive_time_when_all_zero():
    """The cabrillo recording: every header stamp 0 → the receive time is the time base."""
    g = TimeGate()
    ds = [g.offer(rd(0), receive_ns=T0 + i * S // 10) for i in range(5)]
    assert [d.action for d in ds] == [Action.ACCEPT] * 5
    assert all(d.source == "receive" for d in ds)
    assert [d.sample.t for d in ds] == pytest.approx([0.0, 0.1, 0.2, 0.3, 0.4])
    snap = g.snapshot()
    assert snap["notes"]["receive_time"] == 5 and snap["time_source"] == "receive"
    assert snap["input_rate_hz"] == pytest.approx(10.0) == snap["accepted_rate_hz"]
    # once locked on the receive clock, later valid header stamps do not switch clocks
    d = g.offer(rd(T0 + 100 * S), receive_ns=T0 + 5 * S // 10)
    assert d.action is Action.ACCEPT and d.stamp_ns == T0 + 5 * S // 10


def test_zero_stamp_in_header_mode_is_dropped():
    g = TimeGate()
    g.offer(rd(T0), receive_ns=T0)
    d = g.offer(rd(0), receive_ns=T0 + S)
    assert (d.action, d.reason) == (Action.DROP, "zero_stamp") and d.sample is None
    d = g.offer(rd(None), receive_ns=T0 + S)                              # Twist (no header) in header mode
    assert (d.action, d.reason) == (Action.DROP, "zero_stamp")
    assert g.snapshot()["dropped_by_reason"] == {"zero_stamp": 2}


def test_receive_mode_without_receive_time():
    g = TimeGate(GateConfig(time_source="receive"))
    d = g.offer(rd(T0))
    assert (d.action, d.reason) == (Action.DROP, "no_time")
    d = g.offer(rd(T0), receive_ns=T0 + 7)
    assert d.stamp_ns == T0 + 7 and d.source == "receive"


def test_repeated_and_small_backward_stamps_are_dropped_without_moving_time():
    g = TimeGate()
    g.offer(rd(T0))
    g.offer(rd(T0 + S // 10))
    d = g.offer(rd(T0 + S // 10))
    assert (d.action, d.reason) == (Action.DROP, "repeated_stamp")
    d = g.offer(rd(T0 + S // 20))                                         # 50 ms back: out of order
    assert (d.action, d.reason) == (Action.DROP, "backward_stamp")
    d = g.offer(rd(T0 + 2 * S // 10))
    assert (d.action, d.reason) == (Action.ACCEPT, "ok") and d.sample.t == pytest.approx(0.2)
    assert g.last_stamp_ns == T0 + 2 * S // 10


def test_large_backward_jump_resets_looped_bag():
    g = TimeGate(GateConfig(reset_on_jump_back=1.0))
    for i in range(20):
        g.offer(rd(T0 + i * S // 2))
    d = g.offer(rd(T0 + S // 100))                                        # the bag loops: 9.5 s back
    assert (d.action, d.reason) == (Action.RESET, "jump_back") and "9.49" in d.detail
    assert d.sample.t == pytest.approx(0.01)                              # same origin as before
    d = g.offer(rd(T0 + S // 100 + S // 10))
    assert (d.action, d.reason) == (Action.ACCEPT, "ok")
    snap = g.snapshot()
    assert snap["resets_by_reason"] == {"jump_back": 1} and snap["resets"] == 1


def test_gap_resets_by_default_or_integrates_when_configured():
    g = TimeGate(GateConfig(max_gap=0.5))
    g.offer(rd(T0))
    d = g.offer(rd(T0 + S // 2))                                          # exactly max_gap: fine
    assert d.reason == "ok"
    d = g.offer(rd(T0 + S // 2 + 2 * S))
    assert (d.action, d.reason) == (Action.RESET, "gap") and "2 s" in d.detail
    g = TimeGate(GateConfig(max_gap=0.5, on_gap="integrate"))
    g.offer(rd(T0))
    d = g.offer(rd(T0 + 3 * S))
    assert (d.action, d.reason) == (Action.ACCEPT, "ok") and d.sample.t == 3.0
    assert g.snapshot()["notes"]["gap_integrated"] == 1


@pytest.mark.parametrize("w,f", [((math.nan, 0, 0), (0, 0, 9.8)), ((0, math.inf, 0), None),
                                 ((0, 0, 0), (0, -math.inf, 9.8))])
def test_non_finite_values_are_dropped(w, f):
    g = TimeGate()
    d = g.offer(rd(T0, w, f))
    assert (d.action, d.reason, d.sample) == (Action.DROP, "non_finite", None)
    assert g.origin_ns is None                                            # a dropped sample sets no time


def test_over_rate_is_dropped():
    g = TimeGate(GateConfig(max_rate=35.0))
    d = g.offer(rd(T0, (30.0, 20.0, 0.0)))                                # |w| = 36.06 rad/s
    assert (d.action, d.reason) == (Action.DROP, "over_rate") and "36.05" in d.detail
    assert g.offer(rd(T0, (34.9, 0.0, 0.0))).action is Action.ACCEPT       # just inside the limit
    assert g.offer(rd(T0 + 1, (0.0, 0.0, -35.5))).reason == "over_rate"   # sign does not matter


@pytest.mark.parametrize("reason", ["no_rate", "unknown_frame", "bad_message"])
def test_rejections_from_the_message_layer_are_counted(reason):
    g = TimeGate()
    d = g.offer(Rejected(reason, "why", stamp_ns=T0, frame_id="imu_link"), receive_ns=T0)
    assert (d.action, d.reason, d.detail, d.stamp_ns) == (Action.DROP, reason, "why", T0)
    snap = g.snapshot()
    assert snap["dropped_by_reason"] == {reason: 1}
    assert (snap["last_action"], snap["last_reason"], snap["last_drop_reason"]) == ("drop", reason, reason)


def test_identity_frame_note():
    g = TimeGate()
    assert g.offer(rd(T0, identity=True)).action is Action.ACCEPT
    assert g.snapshot()["notes"] == {"identity_frame": 1}


def test_garbage_never_raises():
    g = TimeGate()
    for junk in (None, 3.0, "imu", Reading(np.zeros(2), None, T0, ""), Reading(np.zeros(3), np.zeros(4), T0, ""),
                 Reading(np.array(["a", "b", "c"]), None, T0, "")):
        d = g.offer(junk, receive_ns=T0)
        assert (d.action, d.reason) == (Action.DROP, "bad_message")
    assert g.snapshot()["dropped_by_reason"] == {"bad_message": 6}


def test_restart_forgets_time_base_but_keeps_counts():
    g = TimeGate()
    g.offer(rd(T0))
    g.offer(rd(T0))
    g.restart()
    assert g.origin_ns is None and g.time_source is None
    d = g.offer(rd(0), receive_ns=T0 + 5)                                 # relocks, on the receive clock now
    assert (d.reason, d.source, d.sample.t) == ("start", "receive", 0.0)
    assert g.snapshot()["dropped_by_reason"] == {"repeated_stamp": 1}


def test_config_validation():
    for bad in ({"max_gap": 0}, {"on_gap": "skip"}, {"reset_on_jump_back": -1}, {"max_rate": 0},
                {"time_source": "gps"}, {"rate_smoothing": 0}):
        with pytest.raises(ValueError):
            GateConfig(**bad)


def test_mixed_stream_counts_add_up_and_accepted_times_increase_between_resets():
    """A noisy 30 Hz stream with every defect; the counters account for every message."""
    rng = np.random.default_rng(3)
    g = TimeGate(GateConfig(max_gap=1.0, reset_on_jump_back=2.0))
    t = T0
    decisions = []
    for i in range(3000):
        t += S // 30 + int(rng.integers(-200_000, 200_000))
        kind = rng.integers(0, 20) if i not in (1000, 1500, 2000) else 99
        stamp, w, f = t, rng.normal(size=3), rng.normal(size=3)
        if kind == 0:
            w[1] = math.nan
        elif kind == 1:
            w *= 100.0
        elif kind == 2:
            stamp = t - S // 30                                            # repeated / backward
        elif i in (1000, 1500):
            t += 3 * S                                                     # gap
            stamp = t
        elif i == 2000:
            t -= 10 * S                                                    # the bag loops
            stamp = t
        elif kind == 5:
            decisions.append(g.offer(Rejected("no_rate", "cov -1", stamp), receive_ns=t + 25_000_000))
            continue
        decisions.append(g.offer(rd(stamp, w, f), receive_ns=t + 25_000_000))
    snap = g.snapshot()
    assert snap["received"] == 3000 == snap["accepted"] + snap["dropped"]
    assert sum(snap["dropped_by_reason"].values()) == snap["dropped"]
    assert set(g.counts) <= set(DROP_REASONS) | set(RESET_REASONS) | set(ACCEPT_REASONS)
    assert set(snap["notes"]) <= set(NOTES)
    for reason in ("non_finite", "over_rate", "no_rate", "backward_stamp"):
        assert snap["dropped_by_reason"].get(reason, 0) > 0, reason
    assert snap["resets_by_reason"].get("gap", 0) > 0 and snap["resets_by_reason"].get("jump_back", 0) > 0
    assert snap["input_rate_hz"] == pytest.approx(30.0, rel=0.01)         # arrivals, dropped ones too
    assert snap["accepted_rate_hz"] < 27.0                                # accepted ones only
    prev = None
    for d in decisions:
        if d.action is Action.RESET:
            prev = d.sample.t
        elif d.action is Action.ACCEPT:
            assert prev is None or d.sample.t > prev
            assert d.sample.is_finite() and np.linalg.norm(d.sample.omega) <= 35.0
            prev = d.sample.t


def test_module_doc_lists_every_reason():
    for reason in DROP_REASONS + RESET_REASONS + NOTES:
        assert f"`{reason}`" in timebase.__doc__ or f"``{reason}``" in timebase.__doc__, reason
