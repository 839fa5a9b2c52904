"""gyro_platform — K. Magnus's gyro-stabilised three-gyro platform, simulated.

The physics (``params``, ``tree``, ``model``, ``effects``, ``integrators``, ``simulator``) knows
nothing of ROS; ``messages``, ``replay`` and ``scene`` map ROS 2 messages, bags and scene files
onto it; ``node`` is the thin rclpy adapter. Units are SI and radians; frames follow REP-103.
"""

__version__ = "0.1.0"
