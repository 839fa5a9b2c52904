"""gyro_platform — K. Magnus's gyro-stabilised three-gyro platform, simulated.

The physics (``params``, ``tree``, ``model``, ``effects``, ``integrators``, ``simulator``) knows
nothing of ROS; ``messages``, ``replay`` and ``scene`` map ROS 2 messages, bags and scene files
onto it; ``node`` is the thin rclpy adapter. Units are SI and radians; frames follow REP-103.

Public API, re-exported here (imported on first use, so that ``gyro-platform --help`` stays
fast): ``Simulator``, ``ModelOptions``, ``RateSample``, ``NAV1``, ``PlatformParams``,
``SimulationError``, ``InputError``, ``INTEGRATORS``.
"""
from importlib import import_module

__version__ = "0.1.0"

_EXPORTS = {
    "Simulator": ".simulator", "ModelOptions": ".options", "RateSample": ".inputs", "NAV1": ".params",
    "PlatformParams": ".params", "SimulationError": ".errors", "InputError": ".errors",
    "INTEGRATORS": ".integrators",
}
__all__ = [*_EXPORTS, "__version__"]


def __getattr__(name: str):
    if name in _EXPORTS:
        return getattr(import_module(_EXPORTS[name], __name__), name)
    raise AttributeError(f"module 'gyro_platform' has no attribute {name!r}")


def __dir__():
    return sorted(__all__)
