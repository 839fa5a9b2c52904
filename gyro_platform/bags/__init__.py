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

"""bags — rosbag2 bags in and out (sqlite3 and mcap), through rosbags.

Holds where a bag's files are (``paths``), reading an intact bag (``reader``: ``InputBag``; fast
block readers ``fast``), salvaging a damaged one (``salvage``), the storage writers (``storage``)
and writing the output bag (``writer``: ``OutputBag``). May import ``messages`` (types, blocks,
decoding), ``physics`` (jit), ``errors``, ``signals`` and ``filesystem``.
"""
from .reader import InputBag
from .writer import OutputBag

__all__ = ["InputBag", "OutputBag"]
