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

"""The kernels' borrowed views (``engine.views``): compiled, they are the slices and reshapes
numpy makes of the same buffer — same elements, shapes and strides, writes landing in the buffer
— also when passed to a function the kernel calls, and ``borrow`` is its argument unchanged."""
from numba import njit
import numpy as np

from gyro_platform.engine.views import borrow, view1, view2, view3


@njit
def _fill(v, base):
    """Write base + the flat index into every element of a 1-, 2- or 3-D view (a called function:
    the view crosses a call as the kernels' views do)."""
    flat = v.reshape(v.size)
    for i in range(flat.size):
        flat[i] = base + i
    return v.sum()


@njit
def _views(buf, o1, n1, o2, d0, d1, o3, e0, e1, e2):
    a = view1(buf, o1, (n1,))
    b = view2(buf, o2, (d0, d1))
    c = view3(buf, o3, (e0, e1, e2))
    s = _fill(a, 1000.0) + _fill(b, 2000.0) + _fill(c, 3000.0)
    # a row of a view and an element through borrow: the same memory
    row = b[d0 - 1]
    row[0] = -1.0
    borrow(buf)[0] = -2.0
    return s, a.shape[0], b.shape, c.shape, b.strides, c.strides


def test_views_are_the_buffer_slices_numpy_makes():
    buf = np.zeros(64)
    s, n1, bs, cs, b_str, c_str = _views(buf, 1, 5, 10, 3, 4, 30, 2, 3, 4)
    ref = np.zeros(64)
    ref[1:6] = 1000.0 + np.arange(5)
    ref[10:22] = 2000.0 + np.arange(12)
    ref[30:54] = 3000.0 + np.arange(24)
    assert s == ref.sum()
    ref[10:22].reshape(3, 4)[2, 0] = -1.0
    ref[0] = -2.0
    np.testing.assert_array_equal(buf, ref)                 # every write where numpy's views put it
    assert (n1, bs, cs) == (5, (3, 4), (2, 3, 4))
    assert b_str == ref[10:22].reshape(3, 4).strides and c_str == ref[30:54].reshape(2, 3, 4).strides


def test_an_int_buffer_and_a_borrowed_2d_argument():
    ib = np.arange(40, dtype=np.int64)

    @njit
    def take(ib, m):
        v = view2(ib, 8, (4, 5))
        mb = borrow(m)
        acc = 0
        for i in range(4):
            for j in range(5):
                acc += v[i, j] * mb[i, j]
        return acc

    m = np.arange(20, dtype=np.int64).reshape(4, 5)
    assert take(ib, m) == int((ib[8:28].reshape(4, 5) * m).sum())
    np.testing.assert_array_equal(ib, np.arange(40))        # read only: the buffer unchanged
