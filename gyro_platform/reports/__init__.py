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

"""reports — what a run leaves for people: a run's summary (``summary``: its figures, names and
units, made once for the recorder and the replay), the one JSON writer of every command's files
(``jsonio``: strict JSON), the recorder (``recording``: CSV, JSON summaries, plots) and the
helper process that draws a command's plot while it runs (``plot_process``).
May import the engine's output records (``engine.outputs``), ``messages``, ``errors``,
``signals`` and ``filesystem``.
"""
from .recording import Recorder

__all__ = ["Recorder"]
