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

"""Borrowed views of a flat buffer as small C-contiguous 1-D/2-D/3-D arrays, for the compiled
kernels.

``view1(buf, offset, (d0,))``, ``view2(buf, offset, (d0, d1))`` and ``view3(buf, offset, (d0, d1,
d2))`` return the array of that shape whose first element is ``buf[offset]`` (``buf``: 1-D
C-contiguous; the view shares its memory). They do what ``buf[o:o+size].reshape(shape)`` does
without reshape's general stride search (~1 ns instead of ~18 ns per view; the kernels rebuild
some forty views per call) and **hold no reference**: the view has no meminfo, so numba's
reference counting of it, and of every view or argument made from it, is a null test instead of
a locked increment and decrement of the buffer's shared count (those atomic operations were two
thirds of the stepping kernel's time, ~20 per right-hand side called). A borrowed view is valid
while the caller holds ``buf``: a kernel passes it to the functions it calls, never returns it
or keeps it beyond the call. No bounds check: the callers' offset tables are built from the
same shapes (``engine.batch.Engine``). ``borrow(a)`` is ``a`` itself as a borrowed array (a
kernel's array arguments, before it makes views of them in its loops). Under
``NUMBA_DISABLE_JIT=1`` they are numpy's slice and reshape, and ``a``.
"""
from __future__ import annotations

import math

from numba import types
from numba.core import cgutils, config
from numba.core.imputils import impl_ret_borrowed
from numba.extending import intrinsic

__all__ = ["borrow", "view1", "view2", "view3"]


def _borrowed(context, builder, rtype, data, shape, strides, itemsize):
    """The array value of type ``rtype`` over ``data`` with no meminfo and no parent: it holds
    no reference (the codegen of :func:`_make_view`'s views and of :func:`borrow`)."""
    from numba.np.arrayobj import populate_array

    out = _array(rtype)(context, builder)
    populate_array(out, data=data, shape=shape, strides=strides, itemsize=itemsize, meminfo=None, parent=None)
    return impl_ret_borrowed(context, builder, rtype, out._getvalue())


def _array(aryty):
    """numba's array structure of ``aryty`` (codegen). numba's array code is imported where a
    kernel compiles, not with this module: a process that loads its kernels from the cache
    never needs it (~23 ms of its start, with the string code it imports)."""
    from numba.np.arrayobj import make_array

    return make_array(aryty)


def _make_view(ndim: int):
    @intrinsic
    def view(typingctx, buf, off, shape):
        if not (isinstance(buf, types.Array) and buf.ndim == 1 and buf.layout == "C"
                and isinstance(off, types.Integer) and isinstance(shape, types.UniTuple)
                and shape.count == ndim and isinstance(shape.dtype, types.Integer)):
            return None
        sig = types.Array(buf.dtype, ndim, "C")(buf, off, shape)

        def codegen(context, builder, sig, args):
            aryty, offty, shty = sig.args
            src = _array(aryty)(context, builder, args[0])
            itemsize = context.get_constant(types.intp, context.get_abi_sizeof(context.get_data_type(aryty.dtype)))
            o = context.cast(builder, args[1], offty, types.intp)
            dims = [context.cast(builder, builder.extract_value(args[2], i), shty.dtype, types.intp)
                    for i in range(ndim)]
            strides = [itemsize] * ndim
            for i in range(ndim - 2, -1, -1):
                strides[i] = builder.mul(strides[i + 1], dims[i + 1])
            return _borrowed(context, builder, sig.return_type, builder.gep(src.data, [o]),
                             cgutils.pack_array(builder, dims), cgutils.pack_array(builder, strides), src.itemsize)

        return sig, codegen

    return view


@intrinsic
def _borrow(typingctx, ary):
    if not isinstance(ary, types.Array):
        return None
    sig = ary(ary)

    def codegen(context, builder, sig, args):
        src = _array(sig.args[0])(context, builder, args[0])
        return _borrowed(context, builder, sig.return_type, src.data, src.shape, src.strides, src.itemsize)

    return sig, codegen


def _plain_view(buf, off, shape):
    """The same view by numpy (``NUMBA_DISABLE_JIT=1``: the kernels run as Python)."""
    return buf[off:off + math.prod(shape)].reshape(shape)


if config.DISABLE_JIT:
    view1 = view2 = view3 = _plain_view
    borrow = (lambda ary: ary)
else:
    borrow = _borrow
    view1 = _make_view(1)
    view2 = _make_view(2)
    view3 = _make_view(3)
