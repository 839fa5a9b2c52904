"""bench — benchmarks that print a table and write a plot: what accuracy costs in time.

Holds the standard benchmark scenes (``bench_scenes``), the accuracy-versus-time study
(``accuracy``), the hard-case table (``hard``), the hot-path and effects-cost figures
(``hotpath``), the consumer figures beside the kernel (``consumer``, on the bags of ``bags``),
the MuJoCo peer comparison (``peer_mujoco``) and the ``gyro-platform bench`` command (``command``). May import every room but
``cli`` (the node core from ``ros`` for per-message figures).
"""
