"""scenes — scene files and the vehicle motions that drive them (ROS-free).

Holds the vehicle motion generators (``motions``: exact body rates, specific force, attitude)
and the scene schema, loader, runner and ``gyro-platform run`` command (``runner``). May import
``pipeline``, ``engine``, ``io``, ``physics`` and ``errors``.
"""
