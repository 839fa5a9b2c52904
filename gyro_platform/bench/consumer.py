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

"""What a user gets: the consumer paths timed beside the compiled kernel (``gyro-platform bench consumer``).

Rows, all in one process run (medians of ``repeats``):

* ``replay`` of a 1 kHz ``sensor_msgs/Imu`` bag of the benchmark's own making (:mod:`gyro_platform.bench.bags`;
  120 s, ``--quick`` 10 s), ``--output-rate 100``, sqlite3 and mcap, and of a second one it was
  not tuned on (another vehicle, stamps jittered ±5 % of the period) and of a third with a 37 Hz
  engine vibration (0.3 rad/s: the mount friction kinks ~220 times a second), through the real command
  (:mod:`gyro_platform.replay.command` in-process, after one untimed run that loads the compiled
  code: the summary's ``real_time_factor``, the first run's kept as ``first_run_rtf``; and the
  whole command in a subprocess, ``python -m gyro_platform replay …`` with default options:
  wall time including interpreter start-up, imports and the plot, and the real-time factor that
  command prints, ``new_process_rtf``: its first replay, the compiled code's loading included);
* the I/O floor of each 1 kHz replay (:mod:`gyro_platform.bench.floor`, beside its row: ``I/O
  floor ×`` and ``replay ÷ floor``, issue 31's bar ≤ 2): the same bag read and decoded, the same
  output messages encoded and written, without simulating (medians of ``repeats`` after one
  untimed pass);
* SQLite's own floor under the sqlite3 replay: the rows that replay wrote, inserted again into a
  fresh database with nothing else running (the best a sqlite3 replay of them can do);
* ``replay`` of the shared husky recording (30 Hz, 395 s; ``--quick``: its first 30 s), found as
  the ``husky_replay`` scene finds it ("not found" when absent);
* ``run default`` (the README's first command) through :mod:`gyro_platform.scenes.command`;
* ``NodeCore.on_message`` per 1 kHz Imu message (rosbags message objects, default node
  configuration, 20000 messages; median and p99 µs).

Beside each, the kernel's figure on the same input samples and options: the compiled
``Simulator.push_many`` µs per sample (integration only); the ratio consumer/kernel says what
the consumer adds around the kernel (1 = nothing). Times are wall clock (``perf_counter``), as
the real-time factors are; the machine may be shared, so medians are quoted. Writes
``consumer.json``, ``consumer.md`` and ``consumer.png`` under ``--out``.
"""
from __future__ import annotations

import argparse
import contextlib
from dataclasses import dataclass, field
import io
import json
from pathlib import Path
import shutil
import subprocess
import sys
import tempfile
import time
from typing import Any, Callable

import numpy as np

from .bags import cache_dir, cached_imu_bag, husky_bag, IMU_TOPIC, short_copy, vehicle_imu
from .bars import BARS
from .report import cpu_ceiling_text, write_report
from ..filesystem import child_env

__all__ = ["Row", "add_floor", "consumer", "kernel_us", "replay_once", "node_us", "table"]

OUTPUT_RATE = 100.0            # Hz, replay --output-rate of the 1 kHz rows
#: the second 1 kHz bag, one the fast path was not tuned on: another vehicle's motion and noise
#: (seed) and header stamps jittered by up to ±5 % of the period, as a real driver's are
OTHER_SEED, OTHER_JITTER = 31, 0.05
NODE_MESSAGES = 20_000
ROOT = Path(__file__).resolve().parents[2]      # the folder holding the gyro_platform package


@dataclass
class Row:
    """One consumer figure: ``us_per_sample`` (wall µs per input message, all in) beside the
    kernel's ``kernel_us`` on the same samples; ``rtf`` the real-time factor (None for the node)."""

    name: str
    what: str
    input: str
    status: str = "ok"                 # ok | not found | failed: … | skipped: …
    rtf: float | None = None
    us_per_sample: float | None = None
    kernel_us: float | None = None
    extra: dict[str, Any] = field(default_factory=dict)
    target: str = ""                   # the key of its bar in ``bars.BARS`` ("" for none)

    @property
    def ratio(self) -> float | None:
        """consumer / kernel µs per sample (how much the consumer adds; 1 = nothing)."""
        if self.us_per_sample is None or not self.kernel_us:
            return None
        return self.us_per_sample / self.kernel_us


