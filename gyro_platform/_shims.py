"""TEMPORARY (session 3, helper H6): slow but exact stand-ins for the fast-path contract's pieces
(/work/notes/fast_contract.md) built on today's per-message code, so that the chunked pipeline
can be written and tested before the real modules exist. The lead deletes this module at merge
and points the one import block of ``pipeline.py`` at the real modules:

========================  ==========================================  ==========================
shim                      real piece                                  owner
========================  ==========================================  ==========================
RowChunk, RateBlock       io/blocks.py                                H3
bag_chunks(bag, ...)      InputBag.chunks (unbound: same signature)   H3
decode_rates              io/decode.py (io.codec)                     H3
rotate_block(m, rb)       Mounting.rotate_block                       H5
GateBlock, offer_block    io/gate.py (TimeGate.offer_block)           H5
push_block(sim, ...)      Simulator.push_block                        H1
OutputBlock               engine/outputs.py                           H2
encode_outputs            io/encode.py (io.codec)                     H4
write_many, copy_chunk    OutputBag.write_many / copy_chunk           H4
========================  ==========================================  ==========================

Every function here is the reference path of today in a loop: rosbags deserialisation +
``reading_from_msg``, ``TimeGate.offer``, ``Simulator.push`` + ``outputs()``,
``output_messages`` + ``serialize_cdr``, ``OutputBag.write_raw``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Iterator

import numpy as np

from .engine.inputs import RateSample
from .engine.outputs import BEARING_NAMES, Outputs
from .errors import BagReadError, SimulationError
from .io import messages as msgs
from .io.gate import ACCEPT_REASONS, DROP_REASONS, RESET_REASONS, Action, TimeGate
from .io.messages import Mounting, Reading, Rejected

# ---- io/blocks.py (H3) ---------------------------------------------------------------------
REJECT_REASONS = ("no_rate", "unknown_frame", "bad_message")


@dataclass
class RowChunk:
    """Rows of a bag in bag order: connection id, record time (ns), CDR bytes."""

    conn_id: np.ndarray
    ts: np.ndarray
    raws: list

    def __len__(self) -> int:
        return len(self.ts)


@dataclass
class RateBlock:
    """Decoded input rows (see the contract): sensor frame until ``rotate_block``."""

    stamp_ns: np.ndarray
    has_header: np.ndarray
    frame_id: list
    omega: np.ndarray
    force: np.ndarray
    has_force: np.ndarray
    reject: np.ndarray
    detail: dict = field(default_factory=dict)
    identity: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.stamp_ns)


def bag_chunks(bag: Any, max_rows: int = 4096, input_only: bool = False) -> Iterator[RowChunk]:
    """``InputBag.chunks``: the rows of ``bag.messages()`` in chunks; on a read error the rows
    read before it are yielded first, then the BagReadError is raised."""
    ids, ts, raws = [], [], []

    def flush() -> RowChunk:
        c = RowChunk(np.array(ids, dtype=np.int64), np.array(ts, dtype=np.int64), list(raws))
        ids.clear(), ts.clear(), raws.clear()
        return c

    try:
        for conn, t, raw in bag.messages(input_only=input_only):
            ids.append(conn.id), ts.append(t), raws.append(raw)
            if len(ts) >= max_rows:
                yield flush()
    except BagReadError:
        if ts:
            yield flush()
        raise
    if ts:
        yield flush()


class _NoMounting(Mounting):
    """Every frame unknown and taken as is: ``reading_from_msg`` without rotation."""

    def matrix(self, frame_id: str) -> None:
        return None


_RAW = _NoMounting()


def decode_rates(msgtype: str, raws: list, store: Any = None) -> RateBlock:
    """CDR rows of one input type → RateBlock in the sensor frame (rosbags + reading_from_msg)."""
    store = store if store is not None else msgs.jazzy_typestore()
    n = len(raws)
    rb = RateBlock(np.zeros(n, np.int64), np.zeros(n, bool), [""] * n, np.zeros((n, 3)), np.zeros((n, 3)),
                   np.zeros(n, bool), np.zeros(n, np.int8), {})
    for i, raw in enumerate(raws):
        try:
            msg = store.deserialize_cdr(raw, msgtype)
        except Exception as e:
            rb.reject[i] = 1 + REJECT_REASONS.index("bad_message")
            rb.detail[i] = f"cannot decode {msgtype}: {e}"
            continue
        r = msgs.reading_from_msg(msg, _RAW)
        rb.has_header[i] = r.stamp_ns is not None
        rb.stamp_ns[i] = r.stamp_ns or 0
        rb.frame_id[i] = r.frame_id if r.stamp_ns is not None else ""
        if isinstance(r, Rejected):
            rb.reject[i] = 1 + REJECT_REASONS.index(r.reason)
            rb.detail[i] = r.detail
            continue
        rb.omega[i] = r.omega
        if r.specific_force is not None:
            rb.force[i], rb.has_force[i] = r.specific_force, True
    return rb


# ---- io/messages.py (H5) -------------------------------------------------------------------
def rotate_block(mounting: Mounting, rb: RateBlock) -> RateBlock:
    """``Mounting.rotate_block``: rows into base_link (``mat @ v`` as ``reading_from_msg``);
    unknown frames flagged ``identity`` or rejected ``unknown_frame`` by the policy."""
    omega, force, reject, detail = rb.omega.copy(), rb.force.copy(), rb.reject.copy(), dict(rb.detail)
    identity = np.zeros(len(rb), bool)
    for i in range(len(rb)):
        if reject[i]:
            continue
        frame = rb.frame_id[i] if rb.has_header[i] else mounting.vehicle_frame
        mat = mounting.matrix(frame)
        if mat is None:
            if mounting.unknown_frame == "reject":
                reject[i] = 1 + REJECT_REASONS.index("unknown_frame")
                detail[i] = f"no mounting configured for frame_id {frame!r}"
            else:
                identity[i] = True
            continue
        omega[i] = mat @ rb.omega[i]
        if rb.has_force[i]:
            force[i] = mat @ rb.force[i]
    return RateBlock(rb.stamp_ns, rb.has_header, rb.frame_id, omega, force, rb.has_force, reject, detail, identity)


# ---- io/gate.py (H5) -----------------------------------------------------------------------
ACCEPT, DROP, RESET = 0, 1, 2
ALL_REASONS = DROP_REASONS + RESET_REASONS + ACCEPT_REASONS
_ACTION = {Action.ACCEPT: ACCEPT, Action.DROP: DROP, Action.RESET: RESET}


@dataclass
class GateBlock:
    """Decisions on N rows: action (ACCEPT/DROP/RESET), reason (index into ALL_REASONS), t (s
    since the origin, NaN if dropped), stamp_ns (chosen time, -1 if none)."""

    action: np.ndarray
    reason: np.ndarray
    t: np.ndarray
    stamp_ns: np.ndarray

    def __len__(self) -> int:
        return len(self.action)


def reading_of(rb: RateBlock, i: int) -> Reading | Rejected:
    """Row ``i`` of a rotated RateBlock as ``reading_from_msg`` would have made it."""
    stamp = int(rb.stamp_ns[i]) if rb.has_header[i] else None
    if rb.reject[i]:
        return Rejected(REJECT_REASONS[rb.reject[i] - 1], rb.detail.get(i, ""), stamp, rb.frame_id[i])
    return Reading(rb.omega[i].copy(), rb.force[i].copy() if rb.has_force[i] else None, stamp, rb.frame_id[i],
                   bool(rb.identity[i]) if rb.identity is not None else False)


def offer_block(gate: TimeGate, rb: RateBlock, receive_ns: np.ndarray) -> GateBlock:
    """``TimeGate.offer_block``: ``gate.offer`` row by row."""
    n = len(rb)
    gb = GateBlock(np.zeros(n, np.int8), np.zeros(n, np.int16), np.full(n, np.nan), np.full(n, -1, np.int64))
    for i in range(n):
        d = gate.offer(reading_of(rb, i), int(receive_ns[i]))
        gb.action[i] = _ACTION[d.action]
        gb.reason[i] = ALL_REASONS.index(d.reason)
        if d.sample is not None:
            gb.t[i] = d.sample.t
        if d.stamp_ns is not None:
            gb.stamp_ns[i] = d.stamp_ns
    return gb


# ---- engine/outputs.py (H2) ----------------------------------------------------------------
_OPTIONAL = ("mount_angles", "mount_rates", "servo_torque")


@dataclass
class OutputBlock:
    """Outputs at K instants as arrays (the fields of ``Outputs``)."""

    t: np.ndarray
    gimbal_angles: np.ndarray
    gimbal_rates: np.ndarray
    gimbal_axial_torques: np.ndarray
    platform_rate: np.ndarray
    platform_attitude: np.ndarray
    drift_angle: np.ndarray
    drift_rate: np.ndarray
    bearing_torques: np.ndarray
    motor_torques: np.ndarray
    mount_angles: np.ndarray | None = None
    mount_rates: np.ndarray | None = None
    servo_torque: np.ndarray | None = None
    rotor_rates: np.ndarray | None = None
    status: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.t)

    @staticmethod
    def stack(outs: list[Outputs]) -> "OutputBlock":
        def arr(name, shape):
            return np.array([getattr(o, name) for o in outs], dtype=float).reshape((len(outs),) + shape)

        first = outs[0] if outs else None
        opt = {k: (arr(k, (3,)) if first is not None and getattr(first, k) is not None else None)
               for k in _OPTIONAL}
        return OutputBlock(
            t=np.array([o.t for o in outs], dtype=float), gimbal_angles=arr("gimbal_angles", (5,)),
            gimbal_rates=arr("gimbal_rates", (5,)), gimbal_axial_torques=arr("gimbal_axial_torques", (5,)),
            platform_rate=arr("platform_rate", (3,)), platform_attitude=arr("platform_attitude", (4,)),
            drift_angle=arr("drift_angle", (3,)), drift_rate=arr("drift_rate", (3,)),
            bearing_torques=np.array([[o.bearing_torques[b] for b in BEARING_NAMES] for o in outs],
                                     dtype=float).reshape(len(outs), len(BEARING_NAMES), 3),
            motor_torques=arr("motor_torques", (3,)), **opt,
            rotor_rates=None if first is None or first.rotor_rates is None else np.array(first.rotor_rates, float),
            status={k: np.array([o.status[k] for o in outs], dtype=float) for k in (first.status if first else {})})

    def __getitem__(self, i: int) -> Outputs:
        opt = {k: (None if getattr(self, k) is None else getattr(self, k)[i].copy()) for k in _OPTIONAL}
        return Outputs(
            t=float(self.t[i]), gimbal_angles=self.gimbal_angles[i].copy(), gimbal_rates=self.gimbal_rates[i].copy(),
            gimbal_axial_torques=self.gimbal_axial_torques[i].copy(), platform_rate=self.platform_rate[i].copy(),
            platform_attitude=self.platform_attitude[i].copy(), drift_angle=self.drift_angle[i].copy(),
            drift_rate=self.drift_rate[i].copy(),
            bearing_torques={b: self.bearing_torques[i, j].copy() for j, b in enumerate(BEARING_NAMES)},
            motor_torques=self.motor_torques[i].copy(), **opt,
            rotor_rates=None if self.rotor_rates is None else self.rotor_rates.copy(),
            status={k: float(v[i]) for k, v in self.status.items()})

    def as_rows(self) -> list[dict[str, float]]:
        from .io.recording import csv_row
        return [csv_row(self[i]) for i in range(len(self))]


# ---- engine/simulator.py (H1) --------------------------------------------------------------
def push_block(sim: Any, t: np.ndarray, omega: np.ndarray, force: np.ndarray | None,
               out_idx: np.ndarray) -> OutputBlock:
    """``Simulator.push_block``: ``sim.push`` per sample, ``sim.outputs()`` after the samples in
    ``out_idx``. A SimulationError carries ``.block`` (outputs before it) and ``.n_done``
    (samples integrated by this call; an output failure at sample j gives n_done = j + 1)."""
    from .errors import InputError
    t = np.asarray(t, dtype=float)
    n = len(t)
    if omega.shape != (n, 3) or (force is not None and force.shape != (n, 3)):
        raise InputError("t, omega and specific_force must have the same length")
    bad = ~(np.isfinite(t) & np.all(np.isfinite(omega), 1) & (True if force is None else np.all(np.isfinite(force), 1)))
    if bad.any():
        raise InputError(f"non-finite sample at index {int(np.argmax(bad))}")
    if sim.needs_f and force is None:
        raise InputError("these effects need the specific force, which the samples do not carry")
    prev = sim.t_rel if sim.t_start is not None else None
    rel = t - sim.t_start if sim.t_start is not None else t - t[0]
    if n and ((prev is not None and not rel[0] > prev) or np.any(np.diff(rel) <= 0)):
        raise InputError("sample times are not increasing")
    want = np.zeros(n, bool)
    want[np.asarray(out_idx, dtype=np.int64)] = True
    outs: list[Outputs] = []
    for i in range(n):
        try:
            sim.push(RateSample(float(t[i]), omega[i].copy(), None if force is None else force[i].copy()))
        except SimulationError as e:
            e.block, e.n_done = OutputBlock.stack(outs), i
            raise
        if want[i]:
            try:
                outs.append(sim.outputs())
            except SimulationError as e:
                e.block, e.n_done = OutputBlock.stack(outs), i + 1
                raise
    return OutputBlock.stack(outs)


# ---- io/encode.py (H4) ---------------------------------------------------------------------
def encode_outputs(block: OutputBlock, stamps_ns: np.ndarray, namespace: str = "",
                   frame_prefix: str = "") -> list[tuple[str, list[bytes]]]:
    """CDR bytes of ``output_messages`` per topic (rosbags serialize_cdr)."""
    types, store = msgs.MessageTypes.rosbags(), msgs.jazzy_typestore()
    res: dict[str, list[bytes]] = {}
    for i in range(len(block)):
        for topic, m in msgs.output_messages(block[i], types, int(stamps_ns[i]), namespace):
            res.setdefault(topic, []).append(bytes(store.serialize_cdr(m, m.__msgtype__)))
    return list(res.items())


# ---- io/bag_writer.py (H4) -----------------------------------------------------------------
def write_many(out: Any, out_conn: Any, ts: np.ndarray, raws: list) -> None:
    """``OutputBag.write_many``: ``write_raw`` per row (``out_conn``: a connection or an
    output topic's name)."""
    if isinstance(out_conn, str):
        out_conn = out._outs[out_conn]
    for t, raw in zip(ts, raws):
        out.write_raw(out_conn, int(t), raw)


def copy_chunk(out: Any, chunk: RowChunk, bag: Any) -> None:
    """``OutputBag.copy_chunk``: every row of a copied connection, byte for byte."""
    conns = {c.id: c for c in bag.connections}
    for cid, t, raw in zip(chunk.conn_id, chunk.ts, chunk.raws):
        conn = conns[int(cid)]
        copy = out.copy_connection(conn, bag.store_for(conn))
        if copy is not None:
            out.write_raw(copy, int(t), raw)
