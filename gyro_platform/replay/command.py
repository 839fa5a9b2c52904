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

"""``gyro-platform replay IN_BAG --out OUT_BAG [--topic T] [--scene S] [--storage sqlite3|mcap]
[--output-rate HZ] [--mount FRAME=qx,qy,qz,qw | FRAME=roll,pitch,yaw] …``: the command line.

* Input: a rosbag2 directory (any version rosbags reads, sqlite3 or mcap; bags without type
  definitions are read with the Jazzy typestore) or a single ``.db3``/``.mcap`` file; the input
  topic (``--topic``; default: the first ``Imu``/``Twist``/``TwistStamped`` topic).
* Output: a rosbag2 version-9 bag (storage of the input unless ``--storage``) with every input
  connection copied byte for byte plus the output topics in the root namespace (or
  ``--namespace``), on the grid ``floor((t − t_origin)·rate)`` (default 10 Hz, ``--output-rate
  0``: every accepted sample); ``/diagnostics`` at 1 Hz of receive time. Next to it
  ``OUT_BAG.summary.json`` and ``OUT_BAG.png``.
* Exit status (``gyro_platform.errors.EXIT_CODES``): 0 ok; 2 cannot start (a path that is no
  rosbag2 bag, no input topic, a bad option, an output path that cannot be written: one line,
  nothing written); 3 the input is damaged (the readable part is processed, the output bag is
  closed and readable, the summary names the error) or gave no output (empty topic, every
  sample dropped or refused); 4 the output could not be written (disk full, file size limit:
  one line, what was written is closed); 130 interrupted (Ctrl-C), 143 terminated (SIGTERM):
  the output bag is closed and readable, the summary's ``error`` says ``interrupted`` /
  ``terminated``. Results go to stdout, progress and errors to stderr.
"""
from __future__ import annotations

import argparse
import re
import sys
from typing import Any

from .loop import DEFAULT_DIAGNOSTICS_RATE, DEFAULT_OUTPUT_RATE, replay, ReplayConfig, sidecar_paths
from ..errors import (BagPathError, BagReadError, EXIT_DATA, EXIT_INTERRUPTED, EXIT_OK, EXIT_TERMINATED, EXIT_USAGE,
                      EXIT_WRITE, OutputError, ReplayError)
from ..filesystem import check_output_path, write_failure
from ..messages import Mounting
from ..pipeline.gate_rules import GateConfig
from ..pipeline.grid import check_grid_rate
from ..pipeline.outcomes import no_sample_hint, nothing_integrated_hint

