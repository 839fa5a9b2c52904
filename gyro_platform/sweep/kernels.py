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

"""The client's compiled kernels for the workers of another machine (imports ``physics.jit``).

A Dask worker on another host (``sweep --scheduler``: a new machine, a container, an
autoscaled node) has its own kernel cache, empty at first, and its first run would compile for
~15 s (~25 CPU s on 2 cores). The client's cache, filled by the set-up step or any earlier run
of the same code, usually holds what the runs need: :func:`ship_kernels` sends this code
version's cache folder (``physics.jit.cache_files``, ~5–25 MB) as a worker plugin
(:class:`KernelShipment`), which every worker of the cluster, and every worker that joins it
later, installs before its first task (``physics.jit.add_cache_files``: only what it lacks,
never over a kernel it has). A worker of another code version (another cache folder) installs
nothing; on another CPU numba does not load the kernels and compiles as before. A local cluster
shares this machine's cache: nothing is sent. Imported only where a sweep runs (``distributed``).
"""
from __future__ import annotations

import logging
from typing import Any, Callable

from distributed import WorkerPlugin

from ..physics.jit import add_cache_files, cache_dir, cache_files, source_digest

__all__ = ["ship_kernels", "KernelShipment", "PLUGIN_NAME"]

#: the plugin's name on the cluster (a later sweep's shipment replaces an earlier one)
PLUGIN_NAME = "gyro-platform-kernels"

_log = logging.getLogger("distributed.worker")


class KernelShipment(WorkerPlugin):
    """This code version's kernel cache files (``files``: relative path → bytes; ``digest``:
    ``physics.jit.source_digest``), installed in a worker's cache when it starts taking tasks."""

    name = PLUGIN_NAME

    def __init__(self, digest: str, files: dict[str, bytes]):
        self.digest, self.files = digest, files

    def setup(self, worker: Any) -> None:
        if source_digest() != self.digest:
            _log.warning("gyro-platform: the client's kernels are of another code version (%s, here %s): "
                         "not installed; this worker compiles its own", self.digest, source_digest())
            return
        try:
            n = add_cache_files(self.files, cache_dir())
        except (OSError, ValueError) as e:
            _log.warning("gyro-platform: the client's kernels were not installed (%s); this worker compiles "
                         "its own", e)
            return
        _log.info("gyro-platform: %d kernel(s) and constant(s) from the client installed in %s", n, cache_dir())


def ship_kernels(client: Any, say: Callable[[str], None]) -> int:
    """Register this machine's kernels (of this code version) as a worker plugin on ``client``'s
    cluster; return how many files were sent (0: the cache is empty or the cluster refused them,
    which ``say`` tells in one line: the workers then compile their own)."""
    files = cache_files(cache_dir())
    if not files:
        return 0
    size = sum(map(len, files.values()))
    try:
        client.register_plugin(KernelShipment(source_digest(), files), name=PLUGIN_NAME)
    except Exception as e:  # noqa: BLE001 — the sweep runs without it; the workers compile
        say(f"warning: this machine's compiled kernels were not sent to the workers ({type(e).__name__}: {e}); "
            "their first run compiles")
        return 0
    say(f"sent this machine's compiled kernels to the workers ({len(files)} files, {size / 1e6:.1f} MB; "
        "each installs what it lacks)")
    return len(files)
