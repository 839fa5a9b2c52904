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

"""Vectorised CDR decoding of the input rows (issue 12 contract: the decode half of ``io.codec``).

:func:`decode_rates` turns the CDR bytes of ``N`` ``sensor_msgs/Imu``, ``geometry_msgs/Twist``
or ``geometry_msgs/TwistStamped`` messages into one :class:`~gyro_platform.messages.blocks.RateBlock`
in one compiled pass (numba, ``nogil``) over the rows in one buffer (joined, or in place in an
MCAP chunk: :class:`~gyro_platform.messages.blocks.RawRows`): every field is read at its byte offset
(the offsets after the header shift with the length of ``frame_id``; each row's are computed from
its own string length) and each distinct ``frame_id`` is decoded once.
Only what is sure to decode as rosbags decodes it is taken this way: a little-endian CDR
encapsulation, a well-formed UTF-8 frame_id with its terminator, the exact size rosbags accepts
(up to 3 bytes of padding) and the standard message layout (the Jazzy definition, or a bag's own
definition with the same fields). Every other row goes through
rosbags (``store.deserialize_cdr``) and :func:`gyro_platform.messages.reading_from_msg`, one
by one; a row rosbags cannot decode is rejected ``bad_message``.

Semantics per row are those of ``reading_from_msg`` (before any mounting: values in the sensor
frame): Imu ``angular_velocity_covariance[0] == -1`` → ``no_rate``; ``linear_acceleration_
covariance[0] == -1`` → no specific force; Twist has no header (stamp 0, frame ""); values
pass through as they are (NaN/Inf and range are the gate's). In addition, a header stamp with
``nanosec >= 1e9`` is not a valid ``builtin_interfaces/Time`` (issue 17): ``bad_message``.
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from .blocks import bad_stamp_detail, RateBlock, Raw, RawRows, readonly, row_lens
from .inputs import Mounting, Reading, reading_from_msg
from .names import IMU, jazzy_typestore, TWIST, TWIST_STAMPED
from .typedefs import core_typestore, has_type
from ..physics.jit import njit

#: detail of an Imu row whose rate is not reported (the text of ``reading_from_msg``)
NO_RATE_DETAIL = "angular_velocity_covariance[0] = -1 (rate not reported)"

#: byte offsets after the 8-aligned start of the body that follows the header (Imu, TwistStamped)
#: or the start of the payload (Twist): (omega, force, angular cov[0], linear cov[0], body size)
IMU_OMEGA, IMU_FORCE, IMU_COV_W, IMU_COV_F, IMU_SIZE = 104, 200, 128, 224, 296
TWIST_OMEGA, TWIST_SIZE = 24, 48

#: a mounting that never rotates a header frame (its vehicle frame is no frame_id a bag holds):
#: reading_from_msg then gives Imu/TwistStamped values in the sensor frame
_SENSOR_FRAME = Mounting(vehicle_frame="\0sensor frame")

_LAYOUT_OK: dict[tuple[int, str], tuple[Any, bool]] = {}   # (id(store), type) -> (store, same layout)


def decode_rates(msgtype: str, raws: Sequence[Raw], store: Any = None) -> RateBlock:
    """CDR bytes of ``msgtype`` messages → :class:`RateBlock` (sensor frame; ``identity`` all
    False until ``Mounting.rotate_block``). ``store``: the rosbags typestore that decodes this
    connection (``InputBag.store_for``), default Jazzy (``typedefs.core_typestore`` for the
    types it holds). Never raises on bad data: such rows are rejected ``bad_message`` with
    rosbags' error in ``detail``."""
    n = len(raws)
    rb = RateBlock.zeros(n)
    if store is None:
        store = core_typestore() if has_type(msgtype) else jazzy_typestore()
    if n == 0:
        return rb
    slow = np.ones(n, bool)
    if msgtype in (IMU, TWIST, TWIST_STAMPED) and standard_layout(store, msgtype):
        slow = _decode_fast(msgtype, raws, rb)
    for i in np.flatnonzero(slow).tolist():
        _decode_one(msgtype, raws[i], store, rb, i)
    return rb


