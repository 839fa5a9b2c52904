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

"""pipeline — input messages → time gate → simulator → output instants: the one pipeline that
the replay, the scene runs and the node core share.

Holds the input time gate (``gate``: stamps, gaps, rates, resets; its vocabulary, settings and
the one rule for a row's values in ``gate_rules``, its compiled block passes in
``gate_kernels``), gate decisions applied to a simulator and their outcome names
(``outcomes``), the per-message pipeline (``stream``: ``Pipeline``, bag samples), its chunked
path (``chunked``: blocks of rows), the output grid (``grid``) and pacing (``pacing``:
read-ahead thread, chunk sizes). May import ``bags``, ``messages``, ``engine``, ``physics``,
``errors`` and ``signals``.
"""
from .gate import TimeGate
from .gate_rules import GateConfig
from .stream import Pipeline, read_samples

__all__ = ["GateConfig", "TimeGate", "Pipeline", "read_samples"]
