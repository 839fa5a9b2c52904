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

"""A batch command's C heap keeps what it frees (``gyro_platform.heap``); the node's does not.

Each probe is a new Python process: it allocates 64 MiB in 32 KiB blocks (glibc's heap, below its
128 KiB mmap threshold), frees them, and reports ``mallinfo2().keepcost``, the free memory left
at the top of the heap, then how many more blocks are mapped for themselves (``hblks``) once a
1 MiB block is allocated. glibc's defaults give the memory back to the kernel (keepcost < 1 MiB)
and map the 1 MiB block; with the batch setting the memory stays (≥ 32 MiB), to be reused
without page faults, and the block comes from the heap.
"""
import ctypes
import os
import subprocess
import sys
import textwrap

import pytest

from gyro_platform.heap import USER_SETTINGS

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _glibc_with_mallinfo2() -> bool:
    try:
        libc = ctypes.CDLL(None)
        return bool(libc.gnu_get_libc_version and libc.mallinfo2)
    except (OSError, AttributeError):
        return False


pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux") or not _glibc_with_mallinfo2(),
                                reason="glibc's mallopt/mallinfo2 (Linux, glibc >= 2.33) only")

PROBE = textwrap.dedent("""
    import ctypes, sys
    SETUP
    class MallInfo2(ctypes.Structure):
        _fields_ = [(n, ctypes.c_size_t) for n in ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks",
                                                     "fsmblks", "uordblks", "fordblks", "keepcost")]
    libc = ctypes.CDLL(None)
    libc.mallinfo2.restype = MallInfo2
    blocks = [bytearray(32768) for _ in range(2048)]
    del blocks
    keep, mapped = libc.mallinfo2().keepcost, libc.mallinfo2().hblks
    big = bytearray(1 << 20)
    print(keep, libc.mallinfo2().hblks - mapped)
""")


def _probe(setup: str, env: dict | None = None) -> tuple[int, int]:
    """(keepcost, blocks mapped for themselves by a 1 MiB allocation) of a new process
    that ran ``setup`` first."""
    code = PROBE.replace("SETUP", setup)
    # a clean allocator environment: Dask's LocalCluster (a sweep run in this test process earlier)
    # leaves MALLOC_TRIM_THRESHOLD_ in os.environ for its workers
    base = {k: v for k, v in os.environ.items() if k not in USER_SETTINGS}
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env={**base, **(env or {})},
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    keep, mapped = out.stdout.split()[-2:]
    return int(keep), int(mapped)


def _command(words: list[str]) -> str:
    """Setup code: ``gyro-platform WORDS --help`` through ``cli.main`` as the process's own command line."""
    return textwrap.dedent(f"""
        from gyro_platform import cli
        sys.argv = ["gyro-platform", *{words!r}, "--help"]
        try:
            cli.main()
        except SystemExit:
            pass
    """)


def _defaults(keep: int, mapped: int) -> bool:
    """glibc's defaults: the freed memory given back, a 1 MiB block mapped for itself."""
    return keep < 1 << 20 and mapped >= 1


def _kept(keep: int, mapped: int) -> bool:
    """The batch setting: the freed memory kept, a 1 MiB block taken from the heap."""
    return keep >= 32 << 20 and mapped == 0


def test_glibc_defaults_give_freed_memory_back():
    assert _defaults(*_probe("pass"))


def test_keep_freed_memory_keeps_it():
    setup = "from gyro_platform.heap import keep_freed_memory\nassert keep_freed_memory()"
    assert _kept(*_probe(setup))


def test_a_users_allocator_settings_are_left_alone():
    setup = "from gyro_platform.heap import keep_freed_memory\nassert not keep_freed_memory()"
    keep, mapped = _probe(setup, {"MALLOC_TOP_PAD_": "131072"})
    assert keep < 1 << 20


@pytest.mark.parametrize("command", ["replay", "run", "compile"])
def test_batch_commands_keep_it(command):
    assert _kept(*_probe(_command([command])))


def test_the_node_keeps_glibcs_defaults():
    assert _defaults(*_probe(_command(["node"])))
