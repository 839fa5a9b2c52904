"""scenes — scene files and the vehicle motions that drive them (ROS-free).

Holds the vehicle motion generators (``motions``: exact body rates, specific force, attitude),
the scene schema, validation, loading and lookup by name (``schema``), running a scene through
the pipeline and evaluating its expectations (``runner``) and the ``gyro-platform run`` command
(``command``). May import ``pipeline``, ``engine``, ``io``, ``physics`` and ``errors``.
"""