# ---------------------------------------------------------------------------------------------
# the kernel

def kernel_us(t: np.ndarray, omega: np.ndarray, force: np.ndarray | None, repeats: int,
              params: Any = None, options: Any = None) -> float:
    """Median wall µs per sample of the compiled ``Simulator.push_many`` (no outputs) over
    these samples (t s, omega rad/s, force m/s²), a fresh simulator each repeat (compiled first)."""
    from ..engine.simulator import Simulator

    kw = {k: v for k, v in (("params", params), ("options", options)) if v is not None}
    warm = Simulator(**kw)
    warm.push_many(t[:3], omega[:3], None if force is None else force[:3])
    out = []
    for _ in range(repeats):
        sim = Simulator(**kw)
        t0 = time.perf_counter()
        sim.push_many(t, omega, force)
        out.append((time.perf_counter() - t0) / len(t) * 1e6)
    return float(np.median(out))


def bag_samples(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The accepted samples of a bag's input topic as the replay's gate yields them (the first
    run of increasing times): t (s since the origin), omega (rad/s), force (m/s², 0 if absent)."""
    from ..pipeline.stream import read_samples

    t, w, f = [], [], []
    for item in read_samples(path):
        s = item.sample
        if s is None or (t and s.t <= t[-1]):
            continue
        t.append(s.t)
        w.append(s.omega)
        f.append(np.zeros(3) if s.specific_force is None else s.specific_force)
    return np.asarray(t), np.asarray(w), np.asarray(f)


# ---------------------------------------------------------------------------------------------
# the consumers

def _quietly(fn: Callable[[], Any]) -> Any:
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        return fn()


def replay_once(bag: Path, out: Path, extra: tuple[str, ...] = ()) -> dict:
    """One ``gyro-platform replay BAG --out OUT --quiet --no-plot …`` through the command's own
    ``add_arguments``/``run``, in this process; the summary (``OUT.summary.json``) with
    ``command_wall_s`` (the whole call) added. Raises RuntimeError on a non-zero exit."""
    from ..replay import command as replay_command
    from ..replay.loop import sidecar_paths

    p = argparse.ArgumentParser(prog="gyro-platform replay")
    replay_command.add_arguments(p)
    args = p.parse_args([str(bag), "--out", str(out), "--quiet", "--no-plot", *extra])
    t0 = time.perf_counter()
    code = _quietly(lambda: replay_command.run(args))
    wall = time.perf_counter() - t0
    if code != 0:
        raise RuntimeError(f"replay exited {code}")
    summary = json.loads(sidecar_paths(out)[0].read_text())
    summary["command_wall_s"] = wall
    return summary


def replay_subprocess(bag: Path, out: Path, extra: tuple[str, ...] = ()) -> tuple[float, float]:
    """(wall seconds of the whole ``python -m gyro_platform replay BAG --out OUT --quiet …``: start-up,
    imports, compiled-code loading, the plot, what a user waits for; the real-time factor the
    command reports, its summary's: the first replay of a new process, compiled-code loading
    included)."""
    from ..replay.loop import sidecar_paths

    cmd = [sys.executable, "-m", "gyro_platform", "replay", str(bag), "--out", str(out), "--quiet", *extra]
    t0 = time.perf_counter()
    r = subprocess.run(cmd, cwd=str(ROOT), env=child_env(), capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        raise RuntimeError(f"replay exited {r.returncode}: {r.stderr.strip().splitlines()[-1:] or ''}")
    return wall, json.loads(sidecar_paths(out)[0].read_text())["real_time_factor"]


def _replay_row(name: str, what: str, bag: Path, work: Path, repeats: int, extra: tuple[str, ...],
                kernel: float, target: str, whole: bool) -> Row:
    rtf, us, walls, cpu_times = [], [], [], []
    # one untimed run first: the compiled code of the replay path loaded (numba caches), as in
    # any run after the first of a process; the first run's own figure is kept beside
    first = replay_once(bag, work / f"{name}_first", extra)
    _discard(work / f"{name}_first")
    summary: dict = {}
    for i in range(repeats):
        summary = replay_once(bag, work / f"{name}_{i}", extra)
        if i:                             # the first is kept for the SQLite floor row
            _discard(work / f"{name}_{i}")
        rtf.append(summary["real_time_factor"])
        us.append(summary["wall_time_s"] / max(summary["counts"]["in"], 1) * 1e6)
        walls.append(summary["command_wall_s"])
        cpu_times.append(summary["cpu_time_s"])
    row = Row(name, what, str(bag), rtf=float(np.median(rtf)), us_per_sample=float(np.median(us)),
              kernel_us=kernel, target=target,
              extra={"duration_s": summary["duration_s"], "messages": summary["counts"]["in"],
                     "outputs": summary["counts"]["out"], "in_process_command_wall_s": float(np.median(walls)),
                     "first_run_rtf": first["real_time_factor"], **cpu_ceiling(cpu_times, summary["duration_s"]),
                     "integrator": summary["simulator"]["stats"]["integrator"],
                     "max_error_norm": summary["simulator"]["stats"].get("max_error_norm")})
    if whole:
        w, printed = [], []
        for i in range(repeats):
            wall, rtf_new = replay_subprocess(bag, work / f"{name}_sub{i}", extra)
            w.append(wall)
            printed.append(rtf_new)
            _discard(work / f"{name}_sub{i}")
        row.extra["whole_command_wall_s"] = float(np.median(w))
        row.extra["whole_command_rtf"] = summary["duration_s"] / float(np.median(w))
        row.extra["new_process_rtf"] = float(np.median(printed))
    return row


def cpu_ceiling(cpu_times: list[float], duration: float) -> dict[str, float]:
    """``cpu_s``: the median of ``cpu_times``, CPU seconds (this process, all threads) of runs of
    ``duration`` s of data; ``cpu_ceiling_rtf``: the real-time factor that much work allows at
    best on this machine's usable CPUs (each busy all the time); ``cpus``: their number."""
    from ..engine.remote import compile_cpus

    cpu, n = float(np.median(cpu_times)), compile_cpus()
    return {"cpu_s": cpu, "cpus": n, "cpu_ceiling_rtf": duration * n / cpu if cpu > 0 else float("inf")}


def _discard(out: Path) -> None:
    """Delete an output bag once its figures are read: the ~70 MB each 1 kHz run writes would
    otherwise sit in the page cache and be flushed to disk during the runs after it (the
    kernel's writeback would then be timed with them; unlinking drops unwritten pages)."""
    shutil.rmtree(out, ignore_errors=True)


def node_us(msgs: list, repeats: int) -> dict[str, float]:
    """µs per ``NodeCore.on_message`` call (default node configuration, rosbags messages,
    receive time = header stamp): median and p99 over the messages, medians over repeats."""
    from ..messages import MessageTypes, stamp_ns
    from ..ros.core import NodeConfig, NodeCore

    types = MessageTypes.rosbags()
    stamps = [stamp_ns(m.header.stamp) for m in msgs]
    warm = NodeCore(NodeConfig.from_ros_params(), types)
    for m, s in zip(msgs[:300], stamps[:300]):
        warm.on_message(m, s)
    med, p99, mx, outs = [], [], [], 0
    clock = time.perf_counter_ns
    for _ in range(repeats):
        core = NodeCore(NodeConfig.from_ros_params(), types)
        dt = np.empty(len(msgs))
        for i, (m, s) in enumerate(zip(msgs, stamps)):
            t0 = clock()
            core.on_message(m, s)
            dt[i] = clock() - t0
        dt *= 1e-3
        med.append(np.median(dt))
        p99.append(np.percentile(dt, 99))
        mx.append(dt.max())
        outs = core.published
    return {"median_us": float(np.median(med)), "p99_us": float(np.median(p99)), "max_us": float(np.median(mx)),
            "published": outs, "internal_errors": core.internal_errors}


def _imu_objects(bag: Path, n: int) -> list:
    """The first ``n`` messages of the bag's Imu topic as rosbags objects."""
    from rosbags.rosbag2 import Reader

    from ..messages import jazzy_typestore

    store = jazzy_typestore()
    out = []
    with Reader(bag) as r:
        conns = [c for c in r.connections if c.topic == IMU_TOPIC]
        for c, _, raw in r.messages(connections=conns):
            out.append(store.deserialize_cdr(raw, c.msgtype))
            if len(out) >= n:
                break
    return out


def _scene_row(repeats: int, work: Path) -> Row:
    """``gyro-platform run default --out DIR`` in this process; RTF = duration / the summary's wall."""
    from ..scenes import command as scene_command
    from ..scenes.schema import load_scene

    scene = load_scene("default")
    p = argparse.ArgumentParser(prog="gyro-platform run")
    scene_command.add_arguments(p)
    rtf, walls, us = [], [], []
    for i in range(repeats):
        out = work / f"run_default_{i}"
        args = p.parse_args(["default", "--out", str(out)])
        t0 = time.perf_counter()
        code = _quietly(lambda: scene_command.run(args))
        walls.append(time.perf_counter() - t0)
        if code not in (0, 1):          # 1: an expectation failed; the timing still holds
            raise RuntimeError(f"run exited {code}")
        s = json.loads((out / "summary.json").read_text())["summary"]
        rtf.append(scene.duration / s["wall_time"])
        us.append(s["wall_time"] / s["n_samples"] * 1e6)
    t, w, f = scene.motion.generator.arrays(scene.duration, scene.sample_rate)
    k = kernel_us(t, w, f, repeats, scene.params, scene.options)
    return Row("run_default", f"run default (scene, {scene.sample_rate:g} Hz input, {scene.duration:g} s)",
               str(scene.source or "default"),
               rtf=float(np.median(rtf)), us_per_sample=float(np.median(us)), kernel_us=k,
               extra={"command_wall_s": float(np.median(walls)), "duration_s": scene.duration,
                      "options": f"{scene.options.mode}/{scene.options.fidelity}/{scene.options.integrator}"})


def _guard(name: str, what: str, fn: Callable[[], Row]) -> Row:
    """A row whatever happens: a failure is reported in the row, never a crash of the benchmark."""
    try:
        return fn()
    except KeyboardInterrupt:
        raise
    except Exception as e:  # the benchmark reports, it does not stop
        return Row(name, what, "", status=f"failed: {type(e).__name__}: {str(e)[:120]}")


def consumer(out_dir: Path, quick: bool = False, repeats: int = 3, whole_command: bool = True) -> list[Row]:
    """Run every consumer row and its kernel figure; print the table, write JSON, Markdown, PNG."""
    duration = 10.0 if quick else 120.0
    n_node = 5_000 if quick else NODE_MESSAGES
    rows: list[Row] = []
    work = Path(tempfile.mkdtemp(prefix="gyro_bench_consumer_"))
    try:
        print(f"consumer figures: 1 kHz Imu bag of {duration:g} s (generated once, cached in {cache_dir()}), "
              f"medians of {repeats} repeat(s)", flush=True)
        imu = vehicle_imu(duration)
        k_imu = kernel_us(imu.t, imu.omega, imu.force, repeats)
        other = vehicle_imu(duration, seed=OTHER_SEED, jitter=OTHER_JITTER)
        k_other = kernel_us(other.t, other.omega, other.force, repeats)
        vib = vehicle_imu(duration, vibration=True)
        k_vib = kernel_us(vib.t, vib.omega, vib.force, repeats)
        for variant, kern, bag_kw, label in (("", k_imu, {}, ""),
                                             ("_other", k_other, {"seed": OTHER_SEED, "jitter": OTHER_JITTER},
                                             f", another vehicle, stamps jittered ±{OTHER_JITTER:g} period"),
                                             ("_vibrating", k_vib, {"vibration": True}, ", 37 Hz engine vibration")):
            for storage in ("sqlite3", "mcap"):
                name = f"replay_1khz{variant}_{storage}"
                what = f"replay 1 kHz Imu{label}, {duration:g} s, --output-rate 100, {storage}"
                rows.append(_guard(name, what, lambda: _replay_row(
                    name, what, cached_imu_bag(duration, storage, **bag_kw), work, repeats,
                    ("--output-rate", f"{OUTPUT_RATE:g}"), kern, "replay_1khz", whole_command)))
                if rows[-1].status == "ok":
                    add_floor(rows[-1], cached_imu_bag(duration, storage, **bag_kw), work, repeats)
                print(_line(rows[-1]), flush=True)
                if storage == "sqlite3" and not variant:
                    rows.append(_guard("sqlite3_floor", SQLITE_FLOOR, lambda: _floor_row(work / f"{name}_0", repeats)))
                    print(_line(rows[-1]), flush=True)
        rows.append(_husky_row(work, repeats, quick, whole_command))
        print(_line(rows[-1]), flush=True)
        rows.append(_guard("run_default", "run default", lambda: _scene_row(repeats, work)))
        print(_line(rows[-1]), flush=True)
        rows.extend(_node_rows(duration, n_node, repeats, imu))
        print(_line(rows[-2]) + "\n" + _line(rows[-1]), flush=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    write_outputs(rows, out_dir, quick=quick, repeats=repeats)
    return rows


def add_floor(row: Row, bag: Path, work: Path, repeats: int) -> None:
    """The replay's I/O floor on the same bag (:func:`gyro_platform.bench.floor.floor_seconds`: the
    same reads, decoding, encoding and writes, no simulation) into ``row.extra``: ``floor_rtf``,
    ``floor_wall_s`` (median s), ``floor_us`` (µs per input message) and ``replay_over_floor``
    (replay wall ÷ floor wall; its bar: ``BARS["replay_over_floor"]``). A failure is noted as ``floor_error``."""
    from .floor import floor_seconds

    try:
        f = floor_seconds(bag, work, repeats, OUTPUT_RATE)
    except KeyboardInterrupt:
        raise
    except Exception as e:  # the benchmark reports, it does not stop
        row.extra["floor_error"] = f"{type(e).__name__}: {str(e)[:120]}"
        return
    row.extra.update(floor_rtf=f["rtf"], floor_wall_s=f["wall_s"], floor_us=f["wall_s"] / max(f["inputs"], 1) * 1e6,
                     floor_walls_s=f["walls"], floor_counts=f["counts"],
                     floor_cpu_ceiling_rtf=cpu_ceiling(f["cpu_times"], f["duration_s"])["cpu_ceiling_rtf"])
    if f["rtf"] and row.rtf:
        row.extra["replay_over_floor"] = f["rtf"] / row.rtf


SQLITE_FLOOR = "SQLite alone: the rows that replay wrote, inserted again (one transaction)"


def sqlite_floor(bag: Path, repeats: int) -> tuple[float, int]:
    """(median s, rows) to insert the ``messages`` rows of a sqlite3 bag into a fresh database of
    the same schema with nothing else running (``bag_storage.insert_rows`` through apsw with the
    writer's page size, one transaction, ``synchronous=OFF``): the floor SQLite sets under a
    replay that writes these rows."""
    import sqlite3

    import apsw

    from ..bags.storage import insert_rows, SQLITE_PAGE_SIZE

    db3 = next(Path(bag).glob("*.db3"))
    src = sqlite3.connect(f"file:{db3}?mode=ro", uri=True)
    try:
        schema = [r[0] for r in src.execute("SELECT sql FROM sqlite_master WHERE sql IS NOT NULL")]
        rows = src.execute("SELECT topic_id, timestamp, data FROM messages ORDER BY id").fetchall()
    finally:
        src.close()
    cids = np.array([r[0] for r in rows], np.int64)
    ts = np.array([r[1] for r in rows], np.int64)
    raws = [r[2] for r in rows]
    walls = []
    with tempfile.TemporaryDirectory(prefix="gyro_bench_sqlite_") as tmp:
        for i in range(repeats):
            conn = apsw.Connection(str(Path(tmp) / f"floor{i}.db3"))
            conn.execute(f"PRAGMA page_size={SQLITE_PAGE_SIZE}")
            for sql in schema:
                conn.execute(sql)
            conn.execute("PRAGMA synchronous=OFF")
            cur = conn.cursor()
            t0 = time.perf_counter()
            cur.execute("BEGIN")
            insert_rows(cur, cids, ts, raws)
            cur.execute("COMMIT")
            walls.append(time.perf_counter() - t0)
            conn.close()
    return float(np.median(walls)), len(raws)


def _floor_row(bag: Path, repeats: int) -> Row:
    summary = json.loads((bag.parent / (bag.name + ".summary.json")).read_text())
    wall, n = sqlite_floor(bag, repeats)
    return Row("sqlite3_floor", SQLITE_FLOOR, str(bag), rtf=summary["duration_s"] / wall,
               us_per_sample=wall / max(summary["counts"]["in"], 1) * 1e6, extra={"rows": n, "seconds": wall})


def _husky_row(work: Path, repeats: int, quick: bool, whole: bool) -> Row:
    name, what = "replay_husky", "replay husky (30 Hz Imu, 395 s, mcap), default options"
    path, why = husky_bag()
    if path is None:
        return Row(name, what, "robot_localization_husky_test1", status=why, target="replay_husky")

    def run() -> Row:
        bag = short_copy(path, 30.0) if quick else path
        t, w, f = bag_samples(bag)
        k = kernel_us(t, w, f, repeats)
        return _replay_row(name, what.replace("395 s", "first 30 s") if quick else what, bag, work, repeats, (),
                           k, "replay_husky", whole)

    return _guard(name, what, run)


def _node_rows(duration: float, n: int, repeats: int, imu) -> list[Row]:
    what = f"NodeCore.on_message, 1 kHz Imu, {n} msgs"

    def run() -> dict:
        msgs = _imu_objects(cached_imu_bag(duration, "mcap"), n)
        res = node_us(msgs, repeats)
        res["kernel_us"] = kernel_us(imu.t[:len(msgs)], imu.omega[:len(msgs)], imu.force[:len(msgs)], repeats)
        return res

    try:
        r = run()
    except KeyboardInterrupt:
        raise
    except Exception as e:
        bad = f"failed: {type(e).__name__}: {str(e)[:120]}"
        return [
            Row("node_median", what + " (median)", "", status=bad),
            Row("node_p99", what + " (p99)", "", status=bad),
        ]
    extra = {k: r[k] for k in ("max_us", "published", "internal_errors")}
    return [Row("node_median", what + " (median)", "generated", us_per_sample=r["median_us"], kernel_us=r["kernel_us"],
                extra=extra, target="node_median"),
            Row("node_p99", what + " (p99)", "generated", us_per_sample=r["p99_us"], kernel_us=r["kernel_us"],
                extra=extra, target="node_p99")]


# ---------------------------------------------------------------------------------------------
# output

def _fmt(x: float | None, spec: str) -> str:
    return "" if x is None else format(x, spec)


def _line(r: Row) -> str:
    if r.status != "ok":
        return f"  {r.what}: {r.status}"
    rtf = f"×{r.rtf:.3g} real time, " if r.rtf else ""
    kernel = f"; kernel {r.kernel_us:.2f} µs/sample; ratio {r.ratio:.1f}" if r.kernel_us else ""
    floor = ""
    if r.extra.get("replay_over_floor"):
        floor = f"; I/O floor ×{r.extra['floor_rtf']:.3g} real time, replay ÷ floor {r.extra['replay_over_floor']:.2f}"
    elif r.extra.get("floor_error"):
        floor = f"; I/O floor failed: {r.extra['floor_error']}"
    return f"  {r.what}: {rtf}{r.us_per_sample:.2f} µs/msg{kernel}{floor}{_ceiling(r, '; ')}"


def _ceiling(r: Row, lead: str = "") -> str:
    """What the replay's CPU allows: 'CPU 0.60 s: ≤ ×400 on 2 CPUs' (and its floor's), or ''."""
    e = r.extra
    text = cpu_ceiling_text(e)
    if not text:
        return ""
    fl = f" (floor ≤ ×{e['floor_cpu_ceiling_rtf']:.3g})" if "floor_cpu_ceiling_rtf" in e else ""
    return f"{lead}{text}{fl}"


def table(rows: list[Row]) -> str:
    """The Markdown table: one line per figure."""
    lines = ["| figure | real-time × (summary) | as printed by a new process | whole command: wall s (×) "
             "| µs per input msg | kernel µs/sample "
             f"| consumer / kernel | I/O floor × | replay ÷ floor ({BARS['replay_over_floor']}) | target "
             "| CPU: at best × on this machine |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if r.status != "ok":
            lines.append(f"| {r.what} | {r.status} | | | | | | | | {_bar_text(r.target)} | |")
            continue
        wc = r.extra.get("whole_command_wall_s")
        whole = "" if wc is None else f"{wc:.2f} (×{r.extra['whole_command_rtf']:.3g})"
        printed = _fmt(r.extra.get("new_process_rtf"), ".3g")
        floor = "failed" if r.extra.get("floor_error") else _fmt(r.extra.get("floor_rtf"), ".3g")
        lines.append(f"| {r.what} | {_fmt(r.rtf, '.3g')} | {printed} | {whole} | {r.us_per_sample:.2f} "
                     f"| {_fmt(r.kernel_us, '.2f')} | {_fmt(r.ratio, '.1f')} | {floor} "
                     f"| {_fmt(r.extra.get('replay_over_floor'), '.2f')} | {_bar_text(r.target)} | {_ceiling(r)} |")
    return "\n".join(lines) + "\n"


def _bar_text(key: str) -> str:
    return str(BARS[key]) if key in BARS else ""


def write_outputs(rows: list[Row], out_dir: Path, **meta: Any) -> None:
    write_report("consumer", rows, table(rows), out_dir, plot, **meta)


def plot(rows: list[Row], path: Path) -> None:
    """Horizontal bars, log µs per input message: consumer beside kernel for every figure."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = [r for r in rows if r.status == "ok" and r.us_per_sample]
    fig, ax = plt.subplots(figsize=(11, 0.6 * max(len(ok), 1) + 1.6))
    y = np.arange(len(ok))
    ax.barh(y - 0.2, [r.us_per_sample for r in ok], 0.4, label="consumer (all in)", color="tab:orange")
    ax.barh(y + 0.2, [r.kernel_us or np.nan for r in ok], 0.4, label="kernel push_many", color="tab:blue")
    floor = [r.extra.get("floor_us", np.nan) for r in ok]
    if np.isfinite(floor).any():
        ax.plot(floor, y - 0.2, "k|", markersize=14, mew=2, label="I/O floor (no simulation)")
    for yi, r in zip(y, ok):
        if r.ratio:
            ax.text(r.us_per_sample * 1.1, yi - 0.2, f"×{r.ratio:.1f}", va="center", fontsize=8)
    ax.axvline(1e3, color="tab:red", lw=0.8, ls=":")
    ax.text(1e3, -0.45, " 1 ms: real time at 1 kHz", color="tab:red", fontsize=7, va="bottom")
    ax.set_yticks(y, [r.what for r in ok], fontsize=7)
    ax.set_xscale("log")
    ax.set_xlabel("wall µs per input message (lower is better)")
    ax.invert_yaxis()
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title("consumer paths beside the compiled kernel (same input samples)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
