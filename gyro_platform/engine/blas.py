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

"""One BLAS thread per process: the engine's matrices are small (≤ 70 × 70).

NumPy's and SciPy's OpenBLAS start a worker per core and use them for products as small as the
exponential methods' stage matrices (``scipy.linalg.expm`` on 14 × 14 blocks). After each
threaded call the idle workers spin for ~2^28 cycles (OpenBLAS's thread timeout: ~0.1 s here)
before they sleep: CPU the replay's reader and writer threads need on a 2-core machine, and
13 µs per sample of a 10-s carried run's CPU time (etd4 28 → 14 µs, measured in session 7).
:func:`limit_blas_threads` sets one thread in the BLAS libraries already loaded (NumPy's)
through ``threadpoolctl`` (what scikit-learn and joblib use) and ``OPENBLAS_NUM_THREADS=1``
for those loaded later (OpenBLAS reads it when it loads; this process's children inherit it):
SciPy's, imported only when an exponential or implicit method first needs ``scipy.linalg``
(importing it here cost every command 0.36 s of start-up).
Once per process; the command line and the ROS node call it at start. Library users decide for
their own process (the same call, or ``OPENBLAS_NUM_THREADS=1``). Imports nothing of this
package.
"""
from __future__ import annotations

import os

__all__ = ["limit_blas_threads"]

_done = False


def limit_blas_threads() -> bool:
    """Use one thread in every BLAS library loaded (NumPy's) and in those loaded later (SciPy's,
    through ``OPENBLAS_NUM_THREADS``, which OpenBLAS reads when it loads); idempotent. False
    where ``threadpoolctl`` is missing (only the environment variable is set then: only CPU is
    lost, no result differs)."""
    global _done
    if _done:
        return True
    os.environ["OPENBLAS_NUM_THREADS"] = "1"
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return False
    threadpool_limits(limits=1, user_api="blas")
    _done = True
    return True
