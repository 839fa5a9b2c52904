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

"""decode_rates: the vectorised CDR decoder equals rosbags' deserialisation + the REP-145 rules
of ``reading_from_msg`` message by message — on every shared recording, on generated Imu,
Twist and TwistStamped messages (any frame_id, big-endian, NaN/Inf, covariance -1 flags,
padding, truncated or garbage bytes, invalid stamps) and with a bag's own definitions."""
from __future__ import annotations

import math
from pathlib import Path

from hypothesis import given, settings
from hypothesis import strategies as st
import numpy as np
import pytest
from rosbags.typesys import get_types_from_msg, get_typestore, Stores

from gyro_platform import messages as m
from gyro_platform.bags.reader import InputBag
from gyro_platform.messages.blocks import concat_rows, RateBlock, RawRows, REJECT_REASONS
from gyro_platform.messages.decode import decode_rates, standard_layout

BAGS = Path(__file__).resolve().parents[2] / "shared" / "data" / "bags"
SHARED = sorted(p for p in BAGS.iterdir() if p.is_dir()) if BAGS.is_dir() else []
J = get_typestore(Stores.ROS2_JAZZY)
T = J.types
S = 1_000_000_000
IMU, TWS, TW = m.IMU, m.TWIST_STAMPED, m.TWIST


class CountingStore:
    """A typestore that counts the messages rosbags had to decode (the fallback path)."""

    def __init__(self, store):
        self.store, self.calls = store, 0

    def get_msgdef(self, name):
        return self.store.get_msgdef(name)

    def deserialize_cdr(self, raw, msgtype):
        self.calls += 1
        return self.store.deserialize_cdr(raw, msgtype)


# ---- the oracle: rosbags + the REP-145 rules of reading_from_msg, one message at a time --------
def oracle(msgtype, raw, store):
    """(reject reason or None, has_header, stamp ns, frame, omega, force or None, undecodable)."""
    try:
        msg = store.deserialize_cdr(raw, msgtype)
    except Exception:
        return "bad_message", False, 0, "", None, None, True
    if msgtype == TW:
        return None, False, 0, "", _v(msg.angular), None, False
    stamp = msg.header.stamp
    head = (True, stamp.sec * S + stamp.nanosec, msg.header.frame_id)
    if stamp.nanosec >= S or stamp.sec < 0:                   # not a valid builtin_interfaces/Time
        return ("bad_message", *head, None, None, False)
    if msgtype == TWS:
        return (None, *head, _v(msg.twist.angular), None, False)
    if msg.angular_velocity_covariance[0] == -1.0:
        return ("no_rate", *head, None, None, False)
    force = None if msg.linear_acceleration_covariance[0] == -1.0 else _v(msg.linear_acceleration)
    return (None, *head, _v(msg.angular_velocity), force, False)


def _v(v):
    return np.array([v.x, v.y, v.z])


def assert_matches_oracle(msgtype, raws, store, rb: RateBlock):
    assert len(rb) == len(raws) and rb.identity is not None and not rb.identity.any()
    for i, raw in enumerate(raws):
        reason, has_header, stamp, frame, omega, force, undecodable = oracle(msgtype, raw, store)
        assert rb.reject_reason(i) == reason, (i, raw, rb.detail.get(i))
        if reason is not None:
            assert rb.detail[i]
        if undecodable:
            assert rb.detail[i].startswith(f"cannot decode {msgtype}:")
            continue
        assert (bool(rb.has_header[i]), int(rb.stamp_ns[i]), rb.frame_id[i]) == (has_header, stamp, frame)
        if reason == "bad_message":
            assert "(invalid stamp)" in rb.detail[i]
        if reason is None:
            assert np.array_equal(rb.omega[i], omega, equal_nan=True)
            assert bool(rb.has_force[i]) == (force is not None)
            if force is not None:
                assert np.array_equal(rb.force[i], force, equal_nan=True)


# ---- shared recordings ----------------------------------------------------------------------
@pytest.mark.parametrize("bag", SHARED, ids=[p.name for p in SHARED])
def test_shared_recordings_message_by_message(bag):
    with InputBag(bag) as b:
        conn = next(c for c in b.connections if b.is_input(c))
        raws = [r for ch in b.chunks(input_only=True) for r in ch.raws]
        store = CountingStore(b.store_for(conn))
        rb = decode_rates(b.msgtype, raws, store)
        assert store.calls == 0                           # all on the vectorised path
        assert_matches_oracle(b.msgtype, raws, b.store_for(conn), rb)
        # and the same as reading_from_msg with the mounting a replay would use (finite rows)
        msgs = [b.deserialize(conn, r) for r in raws[:200]]
    for i, msg in enumerate(msgs):      # no mounting configured: base_link or identity, values unchanged
        r = m.reading_from_msg(msg, m.Mounting(unknown_frame="identity"))
        assert isinstance(r, m.Reading) == (rb.reject[i] == 0)
        if isinstance(r, m.Reading):
            assert np.array_equal(rb.omega[i], r.omega) and int(rb.stamp_ns[i]) == r.stamp_ns
    assert len(raws) > 1000 and (rb.reject == 0).mean() > 0.9


