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
  rosbag2 bag, no input topic, a bad option: one line, nothing written); 3 the input is damaged
  (the readable part is processed, the output bag is closed and readable, the summary names
  the error); 130 interrupted. Results go to stdout, progress and errors to stderr.
"""
from __future__ import annotations

import argparse
import math
import re
import sys
from typing import Any

from ..errors import (EXIT_DATA, EXIT_INTERRUPTED, EXIT_OK, EXIT_USAGE, BagPathError, BagReadError,
                      ReplayError)
from ..io.gate import GateConfig
from ..io.messages import Mounting
from .loop import DEFAULT_DIAGNOSTICS_RATE, DEFAULT_OUTPUT_RATE, ReplayConfig, replay

#: a ROS 2 namespace (empty or "/" = root): tokens [A-Za-z_][A-Za-z0-9_]*, no "__", joined by "/"
NAMESPACE_RE = re.compile(r"/?(?:(?!.*__)[A-Za-z_][A-Za-z0-9_]*(?:/[A-Za-z_][A-Za-z0-9_]*)*/?)?")


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
    frames = dict(Mounting.parse_spec(s) for s in args.mount)
    cfg = ReplayConfig(
        topic=args.topic, storage=args.storage, diagnostics_rate=args.diagnostics_rate,
        mounting=Mounting(frames, unknown_frame=args.unknown_frame),
        gate=GateConfig(max_gap=args.max_gap, on_gap=args.on_gap, reset_on_jump_back=args.reset_on_jump_back,
                        max_rate=args.max_rate, time_source=args.time_source),
        namespace=args.namespace, plot=not args.no_plot, progress=not args.quiet)
    if args.scene:
        from ..scenes.schema import load_scene

        scene = load_scene(args.scene)
        cfg.params, cfg.options = scene.params, scene.options
        if getattr(scene, "output_rate", None):
            cfg.output_rate = float(scene.output_rate)
    if args.output_rate is not None:
        if not (math.isfinite(args.output_rate) and args.output_rate >= 0):
            raise ReplayError(f"--output-rate {args.output_rate}: must be a finite rate >= 0 Hz (0 = every sample)")
        cfg.output_rate = args.output_rate if args.output_rate > 0 else None
    if not (math.isfinite(cfg.diagnostics_rate) and cfg.diagnostics_rate > 0):
        raise ReplayError(f"--diagnostics-rate {cfg.diagnostics_rate}: must be a finite rate > 0 Hz")
    if not NAMESPACE_RE.fullmatch(cfg.namespace):
        raise ReplayError(f"--namespace {cfg.namespace!r}: not a ROS namespace (tokens of letters, digits and "
                          f"'_' separated by '/', not starting with a digit)")
    return cfg


def run(args: argparse.Namespace) -> int:
    """``gyro-platform replay``: exit 0 ok, 2 cannot start (bad argument, not a bag, no input
    topic), 3 input damaged (partial output written), 130 interrupted. Results go to stdout,
    progress, warnings and errors to stderr."""
    try:
        cfg = config_from_args(args)
        summary = replay(args.in_bag, args.out, cfg)
    except BagPathError as e:
        print(f"gyro-platform replay: error: {e}", file=sys.stderr)
        return EXIT_USAGE
    except BagReadError as e:    # rosbags and the salvage reader both failed: corrupt data
        print(f"gyro-platform replay: error: {e}", file=sys.stderr)
        return EXIT_DATA
    except (ReplayError, ValueError) as e:
        print(f"gyro-platform replay: error: {e}", file=sys.stderr)
        return EXIT_USAGE
    print_results(summary, args.out)
    if summary["counts"]["in"] and not summary["counts"]["accepted"] and not summary["error"]:
        print(f"gyro-platform replay: error: {summary['warnings'][0]}", file=sys.stderr)
        return EXIT_USAGE
    if summary["error"]:
        if summary["error"] == "interrupted":
            print("gyro-platform replay: interrupted; the output bag is closed and readable", file=sys.stderr)
            return EXIT_INTERRUPTED
        print(f"gyro-platform replay: error: {summary['error']}; output bag closed and readable "
              f"({summary['output']['messages']} messages)", file=sys.stderr)
        return EXIT_DATA
    return EXIT_OK
