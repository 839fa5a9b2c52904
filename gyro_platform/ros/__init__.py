"""ros — the platform as a ROS 2 node, on rclpy or on plain DDS.

Holds the transport-independent node core and parameter schema (``core``), the rclpy node
(``node``, the only module that imports rclpy), the plain-DDS transport (``dds``, cyclonedds),
the ``gyro-platform node`` command (``command``) and the launch file's argument logic
(``launch_setup``). May import everything below it (``replay``, ``pipeline``, ``scenes``,
``engine``, ``io``, ``physics``, ``errors``); nothing imports it but ``cli`` and ``bench``.
"""
