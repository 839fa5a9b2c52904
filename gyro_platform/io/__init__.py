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

"""io — the edge to the outside world: ROS 2 messages, the input time gate, bags, recordings.

Holds the ROS message mapping (``messages``: inputs → readings, outputs → messages, topics,
diagnostics, TF), the input time gate (``gate``: stamps, gaps, rates, resets), the recorder
(``recording``: CSV, JSON summaries, plots; ``plot_process``: the helper process that draws a
command's plot while it runs) and the URDF generated from the parameters
(``urdf``), and rosbag2 bags: where their files are (``bag_paths``), reading an intact bag
(``bag_reader``; fast block readers ``bag_fast``), salvaging a damaged one (``bag_salvage``),
writing the output bag (``bag_writer``); the fast path's array blocks (``blocks``: RowChunk,
RateBlock), the vectorised input decoder (``decode``) and the Jazzy definitions of the types it
reads and writes (``typedefs``: a small typestore). May import ``physics`` (parameters,
geometry), the engine's public records (``engine.inputs``, ``engine.outputs``) and ``errors`` —
never integrators or the simulator.
"""
