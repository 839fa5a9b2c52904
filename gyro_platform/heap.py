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

"""The C heap of a batch command: memory freed during the run kept for reuse (glibc ``malloc``).

A replay allocates and frees its chunks' arrays (decoded rows, output blocks, MCAP records)
chunk after chunk. glibc gives the free memory at the top of its heap back to the kernel once it
exceeds the trim threshold (128 KiB, raised by its dynamic rule as large blocks are freed) and
then takes it again page by page: a page fault and a zero-fill per 4 KiB. A batch command
(``run``, ``replay``, ``bench``, ``compile``, ``sweep``) ends within seconds to minutes, so
:func:`keep_freed_memory` sets the trim threshold to :data:`TRIM_THRESHOLD` and pads each
growth of the heap by :data:`TOP_PAD`: its pages are faulted in once. Setting either turns off
glibc's dynamic mmap threshold (which moves up to 32 MiB as large blocks are freed), and a block
above the threshold is mapped for itself and unmapped when freed (a fault per page each time,
and a TLB shootdown for the other threads): the mmap threshold is set to :data:`MMAP_THRESHOLD`,
where the dynamic rule ends. The 120 s 1 kHz MCAP replay of a new process: ~20 000 → ~16 500
page faults, 0.39 → 0.37 s (medians of seven). The node, which runs for hours, keeps glibc's
defaults. Nothing is changed where ``mallopt`` is not glibc's (musl, macOS) or where the user
tuned glibc's allocator (:data:`USER_SETTINGS`). Imports the standard library only.
"""
from __future__ import annotations

import ctypes
import os
import sys

__all__ = ["keep_freed_memory", "TRIM_THRESHOLD", "TOP_PAD", "MMAP_THRESHOLD", "USER_SETTINGS"]

#: free memory at the top of the heap kept up to this size (bytes): glibc's ``M_TRIM_THRESHOLD``
TRIM_THRESHOLD = 256 << 20
#: each growth of the heap asks the kernel for this much more (bytes, address space until
#: touched): glibc's ``M_TOP_PAD``
TOP_PAD = 64 << 20
#: blocks up to this size (bytes) come from the heap, not a mapping of their own: glibc's
#: ``M_MMAP_THRESHOLD`` at the largest value it takes on 64-bit systems (its dynamic rule's end)
MMAP_THRESHOLD = 32 << 20
#: environment variables by which a user tunes glibc's allocator: then it is left as set
USER_SETTINGS = ("MALLOC_TRIM_THRESHOLD_", "MALLOC_TOP_PAD_", "MALLOC_MMAP_THRESHOLD_", "GLIBC_TUNABLES")

_M_TRIM_THRESHOLD = -1      # glibc's malloc.h
_M_TOP_PAD = -2
_M_MMAP_THRESHOLD = -3


def keep_freed_memory() -> bool:
    """Set glibc's trim threshold, top pad and mmap threshold for this process (see module doc);
    True when all three are set."""
    if not sys.platform.startswith("linux") or any(k in os.environ for k in USER_SETTINGS):
        return False
    try:
        libc = ctypes.CDLL(None)        # the symbols of this process: its C library's
        libc.gnu_get_libc_version       # glibc only (musl has a mallopt that does nothing)
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    return all([mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD) == 1, mallopt(_M_TOP_PAD, TOP_PAD) == 1,
                mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD) == 1])
