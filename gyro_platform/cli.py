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

"""gyro-platform command line: run a scene, replay a bag, benchmark, run the ROS 2 node, sweep.

Each subcommand lives in the module that owns it; that module provides
``add_arguments(parser)`` and ``run(args) -> int``. Imports are lazy so that a missing optional
dependency only affects its own subcommand.

Exit status, the same for every subcommand (``EXIT_CODES``, defined in ``gyro_platform.errors``;
also in every ``--help``):
0 success; 1 the command ran but failed (an expectation failed or could not be evaluated, the
simulation failed, the transport could not start); 2 bad argument or path, refused before
anything is written (argparse's convention: unknown flag, value out of range, missing file, a
file that is not a bag or scene, an invalid scene, an unwritable output path, a run beyond the
memory/step bounds); 3 unusable input data (a damaged bag: what was readable is processed and
written; or no usable input sample: no outputs); 4 an output could not be written during the
run (disk full, file size limit); 130 interrupted (Ctrl-C); 143 terminated (SIGTERM, the same
orderly stop as Ctrl-C: :class:`~gyro_platform.errors.StopSignals`). Errors are one line on
stderr, ``gyro-platform <command>: error: …``.
"""
from __future__ import annotations

import argparse
import gc
import importlib
import os
import signal
import sys
from typing import NoReturn

from . import __version__
from .errors import (EXIT_CODES, EXIT_DATA, EXIT_FAILED, EXIT_INTERRUPTED, EXIT_OK, EXIT_TERMINATED, EXIT_USAGE,
                     EXIT_WRITE, not_finite)
from .filesystem import write_failure
from .heap import keep_freed_memory
from .signals import exit_now, stop_exit_code, stop_reason, StopSignals

__all__ = ["main", "entry", "platform_node", "build_parser", "SUBCOMMANDS", "EXIT_CODES", "EXIT_OK",
           "EXIT_FAILED", "EXIT_USAGE",
           "EXIT_DATA", "EXIT_WRITE", "EXIT_INTERRUPTED", "EXIT_TERMINATED"]   # re-exported from errors

EPILOG = "exit status:\n" + "\n".join(f"  {code:<4}{text}" for code, text in EXIT_CODES.items())
#: what a subcommand does differently with the codes above
EPILOG_NOTES = {"node": "\n\nnode: Ctrl-C or SIGTERM is how a node is stopped (ros2 launch, systemd): exit 0 after a "
                        "last /diagnostics, not 130/143"}

