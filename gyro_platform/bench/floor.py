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

"""The replay's I/O floor (issue 31): what ``gyro-platform replay`` does to a bag, minus the simulation.

:func:`io_floor` opens the input bag (:class:`~gyro_platform.bags.reader.InputBag`), reads every
chunk the replay reads (``InputBag.chunks`` paced by ``ChunkPacer``, the next chunk read and
decoded on a reader thread by ``pipeline.prefetched``, as the replay does), decodes its input rows
as the replay does (``Pipeline.decode``: ``decode_rates`` and the mounting rotation), opens an
output bag of the same storage with the same connections (input connections copied, the output
topics added) and writes, on a writer thread, one chunk in flight, what the replay writes: the
input rows copied (``OutputBag.copy_chunk``), then at the output instants of the replay (the
output grid at ``output_rate`` over the accepted header stamps) the output messages encoded by
the replay's encoder (``encode_outputs(..., arrays=True)`` → ``OutputBag.write_topics``), then
``/diagnostics`` at 1 Hz of receive time (``diagnostic_array``, serialised by
``OutputBag.write_msg``), all in one ``OutputBag.batched`` write per chunk; it closes the bag
(index and metadata). Timed from opening the input to the output's metadata, as the replay's
``wall_time_s`` is.

Left out, being the simulation and its bookkeeping: the time gate (a row counts as accepted when
it decodes (``reject == 0``) and its stamp is later than every accepted one before it: on a
well-formed bag the gate's decision), the simulator (the outputs' values are a real simulator's
first instants repeated: the encoder's cost does not depend on them), the summary's statistics,
the plot series, the summary and the plot.
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from contextlib import closing
from pathlib import Path
import time
from typing import Any

import numpy as np

from .. import messages as msgs
from ..bags.reader import InputBag
from ..bags.writer import OutputBag
from ..engine.outputs import OutputBlock
from ..messages import MessageTypes
from ..messages.encode import encode_outputs
from ..messages.typedefs import core_typestore
from ..pipeline.gate import TimeGate
from ..pipeline.gate_rules import GateConfig
from ..pipeline.grid import grid_indices, new_slots, NO_SLOT
from ..pipeline.pacing import ChunkPacer, prefetched
from ..pipeline.stream import Pipeline

__all__ = ["io_floor", "floor_seconds", "output_template", "FloorRun"]

CHUNK_ROWS = 32768               # rows per chunk at most: the replay's default (ReplayConfig.chunk_rows)
DIAGNOSTICS_RATE = 1.0           # Hz of receive time: the replay's default
TEMPLATE_INSTANTS = 64           # distinct output instants of a real simulator, repeated


def output_template(n: int = TEMPLATE_INSTANTS) -> OutputBlock:
    """``n`` output instants of a default ``Simulator`` (the replay's, default options) at rest
    at 1 kHz: the shapes, mode and status keys of the replay's outputs, finite values."""
    from ..engine.simulator import Simulator

    sim = Simulator()
    t = np.arange(n) * 1e-3                                        # s
    omega = np.zeros((n, 3))                                       # rad/s
    force = np.tile([0.0, 0.0, 9.80665], (n, 1))                   # m/s², gravity's reaction
    return sim.push_block(t, omega, force, np.arange(n))


class FloorRun:
    """One floor pass's state: the output grid and diagnostics clock over the rows seen so far
    (times int64 ns), and the output bag's writer side. Use :func:`io_floor`."""

    def __init__(self, bag: InputBag, out: OutputBag, output_rate: float, template: OutputBlock):
        self.bag, self.out, self.output_rate, self.template = bag, out, output_rate, template
        self.pipeline = Pipeline(None, TimeGate(GateConfig()), output_rate)    # its decode only
        self.types = MessageTypes.rosbags(core_typestore())
        self.diag_topic = msgs.resolve("/diagnostics")
        self.gate_snapshot = self.pipeline.gate.snapshot()
        self.last_stamp = NO_SLOT        # ns: the latest accepted header stamp
        self.origin: int | None = None   # ns: the first accepted stamp (the grid's origin, as the gate's)
        self.slot: int | None = None     # output grid slot of the last output
        self.first_rx: int | None = None
        self.diag_slot: int | None = None
        self.n_in = self.n_acc = self.n_out = self.n_diag = 0
        self.last_out: Any = None

    def decode(self, chunk: Any) -> list[tuple[np.ndarray, Any]]:
        """(reader thread) The chunk's input rows decoded and rotated, as the replay decodes them."""
        return list(self.pipeline.decode(self.bag, chunk))

    def instants(self, rb: Any, rx: np.ndarray) -> tuple:
        """Where the replay emits in these decoded rows received at ``rx`` (ns): (record ns,
        header stamp ns, outputs (OutputBlock) of the output instants; the diagnostics rows'
        record ns, their figures (outputs up to each, samples accepted), the last output up to
        each or None). Accepted: decoded (``reject == 0``) and stamped after every accepted row
        before (``NO_SLOT``, int64's minimum, is "none yet")."""
        self.n_in += len(rx)
        ok = rb.reject == 0
        s = np.where(ok, rb.stamp_ns, NO_SLOT)
        before = np.maximum.accumulate(np.concatenate([[self.last_stamp], s]))[:-1]
        acc = np.flatnonzero(ok & (s > before))
        rows = acc[:0]
        self.n_acc += acc.size
        if acc.size:
            self.last_stamp = max(self.last_stamp, int(s[acc[-1]]))
            if self.origin is None:
                self.origin = int(s[acc[0]])
            slots = grid_indices(s[acc], self.origin, self.output_rate)
            rows = acc[new_slots(slots, self.slot)]
            if rows.size:
                self.slot = int(slots.max())
        k = len(rows)
        block = self.template[np.arange(k) % len(self.template)]
        if self.first_rx is None:
            self.first_rx = int(rx[0])
        dslot = grid_indices(rx, self.first_rx, DIAGNOSTICS_RATE)
        diag = np.flatnonzero(new_slots(dslot, self.diag_slot))
        if diag.size:
            self.diag_slot = int(dslot[diag[-1]])
        upto = np.searchsorted(rows, diag, side="right")        # outputs up to each diagnostics row
        lasts = []
        for u in upto.tolist():
            lasts.append(block[u - 1] if u else self.last_out)
        n_before = self.n_out
        self.n_out += k
        if k:
            self.last_out = block[k - 1]
        self.n_diag += diag.size
        figures = [{"outputs": n, "sim_pushed": self.n_acc} for n in (n_before + upto).tolist()]
        return rx[rows], rb.stamp_ns[rows], block, rx[diag], figures, lasts

    def write(self, chunk: Any, done: list[tuple]) -> None:
        """(writer thread) The chunk's copies, its outputs topic by topic, then its diagnostics,
        in one write (as the replay's writer thread writes a chunk)."""
        out = self.out
        with out.batched():
            out.copy_chunk(chunk, self.bag)
            outs = [d for d in done if len(d[2])]
            if outs:
                block = OutputBlock.concat([d[2] for d in outs]) if len(outs) > 1 else outs[0][2]
                enc = encode_outputs(block, np.concatenate([d[1] for d in outs]), arrays=True)
                out.write_topics(np.concatenate([d[0] for d in outs]), enc)
            for _, _, _, dts, figures, lasts in done:
                for ts, fig, last in zip(dts.tolist(), figures, lasts):
                    msg = msgs.diagnostic_array(self.gate_snapshot, last, self.types, ts, fig)
                    out.write_msg(self.diag_topic, ts, msg)


def io_floor(bag: str | Path, out: str | Path, storage: str | None = None, output_rate: float = 100.0,
             template: OutputBlock | None = None, chunk_rows: int = CHUNK_ROWS) -> dict[str, Any]:
    """Read, decode, encode and write what a replay of ``bag`` into ``out`` (must not exist) with
    ``--output-rate output_rate`` (Hz) reads and writes, without simulating (see the module).
    ``storage``: of the output bag (None: the input's, as the replay). ``template``: the outputs'
    values (:func:`output_template`, made when None, untimed). Returns ``wall_s`` (s, opening the
    input to closing the output), ``cpu_s`` (this process's CPU seconds over the same span),
    ``duration_s`` (s of record time), ``rtf`` (duration / wall), ``messages`` (rows read),
    ``inputs``, ``outputs``, ``diagnostics`` and ``counts`` (messages written per topic)."""
    template = output_template() if template is None else template
    t0, c0 = time.perf_counter(), time.process_time()
    src = InputBag(bag)
    src.open()
    lo = hi = None
    n_msgs = 0
    try:
        dst = OutputBag(Path(out), storage or src.storage)
        try:
            for conn in src.connections:
                dst.copy_connection(conn, src.store_for(conn))
            for topic, typ in msgs.output_topics().items():
                dst.add_output(topic, typ)
            run = FloorRun(src, dst, output_rate, template)
            pace = ChunkPacer(chunk_rows)
            inflight = None
            with ThreadPoolExecutor(1, thread_name_prefix="gyro-floor-writer") as writer:
                with closing(prefetched(src.chunks(chunk_rows, pace=pace), run.decode)) as feed:
                    for chunk, parts in feed:
                        t1 = time.perf_counter()
                        a, b = int(chunk.ts.min()), int(chunk.ts.max())
                        lo, hi = (a, b) if lo is None else (min(lo, a), max(hi, b))
                        n_msgs += len(chunk.ts)
                        done = [run.instants(rb, chunk.ts[rows]) for rows, rb in parts]
                        if inflight is not None:
                            inflight.result()
                        inflight = writer.submit(run.write, chunk, done)
                        pace.observe(len(chunk.ts), time.perf_counter() - t1)
                if inflight is not None:
                    inflight.result()
        finally:
            dst.close()
    finally:
        src.close()
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    duration = 0.0 if lo is None else (hi - lo) * 1e-9
    return {"wall_s": wall, "cpu_s": cpu, "duration_s": duration, "rtf": duration / wall if wall > 0 else None,
            "messages": n_msgs, "inputs": run.n_in, "outputs": run.n_out, "diagnostics": run.n_diag,
            "counts": dict(dst.counts)}


def floor_seconds(bag: str | Path, work: str | Path, repeats: int, output_rate: float = 100.0,
                  storage: str | None = None) -> dict[str, Any]:
    """:func:`io_floor` of ``bag`` ``repeats`` times after one untimed pass (output bags under
    ``work``, deleted after each): the last pass's figures with ``wall_s`` the median (s),
    ``rtf`` the duration over it, ``walls`` and ``cpu_times`` every pass's wall and CPU (s)."""
    import shutil

    template = output_template()
    work = Path(work)
    walls: list[float] = []
    cpu_times: list[float] = []
    res: dict[str, Any] = {}
    for i in range(repeats + 1):
        path = work / f"io_floor_{Path(bag).name}_{i}"
        res = io_floor(bag, path, storage, output_rate, template)
        shutil.rmtree(path, ignore_errors=True)       # unwritten pages dropped, not flushed during the next
        if i:
            walls.append(res["wall_s"])
            cpu_times.append(res["cpu_s"])
    wall = float(np.median(walls))
    return {**res, "wall_s": wall, "rtf": res["duration_s"] / wall if wall > 0 else None, "walls": walls,
            "cpu_times": cpu_times}
