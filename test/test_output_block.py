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

"""The compiled output kernel (engine.output_kernel) and OutputBlock (engine.outputs).

Reference: the numpy implementation of ``Simulator.outputs()`` as it was before the kernel
(kept here, and only here). The kernel must agree with it to 1e-12 over every mode, fidelity and
effect, on the shipped scenes and on random states; ``block[i]`` must be exactly
``Simulator.outputs()`` at that instant; non-finite outputs must never come out (issue 17).
"""
from __future__ import annotations

import math
from pathlib import Path
import zlib

from hypothesis import given, HealthCheck, settings
from hypothesis import strategies as st
import numpy as np
import pytest

from gyro_platform.engine.inputs import RateSample
from gyro_platform.engine.outputs import BEARING_NAMES, N_COL, OutputBlock, Outputs
from gyro_platform.engine.simulator import Simulator
from gyro_platform.engine.snapshots import Snapshots
from gyro_platform.errors import GimbalLockError, NonFiniteOutputError, SimulationError
from gyro_platform.physics import effects as fx
from gyro_platform.physics.model import BODY_OF_GIMBAL, GIMBAL_AXES, SPIN_AXES
from gyro_platform.physics.options import EFFECTS, ModelOptions, STABILISED_ONLY
from gyro_platform.physics.params import NAV1
from gyro_platform.physics.rotations import (euler_xyz, euler_xyz_rates, euler_xyz_rates_into, matrix_quat,
                                             matrix_rotvec, quat_matrix, rotvec_matrix)
from gyro_platform.physics.system import PRECESSION, SEG_DT, SEG_F0, SEG_F1, SEG_N, SEG_T0, SEG_W0, SEG_W1
from gyro_platform.physics.tree import kinematics, tree_inverse_dynamics, TreeWork
from gyro_platform.scenes.schema import load_scene

#: the vector fields of a ``seg`` row
W0, W1, F0, F1 = (slice(o, o + 3) for o in (SEG_W0, SEG_W1, SEG_F0, SEG_F1))
SCENES = sorted((Path(__file__).resolve().parents[1] / "config" / "scenes").glob("*.yaml"))


# ---- the reference: Simulator.outputs() before the compiled kernel (numpy) ------------------

