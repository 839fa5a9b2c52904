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

"""replay — a rosbag2 bag through the simulator into an output bag (``gyro-platform replay``).

Holds the replay run (``loop``: ``ReplayConfig``, ``replay()``, the message loop, the summary),
the streamed output statistics (``stats``: ranges, drift-rate line fit, plot series) and the
command line (``command``: ``add_arguments``/``run``). Bag reading and writing are in ``bags``,
the gate → simulator → output grid in ``pipeline``. May import ``pipeline``, ``scenes``, ``bags``,
``messages``, ``reports``, ``engine``, ``physics``, ``errors``, ``signals``, ``filesystem``.
"""
from .command import add_arguments, config_from_args, NAMESPACE_RE, print_results, run
from .loop import DEFAULT_DIAGNOSTICS_RATE, DEFAULT_OUTPUT_RATE, replay, ReplayConfig, sidecar_paths
from ..bags.reader import InputBag
from ..errors import BagPathError, BagReadError, ReplayError
from ..pipeline.outcomes import apply_decision
from ..pipeline.stream import read_samples

__all__ = ["replay", "ReplayConfig", "sidecar_paths", "add_arguments", "run", "config_from_args",
           "print_results", "NAMESPACE_RE", "DEFAULT_OUTPUT_RATE", "DEFAULT_DIAGNOSTICS_RATE",
           "BagReadError", "BagPathError", "ReplayError", "InputBag", "read_samples", "apply_decision"]
