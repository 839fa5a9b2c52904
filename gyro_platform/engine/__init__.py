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

"""engine — integrate the physics in time: input samples in, outputs out (ROS-free).

Holds the input sample (``inputs.RateSample``), the output record (``outputs.Outputs``), the
integrators behind one contract with error control (the ``integrators`` package), the compiled batch
stepping (``batch``), the ``Simulator`` (state, ``push``/``push_many``, outputs), the
catalogue of hard cases (``hardcases``), how far a run near gimbal lock holds
(``conditioning``), one BLAS thread per process (``blas``) and a cold start's simulator
(``remote``: the interpreted kernels in a helper process until the compiled ones are made). May import
``physics``, ``errors`` and ``signals``.
"""
