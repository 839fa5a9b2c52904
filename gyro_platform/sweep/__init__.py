"""Sweeps: Monte Carlo drift budgets and fleet replays, scheduled on Dask.

Holds the sweep file schema and its seeded draws (``spec``), one run as a pure function of its
task (``runs``), the crash-safe result store and the results table (``store``), the budget plots
(``plots``) and the ``gyro-platform sweep`` command (``command``). May import ``scenes``,
``replay``, ``engine``, ``physics``, ``io`` and ``errors``; nothing imports it but ``cli`` and
``bench``. Dask (``distributed``) and pyarrow are imported only where a sweep runs.
"""
from .runs import RunTask, execute_run
from .spec import SweepSpec, SweepSpecError, load_sweep

__all__ = ["SweepSpec", "SweepSpecError", "load_sweep", "RunTask", "execute_run"]
