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

"""prefill — fill the kernel cache once, at install, image or ``colcon build`` time.

Holds ``command`` (``gyro-platform compile``): the default scene, the node's per-message path
and a replay, each run briefly in the shipped configuration, so that numba compiles their
kernels into the shared cache (``physics.jit``) before a user's first command. May import
``ros``, ``replay``, ``scenes``, ``bench.bags`` (the synthetic Imu bag), ``messages``,
``engine``, ``physics``, ``errors``, ``signals`` and ``filesystem``.
"""