def reference_outputs(sim: Simulator) -> Outputs:
    """Outputs at the simulator's current instant, computed the old way (numpy, Python)."""
    st = sim.layout
    sys_ = sim.system
    y = sim.y
    q = y[st.q].copy()
    wB = sys_.seg[W1].copy()
    fB = sys_.seg[F1].copy()

    def rhs(t, yy):
        out = np.empty_like(yy)
        sys_.rhs_into(t, yy, out)
        return out

    yd = rhs(sim.t_rel, y)
    if sys_.fid != PRECESSION:
        v, a = y[st.v].copy(), yd[st.v].copy()
    else:
        eps = 1e-6
        qdd = (rhs(sim.t_rel + eps, y + eps * yd)[st.q] - rhs(sim.t_rel - eps, y - eps * yd)[st.q]) / (2 * eps)
        v, a = (np.concatenate([y[st.Om], yd[st.q]]), np.concatenate([yd[st.Om], qdd])) if sys_.stabilised \
            else (yd[st.q].copy(), qdd)
    qd = v[-5:].copy()
    R_IB = quat_matrix(y[st.quat_IB])
    R_IP = quat_matrix(y[st.quat_IP]) if st.quat_IP is not None else R_IB @ sys_.R_BP
    R_IC = rotvec_matrix(sys_.w_IN * sim.t_rel)
    Om = y[st.Om].copy() if st.Om is not None else sys_.R_PB @ wB
    Q = np.zeros(5)
    wc = R_IP.T @ (R_IC @ sys_.w_IN) if sim.options.has("earth_rate") else np.zeros(3)
    fx.gimbal_forces(sys_.on, sys_.k, sys_.L, q, qd, wc, Q)
    tree = sys_.tree
    wk = TreeWork(tree)
    tau_ext = np.zeros((tree.nb, 3))
    if sim.needs_f:
        kinematics(tree.parent, tree.jtype, tree.axis, tree.qidx, tree.vidx, tree.root_dynamic,
                   q, v, Om, wk.R, wk.w, wk.J)
        fb = np.zeros((tree.nb, 3))
        fx.body_specific_force(wk.R, tree.parent, R_IP.T @ (R_IB @ fB), fb)
        fx.g_sensitive_torques(sys_.k, sys_.on[fx.UNBALANCE], sys_.on[fx.ANISO], tree.rotor_host,
                               tree.rotor_axis, fb, tau_ext)
    if sys_.stabilised:
        w0, wd0 = np.zeros(3), np.zeros(3)
    else:
        seg = sys_.seg
        w0 = sys_.R_PB @ wB
        wd0 = sys_.R_PB @ ((seg[W1] - seg[W0]) / seg[SEG_DT]) if seg[SEG_DT] > 0 else np.zeros(3)
    L = sys_.L_true if sim.options.has("rotor_gyroscopic") else np.zeros(3)
    _, f, rtau = tree_inverse_dynamics(tree, wk, q, v, a, w0, wd0, L, tau_ext)
    bearings = {"support": f[0].copy()}
    for i, name in enumerate(("gimbal4", "gimbal5", "gimbal7", "gimbal9", "gimbal10")):
        fi, n = f[BODY_OF_GIMBAL[i]], GIMBAL_AXES[i]
        bearings[name] = fi - (n @ fi) * n
    motor = np.zeros(3)
    for r, name in enumerate(("rotor6", "rotor8", "rotor11")):
        s = SPIN_AXES[r]
        motor[r] = s @ rtau[r]
        bearings[name] = rtau[r] - motor[r] * s
    mount = mount_rates = servo = None
    if sys_.stabilised:
        R_CP = R_IC.T @ R_IP
        drift, drift_rate = matrix_rotvec(R_CP), Om - R_CP.T @ sys_.w_IN
        servo = np.zeros(3)
        if sim.options.has("servo"):
            fx.servo_torque(sys_.k, q[[4, 0, 3]], qd[[4, 0, 3]], y[st.z], servo)
        mount = euler_xyz(sys_.R_PB @ (R_IB.T @ R_IP))
        mount_rates = euler_xyz_rates(mount, Om - R_IP.T @ (R_IB @ wB))
    else:   # drift of the gyros' reference triad: y = rotor 11's spin axis, x = rotor 6's normal to it
        R_P5, R_P10 = wk.R[1] @ wk.R[2], wk.R[4] @ wk.R[5]
        e6, e11 = R_P5 @ SPIN_AXES[0], R_P10 @ SPIN_AXES[2]
        w5, w10 = R_P5 @ wk.w[2], R_P10 @ wk.w[5]
        yv = e11
        x = e6 - (e6 @ yv) * yv
        x /= np.linalg.norm(x)
        z = np.cross(x, yv)
        G_P = np.column_stack([x, yv, z])
        R_CG = R_IC.T @ R_IP @ G_P
        drift = matrix_rotvec(R_CG)
        xd, ydv = np.cross(w5, e6), np.cross(w10, e11)
        zd = np.cross(xd, yv) + np.cross(x, ydv)
        w_IG_P = 0.5 * (np.cross(x, xd) + np.cross(yv, ydv) + np.cross(z, zd))
        drift_rate = G_P.T @ w_IG_P - R_CG.T @ sys_.w_IN
    status = {"gimbal_lock_margin": float(np.min(np.abs(np.cos(q[[1, 2, 4]])))),
              "max_gimbal_angle": float(np.max(np.abs(q))), "n_steps": float(sim.n_steps)}
    return Outputs(t=float(sim.t), gimbal_angles=q, gimbal_rates=qd, gimbal_axial_torques=Q, platform_rate=Om,
                   platform_attitude=matrix_quat(R_IP), drift_angle=drift, drift_rate=drift_rate,
                   bearing_torques=bearings, motor_torques=motor, mount_angles=mount, mount_rates=mount_rates,
                   servo_torque=servo, status=status, rotor_rates=np.asarray(sim.params.rotor_speed, float))


# ---- comparison -----------------------------------------------------------------------------

ARRAY_FIELDS = ("gimbal_angles", "gimbal_rates", "gimbal_axial_torques", "platform_rate", "platform_attitude",
                "drift_angle", "drift_rate", "motor_torques", "mount_angles", "mount_rates", "servo_torque",
                "rotor_rates")


def _pairs(a: Outputs, b: Outputs):
    yield "t", np.array([a.t]), np.array([b.t])
    for name in ARRAY_FIELDS:
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            yield name, np.asarray(x), np.asarray(y)
    assert list(a.bearing_torques) == list(BEARING_NAMES) == list(b.bearing_torques)
    for name in BEARING_NAMES:
        yield "bearing " + name, a.bearing_torques[name], b.bearing_torques[name]
    assert list(a.status) == list(b.status)
    yield "status", np.array(list(a.status.values())), np.array(list(b.status.values()))


