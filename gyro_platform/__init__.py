"""gyro_platform — K. Magnus's gyro-stabilised three-gyro platform, simulated.

The physics (``params``, ``tree``, ``model``, ``effects``, ``integrators``, ``simulator``) knows
nothing of ROS; ``messages``, ``replay`` and ``scene`` map ROS 2 messages, bags and scene files
onto it; ``node`` is the thin rclpy adapter. Units are SI and radians; frames follow REP-103.

Public API (re-exported here): ``Simulator``, ``ModelOptions``, ``RateSample``, ``NAV1``,
``PlatformParams``, ``SimulationError``, ``InputError``, ``INTEGRATORS``.
"""

__version__ = "0.1.0"

from .errors import InputError, SimulationError
from .inputs import RateSample
from .integrators import INTEGRATORS
from .options import ModelOptions
from .params import NAV1, PlatformParams
from .simulator import Simulator

__all__ = ["Simulator", "ModelOptions", "RateSample", "NAV1", "PlatformParams", "SimulationError", "InputError",
           "INTEGRATORS", "__version__"]
