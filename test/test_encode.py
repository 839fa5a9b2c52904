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

"""encode_outputs: the CDR bytes of K output instants at once must be byte-identical to rosbags
``serialize_cdr`` of the messages ``output_messages`` builds (every topic, stabilised and
carried, with and without namespace / frame prefix, random and simulated outputs)."""
from __future__ import annotations

from types import SimpleNamespace
import zlib

import numpy as np
import pytest

from gyro_platform import messages as m
from gyro_platform.engine.outputs import BEARING_NAMES, Outputs
from gyro_platform.messages.encode import encode_outputs, stamp_columns
from gyro_platform.physics.rotations import euler_xyz_axes

TYPES = m.MessageTypes.rosbags()
STORE = m.jazzy_typestore()


def stack(outs: list[Outputs]):
    """An OutputBlock-like object (the contract's fields, arrays over K instants) from Outputs."""
    try:
        from gyro_platform.engine.outputs import OutputBlock
    except ImportError:
        OutputBlock = None
    if OutputBlock is not None and hasattr(OutputBlock, "stack") and all(len(o.bearing_torques) == 9 for o in outs):
        try:
            return OutputBlock.stack(outs)
        except Exception:   # a producer's block may need fields these synthetic outputs lack
            pass

    def arr(name):
        vals = [getattr(o, name) for o in outs]
        return None if vals[0] is None else np.array(vals, dtype=float)

    return SimpleNamespace(
        t=np.array([o.t for o in outs]), gimbal_angles=arr("gimbal_angles"), gimbal_rates=arr("gimbal_rates"),
        gimbal_axial_torques=arr("gimbal_axial_torques"), platform_rate=arr("platform_rate"),
        platform_attitude=arr("platform_attitude"), drift_angle=arr("drift_angle"), drift_rate=arr("drift_rate"),
        bearing_torques=np.array([[o.bearing_torques[b] for b in BEARING_NAMES] for o in outs]),
        motor_torques=arr("motor_torques"), mount_angles=arr("mount_angles"), mount_rates=arr("mount_rates"),
        servo_torque=arr("servo_torque"), rotor_rates=outs[0].rotor_rates, status={})


def reference(out: Outputs, stamp: int, namespace: str, prefix: str) -> list[tuple[str, bytes]]:
    """The slow path: message objects (with the node's frame prefix rule), rosbags serialize_cdr."""
    res = []
    for topic, msg in m.output_messages(out, TYPES, stamp, namespace):
        if prefix and msg.header.frame_id:
            msg.header.frame_id = prefix + msg.header.frame_id
        res.append((topic, bytes(STORE.serialize_cdr(msg, msg.__msgtype__))))
    return res


def random_outputs(rng, k: int, stabilised: bool, *, mount_rates: bool = True, servo: bool = True,
                   rotors: bool = True) -> list[Outputs]:
    """Outputs with values over many magnitudes and signs (not physical: the encoding must not care)."""
    def v(n):
        return rng.standard_normal(n) * 10.0 ** rng.integers(-12, 6, n)

    rotor = v(3) * 1e3 if rotors else None
    outs = []
    for i in range(k):
        q = rng.standard_normal(4)
        outs.append(Outputs(
            t=float(rng.uniform(0, 1e4)), gimbal_angles=v(5), gimbal_rates=v(5), gimbal_axial_torques=v(5),
            platform_rate=v(3), platform_attitude=q / np.linalg.norm(q), drift_angle=v(3), drift_rate=v(3),
            bearing_torques={b: v(3) for b in BEARING_NAMES}, motor_torques=v(3),
            mount_angles=rng.uniform(-3, 3, 3) if stabilised else None,
            mount_rates=v(3) if stabilised and mount_rates else None, rotor_rates=rotor,
            servo_torque=v(3) if stabilised and servo else None))
    return outs


def check(outs: list[Outputs], stamps, namespace="", prefix="", block=None) -> None:
    got = encode_outputs(stack(outs) if block is None else block, np.asarray(stamps, np.int64), namespace, prefix)
    for i, out in enumerate(outs):
        ref = reference(out, int(stamps[i]), namespace, prefix)
        assert [t for t, _ in got] == [t for t, _ in ref]
        for (topic, raws), (_, want) in zip(got, ref):
            assert raws[i] == want, (topic, i)