# ---- generated messages ---------------------------------------------------------------------
def stamp(sec, nsec):
    return T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec)


def make(msgtype, sec, nsec, frame, w, f, cov_w, cov_f):
    v3 = T["geometry_msgs/msg/Vector3"]
    if msgtype == TW:
        return T[TW](linear=v3(x=1.0, y=2.0, z=3.0), angular=v3(x=w[0], y=w[1], z=w[2]))
    header = T["std_msgs/msg/Header"](stamp=stamp(sec, nsec), frame_id=frame)
    if msgtype == TWS:
        return T[TWS](header=header, twist=T["geometry_msgs/msg/Twist"](linear=v3(x=f[0], y=f[1], z=f[2]),
                                                                        angular=v3(x=w[0], y=w[1], z=w[2])))
    cw, cf = np.full(9, 0.25), np.full(9, 0.5)
    cw[0], cf[0] = cov_w, cov_f
    return T[IMU](header=header, orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                  orientation_covariance=np.full(9, 7.0), angular_velocity=v3(x=w[0], y=w[1], z=w[2]),
                  angular_velocity_covariance=cw, linear_acceleration=v3(x=f[0], y=f[1], z=f[2]),
                  linear_acceleration_covariance=cf)


floats = st.floats(allow_nan=True, allow_infinity=True, width=64)
vec = st.tuples(floats, floats, floats)
cov = st.sampled_from([0.0, -1.0, 0.01, math.nan, -0.0])
frames = st.one_of(st.sampled_from(["", "base_link", "imu_link", "a", "seven77", "eight888", "x" * 17]),
                   st.text(max_size=13))
mutation = st.one_of(st.just(("none", 0)), st.tuples(st.sampled_from(["cut", "pad", "junk", "flip"]),
                                                     st.integers(1, 40)))


@st.composite
def message_bytes(draw, msgtype):
    msg = make(msgtype, draw(st.integers(-2**31, 2**31 - 1)),
               draw(st.one_of(st.integers(0, S - 1), st.integers(S, 2**32 - 1))),
               draw(frames), draw(vec), draw(vec), draw(cov), draw(cov))
    raw = bytearray(J.serialize_cdr(msg, msgtype, little_endian=draw(st.booleans())))
    kind, k = draw(mutation)
    if kind == "cut":
        raw = raw[: max(0, len(raw) - k)]
    elif kind == "pad":
        raw += bytes(k % 9)
    elif kind == "junk":
        raw[draw(st.integers(0, len(raw) - 1))] = draw(st.integers(0, 255))
    elif kind == "flip" and len(raw) > 12:
        raw[12] ^= k                                      # frame_id length field (or a Twist float)
    return bytes(raw)


@pytest.mark.parametrize("msgtype", [IMU, TWS, TW])
@settings(max_examples=60, deadline=None)
@given(data=st.data())
def test_generated_messages_equal_rosbags(msgtype, data):
    raws = data.draw(st.lists(message_bytes(msgtype), min_size=1, max_size=25))
    listed = CountingStore(J)
    rb = decode_rates(msgtype, raws, listed)
    assert_matches_oracle(msgtype, raws, J, rb)
    # the same rows in place in one buffer between other bytes (as in an MCAP chunk: RawRows):
    # the same results, and the same rows left to rosbags
    gaps = data.draw(st.lists(st.binary(min_size=1, max_size=40), min_size=len(raws) + 1, max_size=len(raws) + 1))
    rows = in_place(raws, gaps)
    assert list(rows) == raws
    placed = CountingStore(J)
    assert_matches_oracle(msgtype, raws, J, decode_rates(msgtype, rows, placed))
    assert placed.calls == listed.calls


def in_place(raws, gaps):
    """``raws`` as RawRows in one buffer, ``gaps[i]`` before row i (and the last one after)."""
    buf, beg, end = bytearray(), [], []
    for gap, raw in zip(gaps, raws):
        buf += gap
        beg.append(len(buf))
        buf += raw
        end.append(len(buf))
    buf += gaps[-1]
    return RawRows(np.frombuffer(bytes(buf), np.uint8), np.array(beg, np.int64), np.array(end, np.int64))


