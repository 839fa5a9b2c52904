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
at the top of the heap. glibc's defaults give it back to the kernel (keepcost < 1 MiB); with
the batch setting it stays (≥ 32 MiB), to be reused without page faults.
"""
import ctypes
import os
import subprocess
import sys
import textwrap

import pytest

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
    print(libc.mallinfo2().keepcost)
""")


def _keepcost(setup: str, env: dict | None = None) -> int:
    code = PROBE.replace("SETUP", setup)
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env={**os.environ, **(env or {})},
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    return int(out.stdout.split()[-1])


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


def test_glibc_defaults_give_freed_memory_back():
    assert _keepcost("pass") < 1 << 20


def test_keep_freed_memory_keeps_it():
    setup = "from gyro_platform.heap import keep_freed_memory\nassert keep_freed_memory()"
    assert _keepcost(setup) >= 32 << 20


def test_a_users_allocator_settings_are_left_alone():
    setup = "from gyro_platform.heap import keep_freed_memory\nassert not keep_freed_memory()"
    assert _keepcost(setup, {"MALLOC_TOP_PAD_": "131072"}) < 1 << 20


@pytest.mark.parametrize("command", ["replay", "run", "compile"])
def test_batch_commands_keep_it(command):
    assert _keepcost(_command([command])) >= 32 << 20


def test_the_node_keeps_glibcs_defaults():
    assert _keepcost(_command(["node"])) < 1 << 20