def deviation(a: Outputs, b: Outputs) -> float:
    """Largest difference over all quantities, relative to max(1, |b|) (rad, rad/s, N m)."""
    worst = 0.0
    for name, x, y in _pairs(a, b):
        assert np.all(np.isfinite(x)), name
        worst = max(worst, float(np.max(np.abs(x - y) / np.maximum(1.0, np.abs(y)))))
    return worst


def assert_identical(a: Outputs, b: Outputs) -> None:
    for name, x, y in _pairs(a, b):
        np.testing.assert_array_equal(x, y, err_msg=name)


TOL = 1e-12
STAB_EFFECTS = tuple(e for e in EFFECTS if e != "vehicle_angular_acceleration")
CARRIED_EFFECTS = tuple(e for e in EFFECTS if e not in STABILISED_ONLY)
PARAMS = NAV1.with_(spring=(0.5, 0.4, 0.3, 0.6, 0.45), damper=(2e-3, 3e-3, 1e-3, 2e-3, 4e-3),
                    gimbal_coulomb=(1e-6,) * 5, gimbal_viscous_friction=(1e-7,) * 5,
                    bias_torque=(1e-6, -2e-6, 3e-6, -1e-6, 2e-6), unbalance=2e-6, anisoelastic=3e-6)


def _configs():
    for mode, every in (("stabilised", STAB_EFFECTS), ("carried", CARRIED_EFFECTS)):
        for fid in ("full", "linear", "precession"):
            for effects in ("defaults", "all"):
                eff = None if effects == "defaults" else every
                yield pytest.param(mode, fid, eff, id=f"{mode}-{fid}-{effects}")


def _sim(mode, fid, effects, **kw) -> Simulator:
    opt = ModelOptions.make(mode, fid, effects, **kw) if effects is not None else ModelOptions.make(mode, fid, **kw)
    return Simulator(PARAMS, opt)


def _drive(sim: Simulator, n: int, rng, dt=2e-3, force_scale=9.81):
    """Push n samples of a smooth random motion with specific force; yield after each."""
    a = rng.normal(scale=0.3, size=(3, 3))
    g = rng.normal(scale=force_scale, size=3)
    for i in range(n):
        t = i * dt
        w = a[0] + a[1] * math.sin(7 * t) + a[2] * math.cos(13 * t)
        sim.push(RateSample.of(100.0 + t, w, g + 2.0 * math.sin(5 * t)))
        yield i


@pytest.mark.parametrize("mode, fid, effects", list(_configs()))
def test_kernel_matches_reference_along_a_motion(mode, fid, effects):
    rng = np.random.default_rng(zlib.crc32(f"{mode}{fid}{effects}".encode()))
    sim = _sim(mode, fid, effects)
    worst = 0.0
    for _ in _drive(sim, 12, rng):
        worst = max(worst, deviation(sim.outputs(), reference_outputs(sim)))
    assert worst <= TOL


@pytest.mark.parametrize("mode, fid, effects", list(_configs()))
def test_kernel_matches_reference_at_large_random_states(mode, fid, effects):
    """Large gimbal angles and rates, tilted attitudes, steep input slopes: every term of the
    Newton–Euler pass, the drift and the mount angles far from zero."""
    rng = np.random.default_rng(7)
    sim = _sim(mode, fid, effects)
    for _ in _drive(sim, 2, rng):
        pass
    st = sim.layout
    worst = 0.0
    for _ in range(6):
        y = sim.y.copy()
        y[st.q] = rng.uniform(-1.0, 1.0, 5)
        if st.v.stop > st.v.start:
            y[st.v] = rng.normal(scale=2.0, size=st.v.stop - st.v.start)
        for sl in (st.quat_IB, st.quat_IP):
            if sl is not None:
                qv = rng.normal(size=4)
                y[sl] = qv / np.linalg.norm(qv)
        if st.z is not None:
            y[st.z] = rng.normal(scale=1e-3, size=3)
        sim.y = y
        sim.system.seg[SEG_W0:SEG_N] = rng.normal(scale=3.0, size=12)
        sim.t_rel = float(rng.uniform(0, 1e4))
        sim.system.seg[SEG_T0] = sim.t_rel - 0.01
        sim.system.seg[SEG_DT] = 0.01
        worst = max(worst, deviation(sim.outputs(), reference_outputs(sim)))
    assert worst <= TOL


