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

"""bench — benchmarks that print a table and write a plot: what accuracy costs in time.

Holds the standard benchmark scenes (``bench_scenes``), the accuracy-versus-time study
(``accuracy``), the hard-case table (``hard``), the hot-path and effects-cost figures
(``hotpath``), the consumer figures beside the kernel (``consumer``, on the bags of ``bags``),
the MuJoCo peer comparison (``peer_mujoco``) and the ``gyro-platform bench`` command (``command``).
May import every room but ``cli`` (the node core from ``ros`` for per-message figures).
"""