NAMESPACES = [("", ""), ("robot1", "robot1/"), ("/a/b", ""), ("", "x/")]


@pytest.mark.parametrize("stabilised", [True, False])
@pytest.mark.parametrize("namespace,prefix", NAMESPACES)
def test_random_outputs_byte_identical(stabilised, namespace, prefix):
    rng = np.random.default_rng(zlib.crc32(repr((stabilised, namespace, prefix)).encode()))
    for _ in range(20):
        k = int(rng.integers(1, 12))
        outs = random_outputs(rng, k, stabilised)
        stamps = rng.integers(-10**9, 2**31 * 10**9 - 1, k)
        stamps[0] = 0
        check(outs, stamps, namespace, prefix)


@pytest.mark.parametrize("kw", [{"mount_rates": False}, {"servo": False}, {"rotors": False}])
def test_partial_outputs_byte_identical(kw):
    """Older producers: stabilised without mount rates (JointState velocity/effort empty),
    without servo torque (no servo topic, zero mount efforts), without rotor rates."""
    rng = np.random.default_rng(7)
    outs = random_outputs(rng, 5, True, **kw)
    for out, stamp in zip(outs, rng.integers(0, 10**18, 5)):    # an OutputBlock always carries
        check([out], [stamp], "ns", "p/", block=out)               # them: K = 1 Outputs each


def test_missing_bearings_left_out():
    """An Outputs (K = 1) carrying only some bearings: those topics only, as output_messages."""
    rng = np.random.default_rng(3)
    out = random_outputs(rng, 1, False)[0]
    out.bearing_torques = {b: out.bearing_torques[b] for b in ("support", "gimbal9", "rotor11")}
    check([out], [123456789], block=out)


@pytest.mark.parametrize("mode", ["stabilised", "carried"])
def test_simulated_outputs_byte_identical(mode):
    from gyro_platform.engine.simulator import Simulator
    from gyro_platform.physics.options import ModelOptions

    sim = Simulator(options=ModelOptions.make(mode, fidelity="linear"))
    rng = np.random.default_rng(11)
    n = 200
    t = 1.0 + np.arange(n) * 1e-3
    outs = sim.push_many(t, rng.normal(0, 0.2, (n, 3)), np.tile([0.0, 0.0, 9.81], (n, 1)) + rng.normal(0, 0.5, (n, 3)),
                         output_every=10)
    assert len(outs) == 20
    stamps = (t[9::10] * 1e9).astype(np.int64)
    for ns, prefix in NAMESPACES:
        check(outs, stamps, ns, prefix)


def test_mount_efforts_are_the_joint_axes_projection():
    """The vectorised servo projection equals euler_xyz_axes(a).T @ τ (the physics definition)."""
    rng = np.random.default_rng(5)
    a, tau = rng.uniform(-3, 3, (50, 3)), rng.normal(0, 10, (50, 3))
    got = m.mount_joint_efforts(a, tau)
    want = np.array([euler_xyz_axes(ai).T @ ti for ai, ti in zip(a, tau)])
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


def test_rotor_angles_wrapped_like_wrap_angle():
    rng = np.random.default_rng(9)
    outs = random_outputs(rng, 30, False)
    cols = m.joint_columns(stack(outs))
    want = [[m.wrap_angle(w * o.t) for w in o.rotor_rates] for o in outs]
    assert cols.position[:, -3:].tolist() == want


def test_stamps_clamped_and_checked():
    sec, nsec = stamp_columns([-5, 0, 1_500_000_000, 2**31 * 10**9 - 1])
    assert sec.tolist() == [0, 0, 1, 2**31 - 1] and nsec.tolist() == [0, 0, 500_000_000, 999_999_999]
    with pytest.raises(ValueError, match="int32"):
        stamp_columns([2**31 * 10**9])


def test_stamp_count_must_match():
    rng = np.random.default_rng(1)
    with pytest.raises(ValueError, match="stamps"):
        encode_outputs(stack(random_outputs(rng, 3, True)), np.zeros(2, np.int64))
