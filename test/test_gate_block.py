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

"""Blocks through the input gate: ``Mounting.rotate_block`` and ``TimeGate.offer_block`` decide a
whole RateBlock exactly as ``reading_from_msg`` and one ``TimeGate.offer`` per message do.

The reference is the per-message path (independently built ``Reading``/``Rejected`` per row, or
rosbags messages through ``reading_from_msg``); hypothesis draws stamp sequences with zero,
repeated, backward, jumping-back and gapped stamps, NaN/Inf and over-rate rates, missing
specific force and rejected rows, fed in chunks of random sizes.
"""
from __future__ import annotations

import math

from hypothesis import example, given, HealthCheck, settings
from hypothesis import strategies as st
import numpy as np
import pytest

from gyro_platform.messages import jazzy_typestore, Mounting, Reading, reading_from_msg, Rejected
from gyro_platform.messages.blocks import RateBlock, REJECT_REASONS
from gyro_platform.pipeline.gate import TimeGate
from gyro_platform.pipeline.gate_rules import ACCEPT, Action, DROP, GateConfig, plain_decision, REASONS, RESET

NS = 1_000_000_000
T0 = 1_700_000_000 * NS
T = jazzy_typestore().types
CODE = {Action.ACCEPT: ACCEPT, Action.DROP: DROP, Action.RESET: RESET}


