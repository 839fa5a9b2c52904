"""bench — benchmarks that print a table and write a plot: what accuracy costs in time.

Holds the accuracy-versus-time study, the hard-case table, the hot-path and effects-cost
figures and the ``gyro-platform bench`` command. May import every room but ``cli`` (the node
core from ``ros`` for per-message figures).
"""
