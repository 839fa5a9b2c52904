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

"""What the simulator reports at an output instant (ROS-free; ``messages`` maps it to ROS types).

Names and frames (all torques in N m, angles rad, rates rad/s):

* gimbal joints ``alpha4, beta5, beta7, alpha9, beta10`` (Magnus 1976 axis numbering);
* bearings: ``support`` (vehicle mount → platform, platform axes), ``gimbal4`` (platform →
  frame 4, frame-4 axes), ``gimbal5``/``gimbal7`` (frame 4 → housing 5/7, housing axes),
  ``gimbal9`` (platform → frame 9), ``gimbal10`` (frame 9 → housing 10), ``rotor6``,
  ``rotor8``, ``rotor11`` (housing → rotor, housing axes). A bearing torque is the reaction
  the bearing carries: the joint torque minus its axial part (the axial part is the spring,
  damper, friction or torquer torque, reported separately as ``gimbal_axial_torques``).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

GIMBAL_NAMES: tuple[str, ...] = ("alpha4", "beta5", "beta7", "alpha9", "beta10")
MOUNT_NAMES: tuple[str, ...] = ("mount_roll", "mount_pitch", "mount_yaw")
BEARING_NAMES: tuple[str, ...] = (
    "support", "gimbal4", "gimbal5", "gimbal7", "gimbal9", "gimbal10", "rotor6", "rotor8", "rotor11",
)
#: frame in whose axes each bearing torque is expressed (ROS frame ids, see README)
BEARING_FRAMES: dict[str, str] = {
    "support": "platform",
    "gimbal4": "gyro_frame4",
    "gimbal5": "gyro_housing5",
    "gimbal7": "gyro_housing7",
    "gimbal9": "gyro_frame9",
    "gimbal10": "gyro_housing10",
    "rotor6": "gyro_housing5",
    "rotor8": "gyro_housing7",
    "rotor11": "gyro_housing10",
}


@dataclass(slots=True)
class Outputs:
    """Platform outputs at time ``t`` (s).

    ``drift_angle`` is the rotation vector (rad, platform axes) of the platform attitude error
    relative to its reference (inertial, or local level when Earth rate is on); in carried mode
    it is the error of the gyros' inertial reference (the frame spanned by the spin axes of
    rotors 6 and 11) instead, because the platform itself turns with the vehicle.
    """

    t: float
    gimbal_angles: np.ndarray                      # (5,) rad
    gimbal_rates: np.ndarray                       # (5,) rad/s
    gimbal_axial_torques: np.ndarray               # (5,) N m, applied about each gimbal axis
    platform_rate: np.ndarray                      # (3,) rad/s, platform axes
    platform_attitude: np.ndarray                  # (4,) quaternion x, y, z, w: platform → inertial
    drift_angle: np.ndarray                        # (3,) rad
    drift_rate: np.ndarray                         # (3,) rad/s
    bearing_torques: dict[str, np.ndarray]         # name -> (3,) N m in BEARING_FRAMES[name]
    motor_torques: np.ndarray                      # (3,) N m, rotor 6, 8, 11 about their spin axes
    mount_angles: np.ndarray | None = None         # (3,) rad, stabilised mode only
    mount_rates: np.ndarray | None = None          # (3,) rad/s, d/dt mount_angles (stabilised mode)
    rotor_rates: np.ndarray | None = None          # (3,) rad/s, rotors 6, 8, 11 relative to their housings
    servo_torque: np.ndarray | None = None         # (3,) N m, platform axes, stabilised mode
    status: dict[str, float] = field(default_factory=dict)  # health figures (gimbal-lock margin …)

    def as_row(self) -> dict[str, float]:
        """Flat ``name -> value`` mapping for CSV/JSON (units in the names' docs above)."""
        row: dict[str, float] = {"t": self.t}
        for i, n in enumerate(GIMBAL_NAMES):
            row[n] = float(self.gimbal_angles[i])
            row[n + "_rate"] = float(self.gimbal_rates[i])
            row[n + "_axial_torque"] = float(self.gimbal_axial_torques[i])
        for i, ax in enumerate("xyz"):
            row["platform_rate_" + ax] = float(self.platform_rate[i])
            row["drift_" + ax] = float(self.drift_angle[i])
            row["drift_rate_" + ax] = float(self.drift_rate[i])
        for name in BEARING_NAMES:
            v = self.bearing_torques.get(name)
            if v is not None:
                for i, ax in enumerate("xyz"):
                    row[f"{name}_torque_{ax}"] = float(v[i])
        if self.mount_angles is not None:
            for i, n in enumerate(MOUNT_NAMES):
                row[n] = float(self.mount_angles[i])
        for k, v in self.status.items():
            row[k] = float(v)
        return row


# ---- row layout (one instant = N_COL floats) ------------------------------------------------
#: 3-vectors stored as consecutive rows of a (N_VEC, 3) block, in this order
VEC_NAMES: tuple[str, ...] = ("platform_rate", "drift_angle", "drift_rate", "motor_torques", "mount_angles",
                              "mount_rates", "servo_torque", "rotor_rates") + BEARING_NAMES
N_VEC = len(VEC_NAMES)
#: status figures with a column of their own (others, e.g. from ``stack``, ride along in a dict)
STATUS_NAMES: tuple[str, ...] = ("gimbal_lock_margin", "max_gimbal_angle", "n_steps")
C_T = 0
C_ANG, C_RATE, C_AXIAL = 1, 6, 11                  # (5,) each: one (3, 5) block
C_VEC = 16
C_OM, C_DRIFT, C_DRATE, C_MOTOR, C_MOUNT, C_MRATE, C_SERVO, C_ROTOR, C_BEAR = (C_VEC + 3 * i for i in range(9))
C_QUAT = C_VEC + 3 * N_VEC
C_STATUS = C_QUAT + 4
C_MARGIN, C_MAXANG, C_NSTEPS = C_STATUS, C_STATUS + 1, C_STATUS + 2
N_COL = C_STATUS + len(STATUS_NAMES)


def _column_names() -> tuple[str, ...]:
    """Human name of every column (errors name the quantity by it)."""
    names = ["t"] + [f"{q}[{n}]" for q in ("gimbal_angles", "gimbal_rates", "gimbal_axial_torques")
                     for n in GIMBAL_NAMES]
    per_rotor = ("rotor6", "rotor8", "rotor11")
    for v in VEC_NAMES:
        if v in BEARING_NAMES:
            names += [f"bearing_torques[{v}].{ax}" for ax in "xyz"]
        elif v in ("motor_torques", "rotor_rates"):
            names += [f"{v}[{r}]" for r in per_rotor]
        elif v in ("mount_angles", "mount_rates"):
            names += [f"{v}[{m}]" for m in MOUNT_NAMES]
        else:
            names += [f"{v}.{ax}" for ax in "xyz"]
    names += [f"platform_attitude.{c}" for c in "xyzw"] + [f"status[{s}]" for s in STATUS_NAMES]
    return tuple(names)


COLUMN_NAMES: tuple[str, ...] = _column_names()
assert len(COLUMN_NAMES) == N_COL


# slices of one row (built once: an Outputs is ~20 numpy views of its row)
_SL_GIMBAL = tuple(slice(c, c + 5) for c in (C_ANG, C_RATE, C_AXIAL))
_SL_VEC = tuple(slice(C_VEC + 3 * i, C_VEC + 3 * i + 3) for i in range(N_VEC))
_SL_BEAR = _SL_VEC[8:]
_SL_QUAT = slice(C_QUAT, C_STATUS)


def outputs_of_row(row: np.ndarray, stabilised: bool, status_keys: tuple[str, ...] = STATUS_NAMES,
                   extra: dict[str, float] | None = None) -> Outputs:
    """``Outputs`` whose arrays are views of ``row`` (N_COL,) (pass a row the caller gives away).
    ``stabilised``: the mount and servo fields exist (else None)."""
    get = row.__getitem__
    ang, rate, axial = map(get, _SL_GIMBAL)
    sv = _SL_VEC
    if status_keys is STATUS_NAMES:
        status = {"gimbal_lock_margin": row.item(C_MARGIN), "max_gimbal_angle": row.item(C_MAXANG),
                  "n_steps": row.item(C_NSTEPS)}
    else:
        status = {k: (row.item(C_STATUS + STATUS_NAMES.index(k)) if k in STATUS_NAMES else extra[k])
                  for k in status_keys}
    if stabilised:
        mount, mrate, servo = get(sv[4]), get(sv[5]), get(sv[6])
    else:
        mount = mrate = servo = None
    rotor = row.item(C_ROTOR)
    return Outputs(t=row.item(C_T), gimbal_angles=ang, gimbal_rates=rate, gimbal_axial_torques=axial,
                   platform_rate=get(sv[0]), platform_attitude=get(_SL_QUAT), drift_angle=get(sv[1]),
                   drift_rate=get(sv[2]), bearing_torques=dict(zip(BEARING_NAMES, map(get, _SL_BEAR))),
                   motor_torques=get(sv[3]), mount_angles=mount, mount_rates=mrate, servo_torque=servo,
                   rotor_rates=None if rotor != rotor else get(sv[7]), status=status)


class OutputBlock:
    """Outputs at K instants (arrays over the instants; fields as in ``Outputs``).

    ``t (K,)`` s; ``gimbal_angles``, ``gimbal_rates``, ``gimbal_axial_torques`` (K, 5);
    ``platform_rate`` (K, 3); ``platform_attitude`` (K, 4) quaternion x, y, z, w;
    ``drift_angle``, ``drift_rate`` (K, 3); ``bearing_torques`` (K, 9, 3) in ``BEARING_NAMES``
    order (frames ``BEARING_FRAMES``); ``motor_torques`` (K, 3); ``mount_angles``,
    ``mount_rates``, ``servo_torque`` (K, 3) in stabilised mode, else None; ``rotor_rates`` (3,)
    or None; ``status`` name -> (K,). The fields are views of ``rows`` (K, N_COL): treat them as
    read-only (``block[i]`` returns copies). ``len(block)``; ``block[i]`` -> ``Outputs``;
    ``block[a:b]`` -> ``OutputBlock``; ``OutputBlock.stack``/``concat``; ``as_rows()`` for CSV."""

    __slots__ = ("rows", "stabilised", "status_keys", "extra_status", "t", "gimbal_angles", "gimbal_rates",
                 "gimbal_axial_torques", "platform_rate", "platform_attitude", "drift_angle", "drift_rate",
                 "bearing_torques", "motor_torques", "mount_angles", "mount_rates", "servo_torque",
                 "rotor_rates", "status")

    def __init__(self, rows: np.ndarray, stabilised: bool, status_keys: tuple[str, ...] = STATUS_NAMES,
                 extra_status: dict[str, np.ndarray] | None = None):
        rows = np.asarray(rows, dtype=float)
        if rows.ndim != 2 or rows.shape[1] != N_COL:
            raise ValueError(f"output rows must have shape (K, {N_COL}), not {rows.shape}")
        K = rows.shape[0]
        self.rows = rows
        self.stabilised = bool(stabilised)
        self.status_keys = tuple(status_keys)
        self.extra_status = {k: np.asarray(v, float) for k, v in (extra_status or {}).items()}
        self.t = rows[:, C_T]
        self.gimbal_angles = rows[:, C_ANG:C_ANG + 5]
        self.gimbal_rates = rows[:, C_RATE:C_RATE + 5]
        self.gimbal_axial_torques = rows[:, C_AXIAL:C_AXIAL + 5]
        vec = rows[:, C_VEC:C_QUAT].reshape(K, N_VEC, 3)
        self.platform_rate, self.drift_angle, self.drift_rate, self.motor_torques = (vec[:, i] for i in range(4))
        if self.stabilised:
            self.mount_angles, self.mount_rates, self.servo_torque = (vec[:, i] for i in range(4, 7))
        else:
            self.mount_angles = self.mount_rates = self.servo_torque = None
        rotor = rows[0, C_ROTOR:C_ROTOR + 3] if K else None
        self.rotor_rates = None if rotor is None or rotor[0] != rotor[0] else rotor.copy()
        self.bearing_torques = vec[:, 8:]
        self.platform_attitude = rows[:, C_QUAT:C_STATUS]
        self.status = {k: (rows[:, C_STATUS + STATUS_NAMES.index(k)] if k in STATUS_NAMES
                           else self.extra_status[k]) for k in self.status_keys}

    def __len__(self) -> int:
        return self.rows.shape[0]

    def __repr__(self) -> str:
        mode = "stabilised" if self.stabilised else "carried"
        span = f", t = {self.t[0]:.9g} .. {self.t[-1]:.9g} s" if len(self) else ""
        return f"OutputBlock({len(self)} instants, {mode}{span})"

    def __getitem__(self, i):
        if isinstance(i, (int, np.integer)):
            n = len(self)
            if not -n <= i < n:
                raise IndexError(f"output instant {i} out of range ({n} instants)")
            extra = {k: float(v[i]) for k, v in self.extra_status.items()}
            return outputs_of_row(self.rows[i].copy(), self.stabilised, self.status_keys, extra)
        return OutputBlock(self.rows[i], self.stabilised, self.status_keys,
                           {k: v[i] for k, v in self.extra_status.items()})

    def __iter__(self):
        return (self[i] for i in range(len(self)))

    @staticmethod
    def empty(stabilised: bool) -> "OutputBlock":
        """No instant."""
        return OutputBlock(np.zeros((0, N_COL)), stabilised)

    @staticmethod
    def stack(outs: list[Outputs], stabilised: bool | None = None) -> "OutputBlock":
        """The block of ``outs`` (all of one mode: mount fields all set or all None, the same
        status keys). ``stack(list(block))`` reproduces ``block``. An empty list gives an empty
        block of mode ``stabilised`` (default carried: no mount fields)."""
        if not outs:
            return OutputBlock.empty(bool(stabilised))
        stab = outs[0].mount_angles is not None
        keys = tuple(outs[0].status)
        rows = np.full((len(outs), N_COL), np.nan)
        extra = {k: np.empty(len(outs)) for k in keys if k not in STATUS_NAMES}
        for i, o in enumerate(outs):
            if (o.mount_angles is not None) != stab or tuple(o.status) != keys:
                raise ValueError(f"OutputBlock.stack: instant {i} differs in mode or status keys from the first")
            r = rows[i]
            r[C_T] = o.t
            r[C_ANG:C_VEC] = np.concatenate([o.gimbal_angles, o.gimbal_rates, o.gimbal_axial_torques])
            vec = r[C_VEC:C_QUAT].reshape(N_VEC, 3)
            for j, name in enumerate(VEC_NAMES[:8]):
                v = getattr(o, name)
                vec[j] = 0.0 if v is None else v
            if o.rotor_rates is None:
                vec[7] = np.nan
            for j, name in enumerate(BEARING_NAMES):
                vec[8 + j] = o.bearing_torques[name]
            r[C_QUAT:C_STATUS] = o.platform_attitude
            for k, v in o.status.items():
                if k in STATUS_NAMES:
                    r[C_STATUS + STATUS_NAMES.index(k)] = v
                else:
                    extra[k][i] = v
        return OutputBlock(rows, stab, keys, extra)

    @staticmethod
    def concat(blocks: list["OutputBlock"]) -> "OutputBlock":
        """One block of the instants of ``blocks`` in order (all of one mode and status keys)."""
        if not blocks:
            raise ValueError("OutputBlock.concat needs at least one block")
        b0 = blocks[0]
        for b in blocks[1:]:
            if b.stabilised != b0.stabilised or b.status_keys != b0.status_keys:
                raise ValueError("OutputBlock.concat: blocks differ in mode or status keys")
        if len(blocks) == 1:
            return b0
        extra = {k: np.concatenate([b.extra_status[k] for b in blocks]) for k in b0.extra_status}
        return OutputBlock(np.concatenate([b.rows for b in blocks]), b0.stabilised, b0.status_keys, extra)

    def _row_columns(self) -> tuple[list[str], list[int]]:
        """Names and columns of ``Outputs.as_row`` (same keys, same order)."""
        names, cols = ["t"], [C_T]
        for i, n in enumerate(GIMBAL_NAMES):
            names += [n, n + "_rate", n + "_axial_torque"]
            cols += [C_ANG + i, C_RATE + i, C_AXIAL + i]
        for i, ax in enumerate("xyz"):
            names += ["platform_rate_" + ax, "drift_" + ax, "drift_rate_" + ax]
            cols += [C_OM + i, C_DRIFT + i, C_DRATE + i]
        for j, name in enumerate(BEARING_NAMES):
            for i, ax in enumerate("xyz"):
                names.append(f"{name}_torque_{ax}")
                cols.append(C_BEAR + 3 * j + i)
        if self.stabilised:
            names += list(MOUNT_NAMES)
            cols += [C_MOUNT, C_MOUNT + 1, C_MOUNT + 2]
        return names, cols

    def as_rows(self) -> list[dict[str, float]]:
        """``[block[i].as_row() for i in range(len(block))]`` (flat rows for CSV/JSON)."""
        names, cols = self._row_columns()
        rows = [dict(zip(names, r)) for r in self.rows[:, cols].tolist()]
        for k in self.status_keys:
            vals = self.status[k].tolist()
            for r, v in zip(rows, vals):
                r[k] = v
        return rows
