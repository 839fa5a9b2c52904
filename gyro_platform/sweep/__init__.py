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

"""Sweeps: Monte Carlo drift budgets and fleet replays, scheduled on Dask.

Holds the sweep file schema and its seeded draws (``spec``), one run as a pure function of its
task (``runs``), the crash-safe result store and the results table (``store``), the budget plots
(``plots``), this machine's compiled kernels for another machine's workers (``kernels``), where
local worker processes log (``worker_log``) and the ``gyro-platform sweep`` command
(``command``). May import ``scenes``,
``replay``, ``pipeline``, ``bags``, ``messages``, ``reports``, ``engine``, ``physics``, ``errors``,
``signals`` and ``filesystem``; nothing imports it but ``cli`` and
``bench``. Dask (``distributed``) and pyarrow are imported only where a sweep runs.
"""
from .runs import execute_run, RunTask
from .spec import load_sweep, SweepSpec, SweepSpecError

__all__ = ["SweepSpec", "SweepSpecError", "load_sweep", "RunTask", "execute_run"]
