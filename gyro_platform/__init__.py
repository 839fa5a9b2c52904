"""gyro_platform — K. Magnus's gyro-stabilised three-gyro platform, simulated.

Rooms, imports pointing down only (README "Architecture"): ``physics`` (what the platform is
and how it moves) ← ``engine`` (integrators, simulator) ← ``io`` (ROS messages, input gate,
bags, recordings) ← ``pipeline`` (messages → gate → engine → outputs) ← ``scenes``, ``replay``
← ``sweep``, ``bench``, ``ros`` (node core, rclpy node, DDS transport) ← ``cli``. The physics
and the engine know nothing of ROS. Units are SI and radians; frames follow REP-103/105.

Public API, re-exported here (imported on first use, so that ``gyro-platform --help`` stays
fast): ``Simulator``, ``ModelOptions``, ``RateSample``, ``NAV1``, ``PlatformParams``,
``SimulationError``, ``InputError``, ``INTEGRATORS``, ``load_scene``, ``run_scene``, ``replay``.
"""
from importlib import import_module

__version__ = "0.1.0"

_EXPORTS = {
    "Simulator": ".engine.simulator", "ModelOptions": ".physics.options", "RateSample": ".engine.inputs",
    "NAV1": ".physics.params", "PlatformParams": ".physics.params", "SimulationError": ".errors",
    "InputError": ".errors", "INTEGRATORS": ".engine.integrators", "load_scene": ".scenes.schema",
    "run_scene": ".scenes.runner", "replay": ".replay",
}
__all__ = [*_EXPORTS, "__version__"]


def __getattr__(name: str):
    if name in _EXPORTS:
        return getattr(import_module(_EXPORTS[name], __name__), name)
    raise AttributeError(f"module 'gyro_platform' has no attribute {name!r}")


def __dir__():
    return sorted(__all__)