SUBCOMMANDS = {
    "run": ("gyro_platform.scenes.command", "run a scene (file or name): summary table, CSV/JSON, plot"),
    "replay": ("gyro_platform.replay.command", "replay a rosbag2 bag through the simulator into an output bag"),
    "bench": (
        "gyro_platform.bench.command",
        "benchmarks: consumer figures beside the kernel, MuJoCo peer, accuracy versus time, hard cases, "
        "hot path, effects cost",
    ),
    "node": ("gyro_platform.ros.command", "run the ROS 2 node (rclpy or plain DDS transport)"),
    "sweep": ("gyro_platform.sweep.command", "Monte Carlo drift budgets and fleet replays on Dask"),
    "compile": ("gyro_platform.prefill.command",
                "compile the kernels of the default scene, the node and the replay into the cache (set-up, image "
                "or colcon build step)"),
}


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser of every subcommand; given ``command``, only that subcommand's module is
    imported for its arguments (the others are listed with their help, without arguments), so
    that a command pays only for its own imports."""
    parser = argparse.ArgumentParser(
        prog="gyro-platform", epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Gyro-stabilised three-gyro platform simulator: run a scene, replay a rosbag2 bag, "
                    "benchmark, or run the ROS 2 node.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="{" + ",".join(SUBCOMMANDS) + "}")
    for name, (module, help_) in SUBCOMMANDS.items():
        p = sub.add_parser(name, help=help_, description=help_, epilog=EPILOG + EPILOG_NOTES.get(name, ""),
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        p.set_defaults(_module=module)
        if command is not None and name != command:
            continue
        try:
            importlib.import_module(module).add_arguments(p)
        except ImportError as e:  # the subcommand's own dependency is missing
            p.set_defaults(_import_error=str(e))
    return parser


def _quiet_broken_pipe() -> None:
    """stdout's reader went away (``… | head -1``): point stdout at devnull so the interpreter's
    final flush does not raise again (the Python docs' recipe for SIGPIPE)."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):
        pass


def _check_scalar_values(parser: argparse.ArgumentParser, args: argparse.Namespace) -> str | None:
    """argparse turns ``--flag=--`` into ``[]`` without calling the flag's type: refuse any
    single-valued option (int, float or text) whose value is not of its type (argparse's
    one-line error, exit 2). A float flag that is not finite (``inf``, ``nan``, ``1e400``:
    ``errors.not_finite``, the rule of every number) gives the error line to print (exit 2)."""
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices[args.command]
    for action in sub._actions:
        typ = str if action.type is None else action.type
        if (action.nargs is None and typ in (int, float, str) and action.option_strings
                and isinstance(action, argparse._StoreAction)):
            value = getattr(args, action.dest, None)
            if value is not None and value is not action.default and not isinstance(value, typ):
                kind = "" if typ is str else f" {typ.__name__}"
                sub.error(f"argument {'/'.join(action.option_strings)}: expected one{kind} value")
            if typ is float and value is not None and not_finite(value):    # the rule of every number
                return f"argument {'/'.join(action.option_strings)}: {not_finite(value)}"
    return None


def command_of(argv: list[str]) -> str:
    """The subcommand named on a command line: its first word that is no option ("" if none;
    the only options before it are ``--help`` and ``--version``, which take no value)."""
    return next((a for a in argv if not a.startswith("-")), "")


#: the commands that end within minutes: their C heap keeps what they free (``heap``; not the node)
BATCH = ("run", "replay", "bench", "compile", "sweep")
#: commands that end with a plot unless told ``--no-plot`` (their helper starts first: reports.plot_process)
PLOTTING = ("run", "replay")


def main(argv: list[str] | None = None) -> int:
    """``gyro-platform …``: the exit status (see :data:`EXIT_CODES`)."""
    # the process's own command line: the start-up's imports (numpy, numba, the command's modules)
    # make objects that live as long as the process, and the collector's passes over them while
    # they are made free nothing (~25 ms of a replay's start here, 128 collections); switched on
    # again, those objects frozen, before the command runs (_main)
    quiet = argv is None and gc.isenabled()
    if quiet:
        gc.disable()
    try:
        return _main(argv, quiet)
    except KeyboardInterrupt:               # Ctrl-C while the command is still being imported and set up
        print("gyro-platform: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    finally:
        if quiet:
            gc.enable()


def _main(argv: list[str] | None, quiet: bool = False) -> int:
    """The command of ``argv`` (None: this process's command line); ``quiet``: the collector was
    switched off for the start-up (:func:`main`), to be switched on again before the command runs."""
    from .engine.blas import limit_blas_threads
    limit_blas_threads()        # small matrices: one BLAS thread (engine.blas); before NumPy loads, whose
    #                             OpenBLAS then starts no worker threads (its import 0.10 -> 0.05 s)
    words = sys.argv[1:] if argv is None else argv
    command = command_of(words)
    if argv is None and command in BATCH:
        keep_freed_memory()     # a short run: memory it frees kept for its next chunk (heap.py)
    if argv is None and command in PLOTTING and not {"--no-plot", "-h", "--help"} & set(words):
        from .reports import plot_process
        plot_process.start()            # matplotlib imported beside this process's start-up
    parser = build_parser(command)
    args = parser.parse_args(argv)
    bad = _check_scalar_values(parser, args)
    if bad:
        print(f"gyro-platform {args.command}: error: {bad}", file=sys.stderr)
        return EXIT_USAGE
    err = getattr(args, "_import_error", None)
    if err:
        print(f"gyro-platform {args.command}: error: unavailable: {err}", file=sys.stderr)
        return EXIT_USAGE
    prog = f"gyro-platform {args.command}"
    if argv is None:                                # the process's own command line (not a library call)
        from .physics.jit import compile_notices
        compile_notices(prog)                       # kernels compiling: said on stderr, interruptible
        # the start-up's objects (numpy, numba, the command's modules) out of the collector's
        # full scans, as the node does after its warm-up (ros.warmup; no collection first here:
        # it would cost what it saves): 4-7 % of a warm `run default` or `replay` command; the
        # collector, off while they were made (main), on again for the command
        gc.freeze()
    if quiet:
        gc.enable()
    with StopSignals(prog, final=argv is None):      # argv None: the process's own command line
        try:
            return int(importlib.import_module(args._module).run(args) or 0)
        except BrokenPipeError:
            _quiet_broken_pipe()
            return EXIT_OK
        except KeyboardInterrupt as e:      # Ctrl-C or SIGTERM before the command could stop in order
            print(f"{prog}: {stop_reason(e)}", file=sys.stderr)
            return stop_exit_code(e)
        except Exception as e:              # an output failed where the command does not catch it
            why = write_failure(e)
            if why is None:
                raise
            print(f"{prog}: error: cannot write the output: {why}", file=sys.stderr)
            return EXIT_WRITE


def entry() -> NoReturn:
    """The ``gyro-platform`` console script and ``python -m gyro_platform``: :func:`main` on this
    process's command line, then :func:`exit_now` with its status."""
    exit_now(main())


def platform_node() -> int:
    """``ros2 run gyro_platform platform_node`` (setup.py's console script): one BLAS thread set
    before NumPy loads (rclpy's and the node's imports load it; engine.blas), then the node's
    ``main``. Through ``gyro_platform.ros.node:main`` directly NumPy's OpenBLAS started a worker
    per core first (~50 ms of the node's start here, and idle threads on a many-core computer).
    The collector is off while the node's modules load and it warms up, as for a command line
    (:func:`main`); it is on again once the start-up's objects are frozen
    (``ros.warmup.freeze_startup_objects``). Ctrl-C while the modules load ends it quietly
    (exit 0), as it does later."""
    gc.disable()
    try:
        from .engine.blas import limit_blas_threads
        limit_blas_threads()
        from .ros.node import main as node_main
    except KeyboardInterrupt:   # Ctrl-C while numba and rclpy load (~1 s): a stop like any later one
        signal.signal(signal.SIGINT, signal.SIG_IGN)        # ros2 launch's second SIGINT
        return 0
    return node_main()


if __name__ == "__main__":
    entry()