def _decode_fast(msgtype: str, raws: Sequence[Raw], rb: RateBlock) -> np.ndarray:
    """Fill ``rb`` for the rows with the plain little-endian layout (one compiled pass,
    :func:`_decode_rows`); returns the mask of rows left for rosbags."""
    n = len(raws)
    if isinstance(raws, RawRows):                 # in place in their buffer (an MCAP chunk)
        buf, beg, lens = raws.buf, raws.beg, raws.lens()
    else:
        lens = row_lens(raws)
        buf = np.frombuffer(b"".join(raws), np.uint8)
        beg = np.zeros(n, np.int64)
        np.cumsum(lens[:-1], out=beg[1:])
    kind = _KINDS[msgtype]
    ok, code, first, nsec, no_rate = _decode_rows(readonly(buf), beg, lens, kind, rb.stamp_ns, rb.has_header, rb.omega,
                                                  rb.force, rb.has_force)
    if kind != _KIND_TWIST:
        names = []
        for k in range(len(first)):           # each distinct frame_id decoded once
            at, ln = int(first[k, 0]), int(first[k, 1])
            try:
                names.append(buf[at:at + ln].tobytes().decode())
            except UnicodeDecodeError:        # not UTF-8: those rows go to rosbags
                names.append(None)
        bad = [k for k, name in enumerate(names) if name is None]
        if bad:                               # back to the zeros of RateBlock.zeros for rosbags
            rows = np.flatnonzero(ok & np.isin(code, bad))
            ok[rows] = False
            rb.has_header[rows], rb.stamp_ns[rows], rb.has_force[rows] = False, 0, False
            rb.omega[rows], rb.force[rows] = 0.0, 0.0
        if len(names) == 1 and ok.all():      # the usual topic: one frame_id
            rb.frame_id = [names[0]] * n
        else:
            rows = np.flatnonzero(ok)
            frame = np.empty(n, object)
            frame[:] = rb.frame_id
            frame[rows] = np.array([x or "" for x in names] + [""], object)[code[rows]]
            rb.frame_id = frame.tolist()
        for i in np.flatnonzero(ok & no_rate).tolist():
            rb.set_reject(i, "no_rate", NO_RATE_DETAIL)
        for i in np.flatnonzero(ok & ((nsec >= 1_000_000_000) | (rb.stamp_ns < 0))).tolist():
            _reject_bad_stamp(rb, i, int(rb.stamp_ns[i] - nsec[i]) // 1_000_000_000, int(nsec[i]))
    return ~ok


_KIND_IMU, _KIND_TWIST_STAMPED, _KIND_TWIST = 0, 1, 2
_KINDS = {IMU: _KIND_IMU, TWIST_STAMPED: _KIND_TWIST_STAMPED, TWIST: _KIND_TWIST}


@njit(cache=True, nogil=True)
def _decode_rows(buf, beg, lens, kind, stamp_ns, has_header, omega, force, has_force):  # pragma: no cover - compiled
    """One pass over the rows ``buf[beg[i]:beg[i] + lens[i]]``: the rows of the plain
    little-endian layout (Imu ``kind`` 0, TwistStamped 1, Twist 2) filled in place. Returns
    (ok mask, frame_id code per row (-1: none), (distinct codes, 2) first byte offset and length
    of each frame_id, header nanosec per row, Imu rows whose rate is not reported)."""
    n = lens.shape[0]
    ok = np.zeros(n, np.bool_)
    no_rate = np.zeros(n, np.bool_)
    code = np.full(n, -1, np.int64)
    nsec = np.zeros(n, np.int64)
    first = np.empty((min(n, 64) + 1, 2), np.int64)
    nfirst = 0
    prev_at, prev_len, prev_code = -1, -1, -1
    size = IMU_SIZE if kind == 0 else TWIST_SIZE
    # aligned scratch: a row's header and body are copied here and read as uint32 / float64
    # (per-row views copied from index 0 compile to vector copies; reading each field through
    # a view of the unaligned buffer cost ~470 ns per Imu row, this ~80)
    hb = np.zeros(16, np.uint8)
    hu = hb.view(np.uint32)
    sb = np.zeros(IMU_SIZE + 8, np.uint8)
    sf = sb.view(np.float64)
    for i in range(n):
        s0, L = beg[i], lens[i]
        if L < 4 or buf[s0] != 0 or buf[s0 + 1] != 1:           # CDR_LE encapsulation
            continue
        p = s0 + 4
        if kind == 2:
            if L < 4 + TWIST_SIZE or L > 4 + TWIST_SIZE + 3:
                continue
            src = buf[p:p + TWIST_SIZE]
            for k in range(TWIST_SIZE):
                sb[k] = src[k]
            ok[i] = True
            for k in range(3):
                omega[i, k] = sf[TWIST_OMEGA // 8 + k]
            continue
        if L < 16:
            continue
        src = buf[p:p + 12]
        for k in range(12):
            hb[k] = src[k]
        slen = np.int64(hu[2])
        body = (12 + slen + 7) & ~7
        total = body + size + 4
        if slen < 1 or total > L or L > total + 3 or buf[p + 12 + slen - 1] != 0:
            continue
        at, ln = p + 12, slen - 1
        name = buf[at:at + ln]
        c = -1
        if ln == prev_len and prev_code >= 0:
            c = prev_code
            other = buf[prev_at:prev_at + ln]
            for k in range(ln):
                if name[k] != other[k]:
                    c = -1
                    break
        if c < 0:
            for j in range(nfirst):
                if first[j, 1] == ln:
                    other = buf[first[j, 0]:first[j, 0] + ln]
                    same = True
                    for k in range(ln):
                        if name[k] != other[k]:
                            same = False
                            break
                    if same:
                        c = j
                        break
        if c < 0:
            if nfirst == first.shape[0]:
                grown = np.empty((2 * nfirst, 2), np.int64)
                grown[:nfirst] = first
                first = grown
            first[nfirst, 0], first[nfirst, 1] = at, ln
            c = nfirst
            nfirst += 1
        prev_at, prev_len, prev_code = at, ln, c
        ok[i] = True
        code[i] = c
        has_header[i] = True
        sec = np.int64(hu[0])
        if sec >= 2 ** 31:
            sec -= 2 ** 32
        ns = np.int64(hu[1])
        nsec[i] = ns
        stamp_ns[i] = sec * 1_000_000_000 + ns
        src = buf[p + body:p + body + size]
        for k in range(size):
            sb[k] = src[k]
        if kind == 1:
            for k in range(3):
                omega[i, k] = sf[TWIST_OMEGA // 8 + k]
            continue
        if sf[IMU_COV_W // 8] != -1.0:                                 # rate reported
            for k in range(3):
                omega[i, k] = sf[IMU_OMEGA // 8 + k]
            if sf[IMU_COV_F // 8] != -1.0:                             # specific force reported
                for k in range(3):
                    force[i, k] = sf[IMU_FORCE // 8 + k]
                has_force[i] = True
        else:
            no_rate[i] = True
    return ok, code, first[:nfirst], nsec, no_rate


def _reject_bad_stamp(rb: RateBlock, i: int, sec: int, nanosec: int) -> None:
    rb.omega[i] = 0.0
    rb.force[i] = 0.0
    rb.has_force[i] = False
    rb.set_reject(i, "bad_message", bad_stamp_detail(sec, nanosec))


def _decode_one(msgtype: str, raw: Raw, store: Any, rb: RateBlock, i: int) -> None:
    """Row ``i`` through rosbags and ``reading_from_msg`` (sensor frame)."""
    try:
        msg = store.deserialize_cdr(raw, msgtype)
    except Exception as e:
        rb.set_reject(i, "bad_message", f"cannot decode {msgtype}: {e}")
        return
    if msgtype == TWIST:       # no header, no frame: the values as they are (reading_from_msg
        try:                   # would multiply them by base_link's identity: inf → nan)
            rb.omega[i] = (float(msg.angular.x), float(msg.angular.y), float(msg.angular.z))
        except (AttributeError, TypeError, ValueError) as e:
            rb.set_reject(i, "bad_message", f"malformed message: {e}")
        return
    header = getattr(msg, "header", None)
    if header is not None:
        try:
            sec, nsec, frame = int(header.stamp.sec), int(header.stamp.nanosec), str(header.frame_id)
        except (AttributeError, TypeError, ValueError):
            pass
        else:
            if bad_stamp_detail(sec, nsec) is not None:      # an invalid stamp, not another time
                rb.has_header[i], rb.stamp_ns[i], rb.frame_id[i] = True, sec * 1_000_000_000 + nsec, frame
                _reject_bad_stamp(rb, i, sec, nsec)
                return
    r = reading_from_msg(msg, _SENSOR_FRAME)
    if header is not None and r.stamp_ns is not None:
        rb.has_header[i] = True
        rb.stamp_ns[i] = r.stamp_ns
        rb.frame_id[i] = r.frame_id
    if not isinstance(r, Reading):
        rb.set_reject(i, r.reason, r.detail)
        return
    rb.omega[i] = r.omega
    if r.specific_force is not None:
        rb.force[i] = r.specific_force
        rb.has_force[i] = True


def standard_layout(store: Any, msgtype: str) -> bool:
    """True when ``store`` defines ``msgtype`` (and every type inside it) with the fields of the
    Jazzy definition, i.e. the byte layout the vectorised decoder assumes."""
    key = (id(store), msgtype)
    hit = _LAYOUT_OK.get(key)
    if hit is None or hit[0] is not store:
        ref = core_typestore() if has_type(msgtype) else jazzy_typestore()
        hit = _LAYOUT_OK[key] = (store, _same_fields(store, ref, msgtype, set()))
    return hit[1]


def _same_fields(a: Any, b: Any, name: str, seen: set[str]) -> bool:
    if name in seen:
        return True
    seen.add(name)
    try:
        fa, fb = a.get_msgdef(name).fields, b.get_msgdef(name).fields
    except Exception:
        return False
    if fa != fb:
        return False
    return all(_same_fields(a, b, desc[1], seen) for _, desc in fa if desc[0].name == "NAME")
