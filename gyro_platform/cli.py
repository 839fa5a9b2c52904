"""``gyro-platform`` command line: ``run`` a scene, ``replay`` a bag, ``bench`` speed/accuracy,
``node`` (ROS 2 node on rclpy or on plain DDS).

Each subcommand lives in the module that owns it; that module provides
``add_arguments(parser)`` and ``run(args) -> int``. Imports are lazy so that ``--help`` is fast
and a missing optional dependency only affects its own subcommand.
"""
from __future__ import annotations

import argparse
import importlib
import sys

SUBCOMMANDS = {
    "run": ("gyro_platform.scene", "run a scene file: summary table, CSV/JSON, plot"),
    "replay": ("gyro_platform.replay", "replay a rosbag2 bag through the simulator into an output bag"),
    "bench": ("gyro_platform.bench", "benchmarks: accuracy versus time, hot path, effects cost"),
    "node": ("gyro_platform.node_main", "run the ROS 2 node (rclpy or plain DDS transport)"),
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="gyro-platform", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    for name, (module, help_) in SUBCOMMANDS.items():
        p = sub.add_parser(name, help=help_, description=help_)
        p.set_defaults(_module=module)
        try:
            importlib.import_module(module).add_arguments(p)
        except ImportError as e:  # the subcommand's own dependency is missing
            p.set_defaults(_import_error=str(e))
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    err = getattr(args, "_import_error", None)
    if err:
        print(f"gyro-platform {args.command}: unavailable: {err}", file=sys.stderr)
        return 2
    return int(importlib.import_module(args._module).run(args) or 0)


if __name__ == "__main__":
    sys.exit(main())
