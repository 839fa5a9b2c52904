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
