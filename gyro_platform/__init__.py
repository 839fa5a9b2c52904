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

"""gyro_platform — K. Magnus's gyro-stabilised three-gyro platform, simulated.

Rooms, imports pointing down only (README "Architecture"): ``physics`` (what the platform is
and how it moves) ← ``engine`` (integrators, simulator) ← ``messages`` (ROS messages, ROS-free), ``reports``
(recordings, plots) ← ``bags`` (rosbag2 in and out) ← ``pipeline`` (input gate → engine → output
grid) ← ``scenes``, ``replay`` ← ``sweep``, ``bench``, ``ros`` (node core, rclpy node, DDS
transport) ← ``cli``. ``errors``, ``signals`` and ``filesystem`` are the shared leaves. The
physics and the engine know nothing of ROS. Units are SI and radians; frames follow REP-103/105.

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