# ---- drawing rows ---------------------------------------------------------------------------
STEPS = st.sampled_from([NS // 1000] * 12 + [0, -NS // 2000, -3 * NS, 2 * NS, NS, NS + 1, 7 * NS // 1000])
VALUES = st.sampled_from([0.1] * 10 + [-0.3, 0.0, math.nan, math.inf, -math.inf, 40.0, 1e200])


@st.composite
def rows(draw, n_max=60):
    """(stamp_ns, has_header, omega, force, has_force, reject, identity, receive_ns) per row."""
    n = draw(st.integers(1, n_max))
    stamp, rx = T0, T0 + 250_000
    out = []
    for _ in range(n):
        stamp += draw(STEPS)
        rx += draw(st.sampled_from([NS // 1000] * 6 + [0, -NS // 1000, 3 * NS]))
        kind = draw(st.sampled_from(["imu"] * 8 + ["zero", "twist", "reject", "noforce"]))
        w = [draw(VALUES) if draw(st.integers(0, 5)) == 0 else 0.1 * k for k in (1, 2, 3)]
        f = [draw(VALUES) if draw(st.integers(0, 8)) == 0 else v for v in (0.0, 0.0, 9.81)]
        out.append({"stamp": 0 if kind in ("zero", "twist") else stamp, "has_header": kind != "twist",
                    "omega": w, "force": f if kind not in ("noforce", "twist") else [0.0, 0.0, 0.0],
                    "has_force": kind not in ("noforce", "twist"),
                    "reject": draw(st.integers(1, 3)) if kind == "reject" else 0,
                    "identity": draw(st.booleans()), "rx": rx})
    return out


def block_of(rs: list[dict]) -> RateBlock:
    n = len(rs)
    rb = RateBlock(np.array([r["stamp"] for r in rs], np.int64), np.array([r["has_header"] for r in rs]),
                   ["base_link"] * n, np.array([r["omega"] for r in rs], float).reshape(n, 3),
                   np.array([r["force"] for r in rs], float).reshape(n, 3), np.array([r["has_force"] for r in rs]),
                   np.array([r["reject"] for r in rs], np.int8), {}, np.array([r["identity"] for r in rs]))
    for i, r in enumerate(rs):
        if r["reject"]:
            rb.detail[i] = f"row {i} rejected"
    return rb


def reading_of(r: dict, i: int) -> Reading | Rejected:
    """What reading_from_msg would have made of the row (built without the block code)."""
    stamp = r["stamp"] if r["has_header"] else None
    if r["reject"]:
        return Rejected(REJECT_REASONS[r["reject"] - 1], f"row {i} rejected", stamp, "base_link")
    return Reading(tuple(r["omega"]), tuple(r["force"]) if r["has_force"] else None, stamp, "base_link",
                   r["identity"])


def state(g: TimeGate) -> dict:
    last = g.last
    snap = g.snapshot()
    snap["last"] = None if last is None else (last.action, last.reason, last.stamp_ns, last.source, last.detail,
                                              None if last.sample is None else (last.sample.t, *last.sample.omega))
    snap["last_drop"] = None if g.last_drop is None else (g.last_drop.reason, g.last_drop.stamp_ns)
    snap["counts"] = {k: v for k, v in g.counts.items() if v}
    snap["rx"] = (g._s.rx_last, g._s.rx_dt_ema, g._s.dt_ema)
    return snap


CONFIGS = st.builds(GateConfig, max_gap=st.sampled_from([1.0, 0.5, 2.5, 1e7]),   # 1e7 s: > 2**53 ns
                    on_gap=st.sampled_from(["reset", "integrate"]),
                    reset_on_jump_back=st.sampled_from([1.0, 0.0, 5.0]),
                    time_source=st.sampled_from(["auto", "auto", "header", "receive"]),
                    require_specific_force=st.booleans(), rebase_on_reset=st.booleans())


def _row(stamp: int, rx: int) -> dict:
    return {"stamp": stamp, "has_header": True, "omega": [0.1, 0.2, 0.3], "force": [0.0, 0.0, 9.81],
            "has_force": True, "reject": 0, "identity": False, "rx": rx}


#: found by hypothesis under ROS's python: a zero stamp locks the receive time; a receive-time gap resets
#: and (rebase_on_reset, auto) the reset chooses header stamps again; the next row repeats that stamp
REBASED = [_row(0, T0), _row(T0 + NS // 1000, T0 + NS // 1000), _row(T0 + 3 * NS, T0 + 3 * NS),
           _row(T0 + 3 * NS, T0 + 3 * NS + NS // 1000), _row(T0 + 3 * NS + NS // 1000, T0 + 3 * NS + NS // 500)]


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(rs=rows(), cfg=CONFIGS, cuts=st.lists(st.integers(0, 60), max_size=4), with_rx=st.booleans())
@example(rs=REBASED, cfg=GateConfig(rebase_on_reset=True), cuts=[], with_rx=True)
def test_offer_block_equals_one_offer_per_row(rs, cfg, cuts, with_rx):
    ref, blk = TimeGate(cfg), TimeGate(cfg)
    decisions = [ref.offer(reading_of(r, i), r["rx"] if with_rx else None) for i, r in enumerate(rs)]
    bounds = sorted({0, len(rs), *(c for c in cuts if c < len(rs))})
    parts = []
    for a, b in zip(bounds, bounds[1:]):                  # chunks of random sizes, one gate across them
        sub = rs[a:b]
        rb = block_of(sub)
        for i in range(len(sub)):                         # details keyed by the row in its chunk
            if sub[i]["reject"]:
                rb.detail[i] = f"row {a + i} rejected"
        rx = np.array([r["rx"] for r in sub], np.int64) if with_rx else None
        parts.append(blk.offer_block(rb, rx))
    action = np.concatenate([p.action for p in parts])
    reason = np.concatenate([p.reason for p in parts])
    t = np.concatenate([p.t for p in parts])
    stamp = np.concatenate([p.stamp_ns for p in parts])
    assert action.tolist() == [CODE[d.action] for d in decisions]
    assert [REASONS[k] for k in reason] == [d.reason for d in decisions]
    exp_t = [d.sample.t if d.sample is not None else math.nan for d in decisions]
    np.testing.assert_array_equal(t, exp_t)               # bit-identical (NaN where dropped)
    assert stamp.tolist() == [-1 if d.stamp_ns is None else d.stamp_ns for d in decisions]
    assert state(blk) == state(ref)


def decision_key(d):
    """A decision as comparable values (the sample's arrays as tuples)."""
    smp = d.sample
    return (d.action, d.reason, d.stamp_ns, d.source, d.detail,
            None if smp is None else (smp.t, tuple(smp.omega),
                                      None if smp.specific_force is None else tuple(smp.specific_force)))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(rs=rows(), cfg=CONFIGS, with_rx=st.booleans(), refuse=st.lists(st.booleans(), min_size=60, max_size=60))
def test_offer_plain_takes_exactly_the_rows_offer_accepts_as_ok_and_leaves_the_same_gate(rs, cfg, with_rx, refuse):
    """The node's per-message lane: ``offer_plain`` first, ``offer`` when it declines. Every
    decision (made on demand from the plain tuple), counter, note, rate estimate and undo (the
    simulator refusing a sample: ``refuse``, drawn at random) equals ``offer`` alone; the lane
    takes only rows that ``offer`` accepts as ``ok``, and declines with nothing changed."""
    ref, lane = TimeGate(cfg), TimeGate(cfg)
    taken = plain = 0
    for i, r in enumerate(rs):
        reading, rx = reading_of(r, i), (r["rx"] if with_rx else None)
        gaps = ref.notes["gap_integrated"]
        d_ref = ref.offer(reading, rx)
        plain += d_ref.reason == "ok" and ref.notes["gap_integrated"] == gaps
        before = state(lane)
        p = lane.offer_plain(reading, rx)
        if p is None:
            assert state(lane) == before                  # declined: nothing changed
            d = lane.offer(reading, rx)
        else:
            taken += 1
            assert lane.last_plain is p
            d = lane.last
            assert d.reason == "ok" and decision_key(d) == decision_key(plain_decision(p))
        assert decision_key(d) == decision_key(d_ref)
        if refuse[i]:
            ref.refuse("drawn")
            lane.refuse("drawn")
        assert state(lane) == state(ref)
        assert lane._undo == ref._undo
    assert taken == plain                                 # every ok row within max_gap, no other


def test_plain_1khz_run_is_accepted_whole_with_exact_times_and_rate_estimates():
    n = 5000
    stamps = T0 + np.arange(n, dtype=np.int64) * 1_000_000
    rb = block_of(
        [
            {
                "stamp": int(s),
                "has_header": True,
                "omega": [0.1, 0.2, 0.3],
                "force": [0, 0, 9.81],
                "has_force": True,
                "reject": 0,
                "identity": False,
                "rx": 0,
            }
            for s in stamps
        ]
    )
    g = TimeGate()
    gb = g.offer_block(rb, stamps + 200_000)
    assert (gb.action == ACCEPT).all() and gb.reason_name(0) == "start" and gb.reason_name(n - 1) == "ok"
    assert gb.t[-1] == (n - 1) * 1e-3 and gb.stamp_ns.tolist() == stamps.tolist()
    snap = g.snapshot()
    assert snap["accepted"] == n and snap["input_rate_hz"] == pytest.approx(1000.0)
    assert snap["accepted_rate_hz"] == pytest.approx(1000.0)


def test_refuse_rolls_the_gate_back_so_the_next_sample_is_judged_as_if_the_refused_never_came():
    g = TimeGate()
    g.offer(Reading((0.1, 0, 0), (0, 0, 9.8), T0, "base_link"), T0)
    d = g.offer(Reading((0.1, 0, 0), None, T0 + 1_000_000, "base_link"), T0 + 1_000_000)
    assert d.accepted
    g.refuse("simulator: needs the specific force")
    assert g.last.reason == "refused" and g.last_stamp_ns == T0
    d = g.offer(Reading((0.1, 0, 0), (0, 0, 9.8), T0 + 1_000_000, "base_link"), T0 + 1_000_000)
    assert (d.action, d.reason) == (Action.ACCEPT, "ok")     # not repeated_stamp
    snap = g.snapshot()
    assert snap["accepted"] == 2 and snap["dropped_by_reason"] == {"refused": 1}
    assert snap["accepted_rate_hz"] == pytest.approx(1000.0)


def test_missing_specific_force_is_dropped_before_it_touches_the_time_base():
    g = TimeGate(GateConfig(require_specific_force=True))
    g.offer(Reading((0.1, 0, 0), (0, 0, 9.8), T0, "base_link"), T0)
    d = g.offer(Reading((0.1, 0, 0), None, T0 + 1_000_000, "base_link"), T0 + 1_000_000)
    assert (d.action, d.reason) == (Action.DROP, "no_specific_force") and g.last_stamp_ns == T0


# ---- rotate_block against reading_from_msg ------------------------------------------------------
def _imu(stamp, w, a, frame, cov_w=0.0, cov_a=0.0):
    cw, ca = np.zeros(9), np.zeros(9)
    cw[0], ca[0] = cov_w, cov_a
    v3 = T["geometry_msgs/msg/Vector3"]
    sec, nsec = divmod(stamp, NS)
    return T["sensor_msgs/msg/Imu"](
        header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec), frame_id=frame),
        orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0), orientation_covariance=np.zeros(9),
        angular_velocity=v3(x=w[0], y=w[1], z=w[2]), angular_velocity_covariance=cw,
        linear_acceleration=v3(x=a[0], y=a[1], z=a[2]), linear_acceleration_covariance=ca)


@pytest.mark.parametrize("policy", ["identity", "reject"])
def test_rotate_block_equals_reading_from_msg_row_by_row(policy):
    mount = Mounting({"imu_link": (0.3, -1.1, 2.0), "cam_imu": (0.0, 0.0, math.pi / 2)}, unknown_frame=policy)
    rng = np.random.default_rng(5)
    frames = ["imu_link", "base_link", "cam_imu", "unknown_link"]
    msgs, rows = [], []
    for i in range(200):
        frame = frames[i % 4] if i < 160 else "imu_link"       # mixed frames, then one frame
        w, a = rng.normal(size=3), rng.normal(size=3) * 5
        cov_w = -1.0 if i % 17 == 0 else 0.0
        cov_a = -1.0 if i % 7 == 0 else 0.0
        msgs.append(_imu(T0 + i * 1_000_000, w, a, frame, cov_w, cov_a))
        rows.append((frame, w, a, cov_w, cov_a))
    rb = RateBlock.zeros(len(rows))
    for i, (frame, w, a, cov_w, cov_a) in enumerate(rows):     # a decoder's block, sensor frame
        rb.stamp_ns[i], rb.has_header[i], rb.frame_id[i] = T0 + i * 1_000_000, True, frame
        rb.omega[i], rb.force[i], rb.has_force[i] = w, a if cov_a != -1 else 0.0, cov_a != -1
        if cov_w == -1:
            rb.set_reject(i, "no_rate", "angular_velocity_covariance[0] = -1 (rate not reported)")
    before = rb.omega.copy()
    out = mount.rotate_block(rb)
    np.testing.assert_array_equal(rb.omega, before)              # the input block is not changed
    for i, m in enumerate(msgs):
        r = reading_from_msg(m, mount)
        if isinstance(r, Rejected):
            assert out.reject_reason(i) == r.reason and out.detail[i] == r.detail
            continue
        assert out.reject[i] == 0 and bool(out.identity[i]) == r.identity_assumed
        assert out.omega[i].tolist() == list(r.omega)            # bit-identical
        assert bool(out.has_force[i]) == (r.specific_force is not None)
        if r.specific_force is not None:
            assert out.force[i].tolist() == list(r.specific_force)
    # and the rotation is the mounting: yaw 90° maps sensor x to base y
    k = frames.index("cam_imu")
    np.testing.assert_allclose(out.omega[k], [-rows[k][1][1], rows[k][1][0], rows[k][1][2]], atol=1e-15)


def test_rotate_block_gives_twist_rows_the_vehicle_frame():
    rb = RateBlock.zeros(2)
    rb.omega[:] = [[0.1, 0.2, 0.3], [0.0, 0.0, 1.0]]
    out = Mounting(unknown_frame="reject").rotate_block(rb)        # no header: Twist, base_link
    assert out.frame_id == ["base_link", "base_link"] and (out.reject == 0).all() and not out.identity.any()


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(rs=rows(), cfg=CONFIGS, snap_rows=st.lists(st.integers(0, 60), max_size=6), with_rx=st.booleans())
def test_offer_block_snapshots_are_the_gate_after_their_rows(rs, cfg, snap_rows, with_rx):
    """``offer_block(..., snap_rows, snapshots)``: the snapshot after each asked row is the one
    of a gate that was offered the rows up to it one by one; the decisions and the final state
    are those of a block without snapshots."""
    ref, blk, plain = TimeGate(cfg), TimeGate(cfg), TimeGate(cfg)
    want = {}
    asked = {r for r in snap_rows if r < len(rs)}
    for i, r in enumerate(rs):
        ref.offer(reading_of(r, i), r["rx"] if with_rx else None)
        if i in asked:
            want[i] = ref.snapshot()
    rb = block_of(rs)
    rx = np.array([r["rx"] for r in rs], np.int64) if with_rx else None
    got: dict[int, dict] = {}
    gb = blk.offer_block(rb, rx, snap_rows, got)
    gp = plain.offer_block(block_of(rs), rx)
    assert got == want
    assert gb.action.tolist() == gp.action.tolist() and gb.reason.tolist() == gp.reason.tolist()
    np.testing.assert_array_equal(gb.t, gp.t)
    assert state(blk) == state(ref) == state(plain)
