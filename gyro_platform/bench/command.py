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

"""``gyro-platform bench [WHAT]``: the benchmarks' command line (coldstart, consumer, peer,
accuracy, hard, effects, hotpath, roughness, sweep; without WHAT: coldstart, consumer, roughness,
then peer, and last the headline table of the four, :mod:`.headline`).

``coldstart`` (:mod:`.coldstart`): whole commands (``run default``, the husky replay, the DDS
node's time to ready, a Dask worker's first run) on an empty kernel cache beside warm, and
their ratio;

``consumer`` (:mod:`.consumer`): replay, scene run and node figures beside the compiled kernel;
``roughness`` (:mod:`.roughness`): right-hand sides per sample and delivered error on a smooth and
a vibrating 1 kHz IMU over a sweep of tolerances, compared at equal delivered accuracy; ``peer``
(:mod:`.peer_mujoco`): the same carried platform in MuJoCo at equal accuracy (needs ``pip install
'.[bench]'``; skipped with a note without it);

``accuracy`` (:mod:`.accuracy`): work-precision study; ``hard`` (:mod:`.hard`): the hard-case
table, exit code 1 if any cell is WRONG; ``effects`` and ``hotpath`` (:mod:`.hotpath`): per-sample
cost; ``sweep`` (:mod:`gyro_platform.sweep.scaling`): runs per minute of the 60 s default
scene on 1 and 2 Dask workers, results identical. Each writes its tables and plots under ``--out``.
"""
from __future__ import annotations

from pathlib import Path
import sys
import time

from .accuracy import accuracy
from .consumer import consumer
from .hard import hard
from .hotpath import effects_cost, hotpath
from ..errors import EXIT_USAGE, OutputError
from ..filesystem import check_output_path
from ..reports.jsonio import write_json

__all__ = ["add_arguments", "run"]


def add_arguments(p) -> None:
    """The ``bench`` subcommand's arguments on the argparse parser ``p``."""
    p.add_argument("what", nargs="?", default="default",
                   choices=["default", "coldstart", "consumer", "roughness", "peer", "accuracy", "effects", "hotpath",
                            "hard", "sweep"],
                   help="which benchmark (default: coldstart, consumer, roughness, then peer)")
    p.add_argument("--out", default="results/bench", help="output folder (default results/bench)")
    p.add_argument("--quick", action="store_true",
                   help="short runs (coldstart: the default scene over its test duration, 5 s sweep scenes, "
                        "husky's first 30 s; consumer: 10 s bags, husky's first 30 s; roughness: 2 s inputs; "
                        "peer: 2 s scenes; accuracy: 60 s ship, 30 s aircraft; hard: the tests' durations)")
    p.add_argument("--case", action="append", default=None, help="hard: only this case (repeatable)")
    p.add_argument("--repeats", type=int, default=3, help=f"timing repeats, 1..{MAX_REPEATS} (median quoted)")
    p.add_argument("--runs", type=int, default=8,
                   help=f"sweep: Monte Carlo runs per worker count, 1..{MAX_RUNS} (default 8)")
    p.add_argument("--no-whole-command", action="store_true",
                   help="consumer: skip the subprocess runs of the whole replay command (start-up included)")


MAX_REPEATS = 1000
MAX_RUNS = 10_000


def _error(text: str) -> int:
    print(f"gyro-platform bench: error: {text}", file=sys.stderr)
    return EXIT_USAGE


def check_options(args) -> str | None:
    """Why the options are refused (one line), or None: checked the same way for every
    benchmark, before anything runs or is written (``--repeats``, ``--runs``, ``--case``)."""
    if not 1 <= args.repeats <= MAX_REPEATS:
        return f"--repeats must be between 1 and {MAX_REPEATS}, got {args.repeats}"
    if not 1 <= args.runs <= MAX_RUNS:
        return f"--runs must be between 1 and {MAX_RUNS}, got {args.runs}"
    if args.case:
        from .hard import case_names, unknown_cases

        bad = unknown_cases(args.case)
        if bad:
            return f"--case {', '.join(bad)}: unknown hard case; known: {', '.join(case_names())}"
    return None


def run(args) -> int:
    """Run the benchmark ``args.what``; exit code (``hard``: 1 if any cell is WRONG, else 0;
    2 a bad flag or an unwritable ``--out``, refused before any run)."""
    out = Path(args.out)
    why = check_options(args)
    if why:
        return _error(why)
    try:
        check_output_path(out, "--out")
    except OutputError as e:
        return _error(str(e))
    t_run = time.time()                 # the headline takes the reports written from here on
    if args.what in ("default", "coldstart"):
        from .coldstart import coldstart

        coldstart(out, quick=args.quick, repeats=args.repeats)
    if args.what == "coldstart":
        return 0
    if args.what in ("default", "consumer"):
        consumer(out, quick=args.quick, repeats=args.repeats, whole_command=not args.no_whole_command)
    if args.what in ("default", "roughness"):
        from .roughness import roughness

        roughness(out, quick=args.quick)
    if args.what in ("default", "peer"):
        from .peer_mujoco import peer

        rc = peer(out, quick=args.quick, repeats=args.repeats, required=args.what == "peer")
        if args.what == "default":
            from .headline import headline

            headline(out, since=t_run)
        return rc
    if args.what in ("default", "consumer", "roughness", "peer"):
        return 0
    if args.what == "accuracy":
        accuracy(out, quick=args.quick, repeats=args.repeats)
    elif args.what == "hard":
        rows = hard(out, quick=args.quick, cases=args.case)
        return 1 if any(r["verdict"] == "WRONG" for r in rows) else 0
    elif args.what == "sweep":
        from ..sweep.scaling import scaling, table

        rows = scaling(out, runs=args.runs)
        print(table(rows), end="")
        return 0 if all(r["identical_to_1_worker"] for r in rows) else 1
    elif args.what == "effects":
        effects_cost(out, repeats=args.repeats)
    else:
        res = hotpath(repeats=args.repeats)
        out.mkdir(parents=True, exist_ok=True)
        write_json(out / "hotpath.json", res, indent=1)
    return 0