def test_raw_rows_slices_takes_and_joins_buffers():
    """RawRows: slicing, index arrays and concatenation of rows of different buffers (only each
    part's span copied) give the same bytes as the lists they stand for."""
    rng = np.random.default_rng(3)
    raws = [bytes(rng.integers(0, 256, rng.integers(0, 30), dtype=np.uint8)) for _ in range(40)]
    a = in_place(raws[:25], [b"xy" * int(k) for k in rng.integers(0, 4, 26)])
    b = in_place(raws[25:], [b"z" * int(k) for k in rng.integers(0, 9, 16)])
    assert list(a[3:9]) == raws[3:9] and a[7] == raws[7] and len(a[3:9]) == 6
    idx = rng.permutation(25)[:12]
    assert list(a[idx]) == [raws[i] for i in idx]
    both = RawRows.concat([a[5:20], b[2:]])
    assert list(both) == raws[5:20] + raws[27:]
    assert len(both.buf) <= len(a.buf) + len(b.buf)
    assert concat_rows([raws[:3], a[3:6]]) == raws[:6]            # mixed: a list of bytes
    assert list(concat_rows([a[:2], a[2:4]])) == raws[:4]


def test_plain_little_endian_rows_never_reach_rosbags():
    """The vectorised path takes every well-formed little-endian row, whatever its frame_id."""
    raws, names = [], ["", "a", "base_link", "imu_link_with_a_longer_name", "ümlaut", "z" * 8]
    for i in range(300):
        msg = make(IMU, 10 + i, i * 1000, names[i % len(names)], (i, -i, 0.5), (0.0, 0.0, 9.8),
                   -1.0 if i % 7 == 0 else 0.0, -1.0 if i % 5 == 0 else 0.0)
        raws.append(bytes(J.serialize_cdr(msg, IMU)))
    store = CountingStore(J)
    rb = decode_rates(IMU, raws, store)
    assert store.calls == 0
    assert_matches_oracle(IMU, raws, J, rb)
    assert (
        rb.reject_reason(0) == "no_rate" and rb.detail[0] == "angular_velocity_covariance[0] = -1 (rate not reported)"
    )
    assert not rb.has_force[5] and rb.has_force[1] and rb.frame_id[4] == "ümlaut"


def test_invalid_nanosec_is_a_bad_message_not_a_time():
    """Issue 17: one stamp with nanosec = 1.5e9 must not become t + 1.5 s; a negative ``sec``
    (before 1970) is no time either (it reset the node twice and stamped an output 0)."""
    good = make(IMU, 100, 999_999_999, "imu", (0.1, 0.2, 0.3), (0, 0, 9.8), 0.0, 0.0)
    bad = make(IMU, 100, 1_500_000_000, "imu", (0.1, 0.2, 0.3), (0, 0, 9.8), -1.0, 0.0)
    before = make(IMU, -1, 500_000_000, "imu", (0.1, 0.2, 0.3), (0, 0, 9.8), 0.0, 0.0)
    for le in (True, False):                              # vectorised and rosbags paths
        raws = [bytes(J.serialize_cdr(x, IMU, little_endian=le)) for x in (good, bad, before)]
        rb = decode_rates(IMU, raws)
        assert rb.reject_reason(0) is None and rb.reject_reason(1) == rb.reject_reason(2) == "bad_message"
        assert "1500000000" in rb.detail[1] and REJECT_REASONS[rb.reject[1] - 1] == "bad_message"
        assert rb.detail[2] == "header.stamp.sec = -1 is negative (invalid stamp)"
        assert int(rb.stamp_ns[2]) == -500_000_000 and bool(rb.has_header[2])


def test_bag_definition_with_another_layout_goes_through_rosbags():
    """A bag whose own Imu definition differs from Jazzy's is never decoded by offsets."""
    text = J.generate_msgdef(IMU)[0]
    same = get_typestore(Stores.EMPTY)
    same.register(get_types_from_msg(text, IMU))
    other = get_typestore(Stores.EMPTY)
    extra = text.replace("std_msgs/Header header\n", "std_msgs/Header header\nfloat64 extra\n", 1)
    other.register(get_types_from_msg(extra, IMU))
    assert standard_layout(same, IMU) and not standard_layout(other, IMU)
    cls = other.types
    msgs = [cls[IMU](header=cls["std_msgs/msg/Header"](stamp=cls["builtin_interfaces/msg/Time"](sec=5, nanosec=i),
                                                       frame_id="imu"), extra=float(i),
                     orientation=cls["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                     orientation_covariance=np.zeros(9),
                     angular_velocity=cls["geometry_msgs/msg/Vector3"](x=float(i), y=2.0, z=3.0),
                     angular_velocity_covariance=np.zeros(9),
                     linear_acceleration=cls["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=9.8),
                     linear_acceleration_covariance=np.zeros(9)) for i in range(20)]
    raws = [bytes(other.serialize_cdr(x, IMU)) for x in msgs]
    store = CountingStore(other)
    rb = decode_rates(IMU, raws, store)
    assert store.calls == len(raws)
    assert_matches_oracle(IMU, raws, other, rb)
    assert rb.omega[7, 0] == 7.0


def test_other_types_and_empty_input():
    assert len(decode_rates(IMU, [])) == 0
    rb = decode_rates("nav_msgs/msg/Odometry", [b"\x00\x01\x00\x00" + bytes(8)])
    assert rb.reject_reason(0) == "bad_message"