#: a ROS 2 namespace (empty or "/" = root): tokens [A-Za-z_][A-Za-z0-9_]*, no "__", joined by "/"
#: (rmw_validate_namespace, plus the design article's rule against repeated underscores)
NAMESPACE_RE = re.compile(r"/?(?:(?!.*__)[A-Za-z_][A-Za-z0-9_]*(?:/[A-Za-z_][A-Za-z0-9_]*)*/?)?")
#: rmw's RMW_TOPIC_MAX_NAME_LENGTH (255 less 8 reserved for the DDS prefixes): the longest
#: fully qualified topic name, here namespace + output topic
TOPIC_MAX_NAME_LENGTH = 247


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``gyro-platform replay``."""
    p = parser
    p.add_argument("in_bag", metavar="IN_BAG", help="rosbag2 directory (sqlite3 or mcap) or .db3/.mcap file")
    p.add_argument("--out", required=True, metavar="OUT_BAG", help="output bag directory (must not exist)")
    p.add_argument("--topic", help="input topic (default: the first Imu/Twist/TwistStamped topic)")
    p.add_argument("--scene", metavar="S", help="scene YAML: params, options, output rate")
    p.add_argument("--storage", choices=("sqlite3", "mcap"), help="output storage (default: as the input)")
    p.add_argument("--output-rate", type=float, metavar="HZ",
                   help=f"output rate, Hz (default: the scene's, else {DEFAULT_OUTPUT_RATE:g}; 0 = every sample)")
    p.add_argument("--diagnostics-rate", type=float, default=DEFAULT_DIAGNOSTICS_RATE, metavar="HZ",
                   help="/diagnostics rate on the receive clock, Hz (default 1)")
    p.add_argument("--mount", action="append", default=[], metavar="FRAME=Q",
                   help="sensor mounting in base_link: FRAME=qx,qy,qz,qw or FRAME=roll,pitch,yaw (rad); repeatable")
    p.add_argument("--unknown-frame", choices=Mounting.UNKNOWN_POLICIES, default="identity",
                   help="frame_id without --mount: take as base_link (default) or drop the samples")
    p.add_argument("--time-source", choices=("auto", "header", "receive"), default="auto",
                   help="sample time: header stamp, bag receive time, or auto (header unless the first is 0)")
    p.add_argument("--max-gap", type=float, default=GateConfig.max_gap, metavar="S",
                   help=f"longest input gap, s (default {GateConfig.max_gap:g})")
    p.add_argument("--on-gap", choices=("reset", "integrate"), default=GateConfig.on_gap,
                   help="after a longer gap: restart the simulation (default) or integrate across")
    p.add_argument("--reset-on-jump-back", type=float, default=GateConfig.reset_on_jump_back, metavar="S",
                   help=f"time jumping back more than this restarts (looped bag), s (default "
                        f"{GateConfig.reset_on_jump_back:g}); smaller steps back are dropped")
    p.add_argument("--max-rate", type=float, default=GateConfig.max_rate, metavar="RAD_S",
                   help=f"drop samples with |omega| above this, rad/s (default {GateConfig.max_rate:g})")
    p.add_argument("--max-specific-force", type=float, default=GateConfig.max_specific_force, metavar="M_S2",
                   help=f"drop samples with |specific force| above this, m/s² (default "
                        f"{GateConfig.max_specific_force:g} ≈ 200 g)")
    p.add_argument("--namespace", default="", help="namespace of the output topics (default: root)")
    p.add_argument("--no-plot", action="store_true", help="do not write OUT_BAG.png")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def print_results(summary: dict[str, Any], out_bag: Any, file: Any = None) -> None:
    """The replay's results on stdout: counts, output files, warnings."""
    out = file if file is not None else sys.stdout
    c = summary["counts"]
    drops = f" {c['dropped_by_reason']}" if c["dropped_by_reason"] else ""
    print(f"{summary['input']['topic']}: {c['in']} in, {c['accepted']} accepted, {c['dropped']} dropped{drops}, "
          f"{c['resets']} resets; {c['out']} outputs; "
          f"{summary['duration_s']:.1f} s of data in {summary['wall_time_s']:.2f} s "
          f"(x{summary['real_time_factor'] or 0:.0f} real time) -> {out_bag}", file=out)
    d = summary.get("drift") or {}
    if "drift_rate_deg_h" in d:
        print(f"drift rate (least-squares slope of the drift angle over the last {d['fit_s']:.1f} s): "
              f"{d['drift_rate_deg_h']['norm']:.4g} deg/h", file=out)
    for w in summary.get("warnings", []):
        print(f"warning: {w}", file=out)
    files = summary["files"]
    print("wrote " + ", ".join(str(files[k]) for k in ("bag", "summary", "plot") if files.get(k)), file=out)


def config_from_args(args: argparse.Namespace) -> ReplayConfig:
    """ReplayConfig from parsed arguments (loads the scene if given)."""
    try:
        frames = Mounting.parse_specs(args.mount)
    except ValueError as e:
        raise ReplayError(f"--mount: {e}") from None
    try:
        gate = GateConfig(max_gap=args.max_gap, on_gap=args.on_gap, reset_on_jump_back=args.reset_on_jump_back,
                          max_rate=args.max_rate, max_specific_force=args.max_specific_force,
                          time_source=args.time_source)
    except ValueError as e:     # "max_gap = inf s; must be > 0": name the flag
        raise ReplayError(f"--{str(e).split(' ', 1)[0].replace('_', '-')}: {e}") from None
    cfg = ReplayConfig(
        topic=args.topic, storage=args.storage, diagnostics_rate=args.diagnostics_rate,
        mounting=Mounting(frames, unknown_frame=args.unknown_frame), gate=gate,
        namespace=args.namespace, plot=not args.no_plot, progress=not args.quiet)
    if args.scene:
        from ..scenes.schema import load_scene

        scene = load_scene(args.scene)
        cfg.params, cfg.options = scene.params, scene.options
        if getattr(scene, "output_rate", None):
            cfg.output_rate = float(scene.output_rate)
    try:
        check_grid_rate(args.output_rate, "--output-rate")
        check_grid_rate(cfg.diagnostics_rate, "--diagnostics-rate", zero_ok=False)
    except ValueError as e:
        raise ReplayError(str(e)) from None
    if args.output_rate is not None:
        cfg.output_rate = args.output_rate if args.output_rate > 0 else None
    check_namespace(cfg.namespace)
    return cfg