@pytest.mark.parametrize("path", SCENES, ids=[p.stem for p in SCENES])
def test_kernel_matches_reference_on_the_shipped_scenes(path):
    scene = load_scene(path)
    if scene.motion.is_bag:
        pytest.skip("bag scene: covered by the replay tests")
    sim = Simulator(scene.params, scene.options)
    t, w, f = scene.motion.generator.arrays(min(scene.duration, 0.5), scene.sample_rate)
    worst = 0.0
    for i in range(len(t)):
        sim.push(RateSample(float(t[i]), w[i], f[i]))
        if i % 5 == 0 or i == len(t) - 1:
            worst = max(worst, deviation(sim.outputs(), reference_outputs(sim)))
    assert worst <= TOL


def test_outputs_keep_the_spec_oracles():
    """O10 (steady precession bearing torques) and O7c (rotor bearing 1/cos β in precession)
    through the kernel."""
    Q10, beta, a9, w = 1e-4, math.radians(60), 0.3, -3.978873032e-3
    sim = Simulator(NAV1.with_(bias_torque=(0, 0, 0, 0, Q10)),
                    ModelOptions.make("carried", "full", ("rotor_gyroscopic", "coriolis", "bias_torque")))
    sim.push(RateSample.of(0.0, [0, 0, 0]))
    sim.y[4], sim.y[3], sim.y[8] = beta, a9, w
    sim.y[5:8] = 0.0
    bt = sim.outputs().bearing_torques
    np.testing.assert_allclose(bt["rotor11"], [9.999993e-5, 0, 0], atol=2e-12)
    np.testing.assert_allclose(bt["gimbal9"], [1.0e-4, 0, 0], atol=2e-12)
    np.testing.assert_allclose(bt["support"], [9.553365e-5, 2.955202e-5, 0], atol=2e-12)
    tau, L = 0.02, NAV1.L[2]
    sim = Simulator(NAV1.with_(bias_torque=(0, 0, 0, tau, 0)),
                    ModelOptions.make("carried", "precession", ("rotor_gyroscopic", "bias_torque")))
    sim.push(RateSample.of(0.0, [0, 0, 0]))
    sim.y[4] = math.radians(80)
    out = sim.outputs()
    assert out.gimbal_rates[4] == pytest.approx(tau / (L * math.cos(math.radians(80))), rel=1e-12)
    assert out.bearing_torques["rotor11"][2] == pytest.approx(0.11517541, rel=1e-7)


def test_compiled_euler_rates_invert_the_joint_axes_and_stay_finite_at_the_singularity():
    from gyro_platform.physics.rotations import euler_xyz_axes
    rng = np.random.default_rng(5)
    out = np.empty(3)
    for _ in range(200):
        ang = rng.uniform(-3, 3, 3)
        om = rng.normal(size=3)
        euler_xyz_rates_into(ang, om, out)
        np.testing.assert_allclose(euler_xyz_axes(ang) @ out, om, atol=1e-12 / abs(math.cos(ang[1])))
        np.testing.assert_allclose(out, euler_xyz_rates(ang, om), rtol=1e-10, atol=1e-12)
    for b in (math.pi / 2, -math.pi / 2):
        ang = np.array([0.3, b, -0.7])
        om = rng.normal(size=3)
        euler_xyz_rates_into(ang, om, out)
        np.testing.assert_allclose(out, euler_xyz_rates(ang, om), atol=1e-12)


# ---- OutputBlock ----------------------------------------------------------------------------

def _snapshots_along(sim: Simulator, n: int, rng, **kw):
    """Drive sim; return (Snapshots after every sample, outputs() after every sample)."""
    T, TR, Y, SEG, NS, outs = [], [], [], [], [], []
    for _ in _drive(sim, n, rng, **kw):
        T.append(sim.t)
        TR.append(sim.t_rel)
        Y.append(sim.y.copy())
        SEG.append(sim.system.seg.copy())
        NS.append(sim.n_steps)
        outs.append(sim.outputs())
    snaps = Snapshots(np.array(T), np.array(TR), np.array(Y), np.array(SEG), np.array(NS, dtype=np.int64))
    return snaps, outs


@pytest.mark.parametrize("mode, fid", [("stabilised", "linear"), ("stabilised", "precession"),
                                       ("carried", "full"), ("carried", "precession")])
