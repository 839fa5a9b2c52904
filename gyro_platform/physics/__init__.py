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

"""physics — what the platform is and how it moves (ROS-free, numpy/numba).

Holds the parameters (``params``, NAV-1 defaults, validated, SI units), rotations, the generic
rigid-body tree (``tree``: kinematics, mass matrix, recursive Newton–Euler), the platform's
geometry and its three fidelities (``model``), the switchable effects (``effects``), the model
options (``options``: mode, fidelity, effects, integrator settings), the platform as an ODE
system over one input interval (``system``), the kinks of its right-hand side (``switching``) and
the single gimballed gyro (``gyro``), and how its kernels are compiled and cached (``jit``: the
one module that touches files, the kernel cache and the constants kept beside it) and loaded
(``kernel_loading``: their bitcode parsed only when needed, numba's runtime kept compiled;
``lean_overloads``: numba's library pieces that cost more to compile than their kernels). May import
only ``errors`` and ``signals``: it knows nothing of integrators' bookkeeping, bags or ROS.
"""
