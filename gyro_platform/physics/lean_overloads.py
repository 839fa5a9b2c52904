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

"""numba library pieces that cost more to compile than the kernels that use them, made cheaper
(imports numba only; installed by ``jit`` before a process's first compile).

* A slice assignment from an array (``a[:k] = b``) raises ``ValueError`` when the shapes differ.
  numba's message names both shapes (``raise_with_shape_context``, an f-string over the shape
  tuples), so the first such kernel a process compiles also compiles numba's string machinery
  (``str`` of an integer, ``join``, ``repr``, concatenation): 2.6 s of the message decoder's
  4.8 s on this machine, 4.7 of the 28.8 CPU s of a cold replay's compile in one process.
  :func:`install` makes the message a constant (numba's own for targets without strings):
  "cannot assign slice from input of different size". The check and the exception are the
  same; a shape mismatch in a kernel is a bug, which the traceback's line still names.

What these replace only raises; no kernel computes anything differently, so kernels cached
before or after :func:`install` are interchangeable.
"""
from __future__ import annotations

from numba.core.extending import overload

__all__ = ["install", "shape_mismatch"]

MESSAGE = "cannot assign slice from input of different size"
_installed = False


def shape_mismatch(src_shapes, index_shape):
    """Raise ``ValueError(MESSAGE)`` (compiled code's stand-in for numba's
    ``raise_with_shape_context``; the shapes are integer tuples)."""
    raise ValueError(MESSAGE)


@overload(shape_mismatch)
def _ol_shape_mismatch(src_shapes, index_shape):
    def impl(src_shapes, index_shape):  # pragma: no cover - compiled
        raise ValueError(MESSAGE)
    return impl


def install() -> bool:
    """Put :func:`shape_mismatch` where numba's slice assignment looks for its error (once);
    False when this numba has no such hook (then nothing is changed)."""
    global _installed
    if _installed:
        return True
    from numba.np import arrayobj

    if not callable(getattr(arrayobj, "raise_with_shape_context", None)):
        return False
    arrayobj.raise_with_shape_context = shape_mismatch
    _installed = True
    return True