def test_block_instants_are_exactly_outputs(mode, fid):
    rng = np.random.default_rng(1)
    sim = _sim(mode, fid, None)
    snaps, outs = _snapshots_along(sim, 15, rng)
    block = sim.outputs_at(snaps)
    assert len(block) == 15
    for i, o in enumerate(outs):
        assert_identical(block[i], o)
    assert block.as_rows() == [o.as_row() for o in outs]
    # the arrays over the instants are the Outputs fields stacked
    np.testing.assert_array_equal(block.bearing_torques[:, BEARING_NAMES.index("gimbal9")],
                                  [o.bearing_torques["gimbal9"] for o in outs])
    np.testing.assert_array_equal(block.status["n_steps"], [o.status["n_steps"] for o in outs])
    assert (block.mount_angles is None) == (mode == "carried")
    # stack, slicing, concat: the same rows
    np.testing.assert_array_equal(OutputBlock.stack(outs).rows, block.rows)
    parts = [block[:4], block[4:9], block[9:]]
    np.testing.assert_array_equal(OutputBlock.concat(parts).rows, block.rows)
    assert_identical(parts[1][2], outs[6])
    assert len(block[3:3]) == 0 and block[3:3].as_rows() == []
    empty = OutputBlock.stack([], stabilised=mode == "stabilised")
    assert len(empty) == 0 and (empty.mount_angles is None) == (mode == "carried")
    assert len(sim.outputs_at(Snapshots.empty(sim.layout.n))) == 0
    with pytest.raises(IndexError):
        block[15]


def test_output_row_is_the_row_of_outputs_and_a_new_array_each_call():
    """``Simulator.output_row`` (the node's per-instant path) holds exactly the numbers of
    ``outputs()`` in the block layout, a fresh array per call; before any sample it refuses."""
    rng = np.random.default_rng(3)
    sim = _sim("stabilised", "linear", None)
    with pytest.raises(SimulationError):
        sim.output_row()
    for _ in _drive(sim, 5, rng):
        row = sim.output_row()
        assert row.shape == (N_COL,)
        np.testing.assert_array_equal(row, OutputBlock.stack([sim.outputs()]).rows[0])
        assert sim.output_row() is not row


def test_block_items_are_copies_and_stack_keeps_extra_status():
    rng = np.random.default_rng(2)
    sim = _sim("stabilised", "linear", None)
    snaps, outs = _snapshots_along(sim, 3, rng)
    block = sim.outputs_at(snaps)
    o = block[1]
    o.gimbal_angles[:] = 99.0
    assert np.all(block.gimbal_angles[1] != 99.0)
    outs[0].status["custom"] = 1.5
    for x in outs[1:]:
        x.status["custom"] = 2.5
    st = OutputBlock.stack(outs)
    assert st[0].status["custom"] == 1.5 and st.as_rows()[2]["custom"] == 2.5
    with pytest.raises(ValueError, match="mode or status"):
        OutputBlock.concat([st, block])


# ---- issue 17: numbers that blow up ---------------------------------------------------------

def _aniso_sim(mode="stabilised", fid="full"):
    eff = ("rotor_gyroscopic", "coriolis", "anisoelastic", "mass_unbalance")
    return Simulator(PARAMS, ModelOptions.make(mode, fid, eff))


def test_huge_specific_force_raises_non_finite_output_error_naming_quantity_and_time():
    sim = _aniso_sim()
    sim.push(RateSample.of(5.0, [0.0, 0.0, 0.0], [1e200, 3e200, -2e200]))
    assert np.all(np.isfinite(sim.y))
    with pytest.raises(NonFiniteOutputError, match=r"at t = 5\.0 s") as ei:
        sim.outputs()
    assert isinstance(ei.value, SimulationError)
    assert ei.value.quantity and ei.value.t == 5.0
    assert ei.value.quantity in str(ei.value)


def test_block_stops_at_the_first_non_finite_instant_and_carries_the_ones_before():
    rng = np.random.default_rng(4)
    sim = _aniso_sim("carried", "full")
    snaps, outs = _snapshots_along(sim, 6, rng)
    seg = snaps.seg.copy()
    seg[3, SEG_F0:SEG_N] = 1e250                # instant 3: absurd specific force
    bad = Snapshots(snaps.t, snaps.t_rel, snaps.y, seg, snaps.n_steps)
    with pytest.raises(NonFiniteOutputError) as ei:
        sim.outputs_at(bad)
    e = ei.value
    assert e.t == snaps.t[3]
    assert len(e.block) == 3
    for i in range(3):
        assert_identical(e.block[i], outs[i])