def check_namespace(namespace: str) -> None:
    """ReplayError unless ``namespace`` is a ROS 2 namespace whose output topics stay within
    rmw's topic name length."""
    if not NAMESPACE_RE.fullmatch(namespace):
        raise ReplayError(f"--namespace {namespace!r}: not a ROS namespace (tokens of letters, digits and "
                          f"'_' separated by '/', not starting with a digit, no '__')")
    from ..messages import output_topics

    longest = max(output_topics(namespace), key=len)
    if len(longest) > TOPIC_MAX_NAME_LENGTH:
        raise ReplayError(f"--namespace: too long: output topic {longest[:40]}… has {len(longest)} characters, "
                          f"ROS 2 allows {TOPIC_MAX_NAME_LENGTH}")


def check_outputs(args: argparse.Namespace) -> None:
    """OutputError (one line) when ``--out`` or its sidecar files cannot be written."""
    summary, plot = sidecar_paths(args.out)
    check_output_path(args.out, "--out", new=True, siblings=(summary,) if args.no_plot else (summary, plot))


def run(args: argparse.Namespace) -> int:
    """``gyro-platform replay``: exit 0 ok, 2 cannot start (bad argument, not a bag, no input
    topic, unwritable output), 3 input damaged (partial output written) or no output, 4 the
    output could not be written, 130 interrupted, 143 terminated. Results go to stdout,
    progress, warnings and errors to stderr."""
    def error(text: str) -> None:
        print(f"gyro-platform replay: error: {text}", file=sys.stderr)

    try:
        cfg = config_from_args(args)
        check_outputs(args)
    except (ReplayError, OutputError, ValueError) as e:      # refused before anything is written
        error(str(e))
        return EXIT_USAGE
    try:
        summary = replay(args.in_bag, args.out, cfg)
    except BagPathError as e:
        error(str(e))
        return EXIT_USAGE
    except BagReadError as e:    # rosbags and the salvage reader both failed: corrupt data
        error(str(e))
        return EXIT_DATA
    except ReplayError as e:
        error(str(e))
        return EXIT_USAGE
    except OutputError as e:     # the output bag failed during the run (closed with what it held)
        error(f"cannot write the output: {e}")
        return EXIT_WRITE
    except Exception as e:       # noqa: BLE001 - a write failure during the run, or a bad value
        why = write_failure(e)
        if why is not None:
            error(f"cannot write the output: {why}; what was written is closed")
            return EXIT_WRITE
        if isinstance(e, ValueError):
            error(str(e))
            return EXIT_USAGE
        raise
    print_results(summary, args.out)
    if summary.get("write_error"):      # the bag closed with what it held; the summary written if it could be
        error(f"cannot write the output: {summary['write_error']}; what was written is closed")
        return EXIT_WRITE
    no_output = not_usable(summary)
    if no_output and not summary["error"]:
        error(no_output)
        return EXIT_DATA
    if summary["error"] in ("interrupted", "terminated"):
        print(f"gyro-platform replay: {summary['error']}; the output bag is closed and readable", file=sys.stderr)
        return EXIT_INTERRUPTED if summary["error"] == "interrupted" else EXIT_TERMINATED
    if summary["error"]:
        error(f"{summary['error']}; output bag closed and readable ({summary['output']['messages']} messages)")
        return EXIT_DATA
    return EXIT_OK


def not_usable(summary: dict[str, Any]) -> str | None:
    """Why a finished replay gave no usable output (one line): none at all, or only the initial
    state (no interval integrated); None if it gave some."""
    c = summary["counts"]
    if c["out"]:
        return nothing_integrated_hint(c["simulator"], c["resets_by_reason"], c["accepted"],
                                       summary["config"]["gate"]["max_gap"])
    if not c["in"]:
        return f"topic {summary['input']['topic']} has no messages: no outputs"
    if not c["accepted"]:
        return no_sample_hint(c["dropped_by_reason"], c["in"], summary["simulator"]["errors"])
    return (f"{c['accepted']} of {c['in']} input samples accepted but no output: the simulator refused them "
            f"({c['simulator']}); see the summary's simulator errors")
