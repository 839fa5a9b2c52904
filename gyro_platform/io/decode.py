"""Vectorised CDR decoding of the input rows (issue 12 contract: the decode half of ``io.codec``).

:func:`decode_rates` turns the CDR bytes of ``N`` ``sensor_msgs/Imu``, ``geometry_msgs/Twist``
or ``geometry_msgs/TwistStamped`` messages into one :class:`~gyro_platform.io.blocks.RateBlock`
with numpy: the rows are joined into one buffer and every field is gathered at its byte offset
(the offsets after the header shift with the length of ``frame_id``; each row's are computed from
its own string length). Only what is sure to decode as rosbags decodes it is taken this way: a
little-endian CDR encapsulation, a well-formed UTF-8 frame_id with its terminator, the exact
size rosbags accepts (up to 3 bytes of padding) and the standard message layout (the Jazzy
definition, or a bag's own definition with the same fields). Every other row goes through
rosbags (``store.deserialize_cdr``) and :func:`gyro_platform.io.messages.reading_from_msg`, one
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

from .blocks import RateBlock, Raw, bad_stamp_detail
from .messages import IMU, TWIST, TWIST_STAMPED, Mounting, Reading, jazzy_typestore, reading_from_msg
from .typedefs import core_typestore, has_type

#: detail of an Imu row whose rate is not reported (the text of ``reading_from_msg``)
NO_RATE_DETAIL = "angular_velocity_covariance[0] = -1 (rate not reported)"

#: byte offsets after the 8-aligned start of the body that follows the header (Imu, TwistStamped)
#: or the start of the payload (Twist): (omega, force, angular cov[0], linear cov[0], body size)
_IMU = dict(omega=104, force=200, cov_w=128, cov_f=224, size=296)
_TWIST = dict(omega=24, size=48)

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
    """Fill ``rb`` for the rows with the plain little-endian layout; returns the mask of rows
    left for rosbags."""
    n = len(raws)
    lens = np.fromiter(map(len, raws), np.int64, n)
    start = np.zeros(n, np.int64)
    np.cumsum(lens[:-1], out=start[1:])
    buf = np.frombuffer(b"".join(raws), np.uint8)
    ok = lens >= 4
    ok[ok] = (buf[start[ok]] == 0) & (buf[start[ok] + 1] == 1)         # CDR_LE encapsulation
    if msgtype == TWIST:
        size = 4 + _TWIST["size"]
        ok &= (lens >= size) & (lens <= size + 3)
        rows = np.flatnonzero(ok)
        rb.omega[rows] = _f8(buf, start[rows] + 4 + _TWIST["omega"], 3)
        return ~ok
    # header: stamp.sec int32 @0, stamp.nanosec uint32 @4, frame_id: uint32 length @8, chars @12
    ok &= lens >= 16
    rows = np.flatnonzero(ok)
    p = start[rows] + 4                                                 # payload start
    slen = _u4(buf, p + 8).astype(np.int64)
    body = (12 + slen + 7) & ~7                                         # 8-aligned, payload-relative
    size = body + (_IMU["size"] if msgtype == IMU else _TWIST["size"]) + 4
    good = (slen >= 1) & (size <= lens[rows]) & (lens[rows] <= size + 3)
    term = p + 12 + slen - 1
    good[good] = buf[term[good]] == 0                                   # string terminator
    codes, names = _frame_ids(buf, p + 12, slen, good)
    good &= codes >= 0
    rows, p, body, codes = rows[good], p[good], body[good], codes[good]
    ok[:] = False
    ok[rows] = True
    rb.has_header[rows] = True
    sec = _u4(buf, p).astype(np.int64)
    sec = np.where(sec >= 2**31, sec - 2**32, sec)                      # int32
    nsec = _u4(buf, p + 4).astype(np.int64)
    rb.stamp_ns[rows] = sec * 1_000_000_000 + nsec
    frame = np.empty(n, object)
    frame[:] = rb.frame_id
    frame[rows] = np.array(names + [""], object)[codes]
    rb.frame_id = frame.tolist()
    b = p + body
    if msgtype == TWIST_STAMPED:
        rb.omega[rows] = _f8(buf, b + _TWIST["omega"], 3)
    else:
        cov_w = _f8(buf, b + _IMU["cov_w"], 1)[:, 0]
        cov_f = _f8(buf, b + _IMU["cov_f"], 1)[:, 0]
        rated = cov_w != -1.0
        rb.omega[rows[rated]] = _f8(buf, b[rated] + _IMU["omega"], 3)
        forced = rated & (cov_f != -1.0)
        rb.force[rows[forced]] = _f8(buf, b[forced] + _IMU["force"], 3)
        rb.has_force[rows[forced]] = True
        for i in rows[~rated].tolist():
            rb.set_reject(i, "no_rate", NO_RATE_DETAIL)
    for i, ns in zip(rows[nsec >= 1_000_000_000].tolist(), nsec[nsec >= 1_000_000_000].tolist()):
        _reject_bad_stamp(rb, i, ns)
    return ~ok


def _frame_ids(buf: np.ndarray, at: np.ndarray, slen: np.ndarray, good: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """frame_id of the ``good`` rows (``slen - 1`` bytes at ``at``) as codes into a list of
    distinct names (each decoded once); code -1: not a good row or not valid UTF-8."""
    codes = np.full(len(at), -1, np.int64)
    names: list[str] = []
    index: dict[bytes, int] = {}
    for L in np.unique(slen[good]).tolist():
        sel = np.flatnonzero(good & (slen == L))
        mat = _gather(buf, at[sel], L - 1)
        todo = np.ones(len(sel), bool)
        while todo.any():
            k = int(np.argmax(todo))
            if len(index) > 64:                     # many distinct names: one look-up per row
                for j in np.flatnonzero(todo).tolist():
                    codes[sel[j]] = _name_code(mat[j].tobytes(), names, index)
                break
            same = todo & (mat == mat[k]).all(axis=1)
            codes[sel[same]] = _name_code(mat[k].tobytes(), names, index)
            todo &= ~same
    return codes, names


def _name_code(raw: bytes, names: list[str], index: dict[bytes, int]) -> int:
    code = index.get(raw)
    if code is None:
        try:
            names.append(raw.decode())
            code = len(names) - 1
        except UnicodeDecodeError:
            code = -1
        index[raw] = code
    return code


def _gather(buf: np.ndarray, at: np.ndarray, nbytes: int) -> np.ndarray:
    """(len(at), nbytes) bytes of ``buf`` from each offset in ``at``: a strided view when the
    offsets are equally spaced (rows of one length, the usual topic), else a fancy-index gather."""
    m = len(at)
    if m > 1:
        step = int(at[1] - at[0])
        if step >= nbytes and int(at[-1]) + nbytes <= len(buf) and (np.diff(at) == step).all():
            return np.lib.stride_tricks.as_strided(buf[int(at[0]):], shape=(m, nbytes), strides=(step, 1))
    return buf[at[:, None] + np.arange(nbytes)]


def _f8(buf: np.ndarray, at: np.ndarray, count: int) -> np.ndarray:
    """(len(at), count) little-endian float64 at byte offsets ``at``."""
    return np.ascontiguousarray(_gather(buf, at, 8 * count)).view("<f8").reshape(len(at), count).astype(np.float64)


def _u4(buf: np.ndarray, at: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(_gather(buf, at, 4)).view("<u4").reshape(len(at))


def _reject_bad_stamp(rb: RateBlock, i: int, nanosec: int) -> None:
    rb.omega[i] = 0.0
    rb.force[i] = 0.0
    rb.has_force[i] = False
    rb.set_reject(i, "bad_message", bad_stamp_detail(nanosec))


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
            if nsec >= 1_000_000_000:       # an invalid stamp, not a later time
                rb.has_header[i], rb.stamp_ns[i], rb.frame_id[i] = True, sec * 1_000_000_000 + nsec, frame
                _reject_bad_stamp(rb, i, nsec)
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
