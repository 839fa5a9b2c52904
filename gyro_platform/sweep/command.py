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

"""``gyro-platform sweep SPEC.yaml --out DIR``: a Monte Carlo budget or a fleet replay on Dask.

Runs go to a Dask cluster: by default a local cluster of worker processes (one per core, one
thread each, on 127.0.0.1, no dashboard); ``--scheduler ADDRESS`` uses any running cluster
(start one with ``dask scheduler`` and ``dask worker ADDRESS`` on each machine; the workers need
this package installed), and sends it this machine's compiled kernels (``kernels``): a new
worker host's first run loads them instead of compiling. Every finished run is written at once
(``store``), so Ctrl-C, SIGTERM or a killed worker lose at most the runs in flight, and the same
command again runs only what is missing.

Exit codes: 0 every run has a record (``ok``, ``refused`` or ``failed_input``: see
``summary.json``) and at least one is ``ok``; 1 no run is ``ok`` (the budget has no data), some
runs ``failed`` or were ``lost`` (run again to retry them), the
scheduler went away during the sweep (one line; the finished records and the table stay), or
the local cluster could not start; 2 a bad sweep file, flag or output folder, another sweep
writing into the same folder now (``OUT/.lock``), or a ``--scheduler`` that cannot be reached
(tried before anything is written); 4 an output could not be written (disk full: one line
naming the file; no temporary is left, the records written so far stay readable); 130
interrupted (Ctrl-C), 143 terminated (SIGTERM): the table holds the runs finished so far. A
damaged run record is named on stderr and its run done again. The local cluster's worker processes
log Dask's own records (warnings and errors, with tracebacks) into ``OUT/workers.log``
(``worker_log``), not the terminal; the command says in one line how many errors they logged.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import logging
import math
import os
from pathlib import Path
import signal
import sys
import threading
import time
from typing import Any, Callable

from .plots import budget_stats, plot_budget
from .runs import execute_run, FINISHED, lost_record
from .spec import load_sweep, SweepSpec, SweepSpecError
from .store import atomic_write, json_bytes, ResultStore, StoreError, SweepLock
from ..engine.remote import compile_cpus, one_compile_process
from ..errors import EXIT_INTERRUPTED, EXIT_OK, EXIT_TERMINATED, EXIT_USAGE, OutputError
from ..filesystem import check_output_path, write_failure
from ..signals import stop_reason, StopSignals

EXIT_RUNS_FAILED = 1


@dataclass
class SweepResult:
    records: list[dict[str, Any]]
    executed: int = 0
    skipped: int = 0
    interrupted: bool = False
    stop: str | None = None         # "interrupted" (Ctrl-C) or "terminated" (SIGTERM)
    wall_s: float = 0.0
    counts: dict[str, int] = field(default_factory=dict)
    beyond: int = 0                 # records in the folder of runs ≥ the sweep's runs (not counted)
    damaged: dict[str, str] = field(default_factory=dict)   # record file that was no record -> why (redone)
    scheduler_lost: str | None = None   # why the sweep stopped: its Dask scheduler went away (runs left undone)


#: the files a sweep writes into its folder (checked before any run: none may be a folder)
OUTPUT_FILES = ("sweep.json", "summary.json", "results.csv", "results.parquet", "budget.png", "workers.log")
#: the local cluster's worker processes log here (``worker_log``), not on the terminal
WORKER_LOG = "workers.log"

#: s, how long ``--scheduler`` is tried before it is refused as unreachable
SCHEDULER_TIMEOUT_S = 20.0


class SchedulerError(ValueError):
    """The ``--scheduler`` address is invalid or no Dask scheduler answers there."""


def connect_scheduler(address: str):
    """A ``distributed.Client`` of the running cluster at ``address`` (tried for
    :data:`SCHEDULER_TIMEOUT_S` s); SchedulerError (one line) if it cannot be reached."""
    from distributed import Client

    try:
        return Client(address, timeout=f"{SCHEDULER_TIMEOUT_S:g}s")
    except (OSError, ValueError) as e:   # OSError: time-out, refused; ValueError: bad address
        why = " ".join(str(e).split())
        raise SchedulerError(f"--scheduler {address}: no Dask scheduler reachable: {why}") from None


def make_client(workers: int | None = None, scheduler: str | None = None, worker_log: Path | None = None):
    """A ``distributed.Client``: to ``scheduler``, or to a new local cluster of processes (their
    log records into ``worker_log`` if given: :class:`~.worker_log.WorkerLogFile`; a run's kernel
    compile abandoned when its worker closes: :class:`~.worker_close.StopCompilesAtClose`)."""
    if scheduler:
        return connect_scheduler(scheduler)
    from distributed import Client, LocalCluster

    from .worker_close import StopCompilesAtClose
    from .worker_log import WorkerLogFile

    n = workers or os.cpu_count() or 1
    plugins = (StopCompilesAtClose(),) + ((WorkerLogFile(worker_log),) if worker_log else ())
    # the worker processes inherit an ignored SIGINT: Ctrl-C (sent to the whole process group)
    # reaches only this process, which cancels the runs and shuts the cluster down in order;
    # and, as many workers as CPUs or more, one compile process each: a cold worker's second
    # process (engine.remote.OutputsAside) would only take another worker's CPU
    main = threading.current_thread() is threading.main_thread()
    old = signal.signal(signal.SIGINT, signal.SIG_IGN) if main else None
    try:
        with one_compile_process(n >= compile_cpus()):
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                                   dashboard_address=None, silence_logs=40,
                                   plugins=plugins)
    finally:
        if main:
            signal.signal(signal.SIGINT, old)
    return Client(cluster)


def run_sweep(spec: SweepSpec, out: Path, workers: int | None = None, scheduler: str | None = None,
              progress: Callable[[str], None] | None = None, client: Any = None) -> SweepResult:
    """Run the runs of ``spec`` not yet finished in ``out``; return every record of the folder.
    ``client``: a connected ``distributed.Client`` to use (left open for its owner); without
    it one is made (``make_client``) and closed here. Holds ``OUT/.lock`` (``SweepLock``) while
    it runs; a damaged record file is named through ``progress`` and its run done again."""
    with SweepLock(out):        # a second sweep into ``out`` is refused (StoreError) while this one runs
        return _run_locked(spec, out, workers, scheduler, progress or (lambda s: None), client)


def _run_locked(spec: SweepSpec, out: Path, workers: int | None, scheduler: str | None,
                say: Callable[[str], None], client: Any) -> SweepResult:
    from distributed import as_completed

    from .worker_log import log_size, logged_records

    store = ResultStore(out, spec.fingerprint(), {"sweep": str(spec.source), "scene": str(spec.scene_path),
                                                  "kind": spec.kind, "runs": spec.n_runs, "seed": spec.seed}).open()
    done = store.finished()
    tasks = spec.tasks(skip=done)
    res = SweepResult(records=[], skipped=len(done), damaged={str(p): why for p, why in store.damaged.items()})
    for path, why in store.damaged.items():
        run = int(path.stem.split("_")[1])
        say(f"warning: damaged run record {path}: {why}; "
            + (f"run {run} runs again" if run < spec.n_runs else "left as it is (beyond runs)"))
    t0 = time.perf_counter()
    if tasks:
        own = client is None
        log_start = log_size(out / WORKER_LOG)
        client = make_client(workers, scheduler, out / WORKER_LOG) if own else client
        futures = []
        try:
            if scheduler or not own:        # another machine's workers: this machine's kernels for them
                from .kernels import ship_kernels

                ship_kernels(client, say)
            workers = len(client.scheduler_info()["workers"])
            say(f"{len(tasks)} run(s) to do, {len(done)} already done, on {workers} worker(s)")
            futures = client.map(execute_run, tasks, key=[f"gyro-sweep-{spec.fingerprint()}-{t.run}" for t in tasks],
                                 pure=False, retries=0)
            by_key = {f.key: t for f, t in zip(futures, tasks)}
            for fut in as_completed(futures):
                task = by_key[fut.key]
                try:
                    rec = fut.result()
                except Exception as e:  # noqa: BLE001 — KilledWorker, lost connection, …
                    if scheduler_lost(client, e):    # no run of its own failed: the rest is not done, not lost
                        res.scheduler_lost = " ".join(f"{type(e).__name__}: {e}".split())
                        # the client's reconnection attempts log tracebacks: the command says it once
                        logging.getLogger("distributed.client").setLevel(logging.CRITICAL)
                        break
                    rec = lost_record(task, f"{type(e).__name__}: {e}")
                store.put(rec)
                res.executed += 1
                say(f"run {rec['run']}: {rec['status']}" + (f" ({rec['message']})" if rec.get("message") else ""))
        except KeyboardInterrupt as e:      # Ctrl-C, or SIGTERM (errors.Terminated)
            res.interrupted, res.stop = True, stop_reason(e)
            if futures:
                client.cancel(futures)          # one message (a future's own cancel waits for the scheduler)
        finally:
            if own:
                close_client(client)
                if logged := logged_records(out / WORKER_LOG, log_start):
                    say(f"the local Dask workers logged {logged} error(s) of their own: {out / WORKER_LOG}")
    res.wall_s = time.perf_counter() - t0
    every = store.records()
    res.records = [r for r in every if r["run"] < spec.n_runs]     # a smaller runs: counts only its own
    res.beyond = len(every) - len(res.records)
    for r in res.records:
        res.counts[r["status"]] = res.counts.get(r["status"], 0) + 1
    return res


def scheduler_lost(client: Any, exc: BaseException) -> bool:
    """True when ``exc`` (from a run's future) says the scheduler went away, not the run's worker:
    the future was cancelled for a lost scheduler connection, or the client no longer runs."""
    reason = str(getattr(exc, "reason", "") or "")
    return "scheduler" in reason or getattr(client, "status", "running") not in ("running", "newly-created")


def close_client(client: Any) -> None:
    """Close a client made by ``make_client``, and its local cluster if it has one."""
    cluster = getattr(client, "cluster", None)
    client.close()
    if cluster is not None:
        cluster.close()


def finish(spec: SweepSpec, out: Path, res: SweepResult, plots: bool = True) -> dict[str, Any]:
    """Write the table, summary.json and the plot (holding ``OUT/.lock``); return the summary."""
    with SweepLock(out):
        return _finish_locked(spec, out, res, plots)


def _finish_locked(spec: SweepSpec, out: Path, res: SweepResult, plots: bool) -> dict[str, Any]:
    store = ResultStore(out, spec.fingerprint(), {})
    parquet, csv = store.write_table(res.records)
    summary = {"sweep": str(spec.source), "kind": spec.kind, "runs": spec.n_runs, "seed": spec.seed,
               "records": len(res.records), "status_counts": res.counts, "executed_now": res.executed,
               "skipped_finished": res.skipped, "records_beyond_runs": res.beyond,
               "interrupted": res.interrupted, "wall_s": res.wall_s, "damaged_records_redone": res.damaged,
               "drift_budget": budget_stats(res.records), "table": [str(parquet), str(csv)],
               "warnings": list(spec.warnings)}
    if plots and any(r["status"] == "ok" for r in res.records):
        summary["plot"] = str(plot_budget(res.records, out / "budget.png",
                                          f"{spec.source.name}: {spec.kind.replace('_', ' ')}, "
                                          f"{res.counts.get('ok', 0)} of {spec.n_runs} runs ok"))
    atomic_write(out / "summary.json", json_bytes(summary, indent=2))
    return summary


def _fmt(x: float | None) -> str:
    return "n/a" if x is None or not math.isfinite(x) else f"{x:.4g}"


def print_summary(summary: dict[str, Any], file=None) -> None:
    out = file or sys.stdout
    print(f"runs: {summary['records']} of {summary['runs']} recorded "
          f"({', '.join(f'{k} {v}' for k, v in sorted(summary['status_counts'].items()))})", file=out)
    if summary.get("records_beyond_runs"):
        print(f"  ({summary['records_beyond_runs']} record(s) of runs beyond runs: {summary['runs']} kept in "
              "runs/, not counted)", file=out)
    print("drift rate budget over the ok runs (°/h):", file=out)
    print(f"  {'axis':<5}{'n':>6}{'mean':>12}{'σ':>12}{'|mean|+1σ':>12}{'|mean|+3σ':>12}{'q99.73 |r|':>12}", file=out)
    for r in summary["drift_budget"]:
        print(f"  {r['axis']:<5}{r['n']:>6}{_fmt(r['mean_deg_per_h']):>12}{_fmt(r['std_deg_per_h']):>12}"
              f"{_fmt(r['bound_1sigma_deg_per_h']):>12}{_fmt(r['bound_3sigma_deg_per_h']):>12}"
              f"{_fmt(r['q99.73_abs_deg_per_h']):>12}", file=out)
    print("wrote " + ", ".join(summary["table"] + ([summary["plot"]] if "plot" in summary else [])), file=out)


def add_arguments(parser) -> None:
    parser.add_argument("spec", help="sweep YAML file (see config/sweeps/)")
    parser.add_argument("--out", metavar="DIR", help="output folder (default results/sweeps/<sweep file name>)")
    parser.add_argument("--workers", type=int, metavar="N", help="local cluster worker processes (default: all cores)")
    parser.add_argument("--scheduler", metavar="ADDRESS", help="use a running Dask cluster, e.g. tcp://10.0.0.5:8786")
    parser.add_argument("--no-plots", action="store_true", help="write no plot")


def run(args) -> int:
    prog = "gyro-platform sweep: error"
    if args.workers is not None and not 1 <= args.workers <= 4096:
        print(f"{prog}: --workers must be between 1 and 4096, got {args.workers}", file=sys.stderr)
        return EXIT_USAGE
    if args.workers is not None and args.scheduler:
        print(f"{prog}: give --workers or --scheduler, not both", file=sys.stderr)
        return EXIT_USAGE
    try:
        spec = load_sweep(args.spec)
    except SweepSpecError as e:
        print(f"{prog}: {e}", file=sys.stderr)
        return EXIT_USAGE
    out = Path(args.out) if args.out else Path("results") / "sweeps" / Path(args.spec).stem
    try:
        check_output_path(out, "--out", files=OUTPUT_FILES)
    except OutputError as e:
        print(f"{prog}: {e}", file=sys.stderr)
        return EXIT_USAGE
    for w in spec.warnings:          # a varied parameter no effect of the scene evaluates
        print(f"gyro-platform sweep: warning: {w}", file=sys.stderr)
    with StopSignals("gyro-platform sweep"):      # SIGTERM: the same orderly stop as Ctrl-C
        try:
            client = connect_scheduler(args.scheduler) if args.scheduler else None   # before any write
        except SchedulerError as e:
            print(f"{prog}: {e}", file=sys.stderr)
            return EXIT_USAGE
        try:
            with SweepLock(out):        # held from the first record to the summary: one sweep per folder
                try:
                    res = run_sweep(spec, out, workers=args.workers, client=client,
                                    progress=lambda s: print(s, file=sys.stderr, flush=True))
                finally:
                    if client is not None:
                        close_client(client)
                summary = finish(spec, out, res, plots=not args.no_plots)
        except StoreError as e:
            print(f"{prog}: {e}", file=sys.stderr)
            return EXIT_USAGE
        except OSError as e:  # the local cluster could not start (a write failure: exit 4, cli.main)
            if write_failure(e) is not None:
                raise
            print(f"{prog}: the Dask cluster could not start: {' '.join(str(e).split())}", file=sys.stderr)
            return EXIT_RUNS_FAILED
    print_summary(summary)
    if res.scheduler_lost:
        left = spec.n_runs - sum(res.counts.get(k, 0) for k in FINISHED)
        print(f"{prog}: the Dask scheduler went away during the sweep ({res.scheduler_lost}); the {res.executed} "
              f"run(s) finished now are kept in {out / 'runs'}; run the same command again to do the {left} left",
              file=sys.stderr)
        return EXIT_RUNS_FAILED
    if res.interrupted:
        print(f"gyro-platform sweep: {res.stop}; {res.executed} run(s) finished now, run the same command to go on",
              file=sys.stderr)
        return EXIT_TERMINATED if res.stop == "terminated" else EXIT_INTERRUPTED
    if res.records and not res.counts.get("ok"):
        print(f"{prog}: none of the {len(res.records)} runs gave a result (see summary.json): "
              "the budget has no data", file=sys.stderr)
        return EXIT_RUNS_FAILED
    return EXIT_RUNS_FAILED if res.counts.get("failed", 0) + res.counts.get("lost", 0) else EXIT_OK