def test_precession_gimbal_lock_in_a_block_raises_the_model_error_with_the_block():
    tau = 0.02
    sim = Simulator(NAV1.with_(bias_torque=(0, 0, 0, tau, 0)),
                    ModelOptions.make("carried", "precession", ("rotor_gyroscopic", "bias_torque")))
    sim.push(RateSample.of(0.0, [0, 0, 0]))
    y = np.repeat(sim.y[None], 3, 0)
    y[2, 4] = math.pi / 2 - 1e-5
    snaps = Snapshots(np.zeros(3), np.zeros(3), y, np.repeat(sim.system.seg[None], 3, 0), np.zeros(3, np.int64))
    seg_before = sim.system.seg.copy()
    with pytest.raises(GimbalLockError, match="gimbal lock") as ei:
        sim.outputs_at(snaps)
    assert len(ei.value.block) == 2
    np.testing.assert_array_equal(sim.system.seg, seg_before)
    sim.y = y[2].copy()
    with pytest.raises(GimbalLockError):
        sim.outputs()


finite_big = st.floats(min_value=-1e300, max_value=1e300, allow_nan=False)
gate_rate = st.floats(min_value=-35.0, max_value=35.0)     # pipeline.gate max_rate: 35 rad/s


def _assert_all_finite(out: Outputs) -> None:
    for name, x, _ in _pairs(out, out):
        assert np.all(np.isfinite(x)), name


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mode=st.sampled_from(["stabilised", "carried"]), fid=st.sampled_from(["full", "linear", "precession"]),
       f=st.tuples(finite_big, finite_big, finite_big), exponent=st.integers(min_value=0, max_value=300),
       w0=st.tuples(gate_rate, gate_rate, gate_rate), w1=st.tuples(gate_rate, gate_rate, gate_rate),
       dt=st.sampled_from([1e-9, 1e-6, 1e-3, 1.0]), qd_scale=st.sampled_from([0.0, 1.0, 1e3, 1e150]))
def test_outputs_are_finite_or_refused_never_nan(mode, fid, f, exponent, w0, w1, dt, qd_scale):
    """Huge specific forces, rates within the gate's limit, steep input slopes, wild (finite)
    gimbal rates: every output that comes out is finite; otherwise NonFiniteOutputError (or
    the model's SimulationError), never a NaN or Inf."""
    sim = _aniso_sim(mode, fid)
    sim.push(RateSample.of(0.0, [0.0, 0.0, 0.0], [0.0, 0.0, 9.81]))
    scale = 10.0 ** exponent / max(1.0, max(abs(x) for x in f))
    seg = sim.system.seg
    seg[SEG_T0], seg[SEG_DT] = sim.t_rel - dt, dt
    seg[W0], seg[W1] = w0, w1
    seg[F0] = seg[F1] = np.array(f) * scale
    if sim.layout.v.stop > sim.layout.v.start:
        sim.y[sim.layout.v] = qd_scale * np.linspace(-1.0, 1.0, sim.layout.v.stop - sim.layout.v.start)
    try:
        out = sim.outputs()
    except NonFiniteOutputError as e:
        assert e.quantity and e.quantity in str(e)
        return
    except SimulationError:
        return
    _assert_all_finite(out)


@pytest.mark.parametrize("mode", ["stabilised", "carried"])
@pytest.mark.parametrize("f", [1e10, 1e30, 1e100, 1e200])
def test_pushing_absurd_specific_forces_never_publishes_nan(mode, f):
    """Issue 17: anisoelastic with |f| >= 1e30 (>= 1e10 carried, next sample) gave NaN bearing
    torques. Now the stepping refuses, or the outputs are finite, or NonFiniteOutputError."""
    sim = Simulator(PARAMS, ModelOptions.make(mode, "full", ("rotor_gyroscopic", "coriolis", "anisoelastic"),
                                              max_substeps=64))
    try:
        for i in range(3):
            sim.push(RateSample.of(i * 1e-3, [0.01, 0.0, 0.0], [f, 0.5 * f, f]))
            try:
                _assert_all_finite(sim.outputs())
            except NonFiniteOutputError as e:
                assert e.t == pytest.approx(i * 1e-3) and e.quantity
    except SimulationError:
        pass


def test_row_layout_has_one_column_per_value():
    from gyro_platform.engine.outputs import COLUMN_NAMES
    assert len(COLUMN_NAMES) == N_COL == len(set(COLUMN_NAMES))
