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

"""``gyro-platform compile``: compile the kernels of the shipped configurations into the cache.

A first command of a code version on a machine compiles the numba kernels its model and method
need (tens of seconds on a 2 GHz core); every later process of the same code — other clones,
reinstalls, colcon installs, containers sharing the cache folder, Dask workers — loads them in
about half a second (``physics.jit``). This command pays that once where waiting is expected
(the set-up command, an image build, ``colcon build``): it runs, each for a moment and without
writing anything outside a temporary folder,

* the scene ``--scene`` (default ``default``, the README's first command) for a few samples,
* the node's per-message path (its warm-up, ``ros.warmup``) in the configuration of
  ``--params-file`` (default: the node's defaults, those of ``config/platform.yaml``),
* a replay in the node's model configuration (the replay's defaults) of a one-second
  synthetic 100 Hz Imu bag of each storage (mcap, sqlite3).

One line per step with its time on stdout; compile notices on stderr as for every command.
Exit 0, or 1 when a step failed (what the other steps compiled stays cached).
"""
from __future__ import annotations

import argparse
from pathlib import Path
import shutil
import sys
import tempfile
import time
from typing import Callable

from ..errors import EXIT_FAILED, EXIT_OK, EXIT_USAGE
from ..physics.jit import cache_dir
from ..signals import Terminated

__all__ = ["add_arguments", "run", "steps"]

#: length of the synthetic bags replayed (s) and their rate (Hz)
BAG_SECONDS = 1.0
BAG_RATE = 100.0
#: scene time run (s): a few samples and output instants
SCENE_SECONDS = 0.2


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--scene", default="default",
                        help="scene (file or name in config/scenes) whose kernels to compile (default: default)")
    parser.add_argument("--params-file", default=None, metavar="YAML",
                        help="the node's ROS 2 parameters file (default: the node's defaults)")


def _scene_step(name: str) -> None:
    from ..scenes.runner import run_scene
    from ..scenes.schema import load_scene

    run_scene(load_scene(name).with_duration(SCENE_SECONDS))


def _scene_exists(name: str) -> None:
    from ..scenes.schema import load_scene

    load_scene(name)        # ScenarioError (a ValueError) for a bad name or file


def _node_config(params_file: str | None):
    from ..ros.command import build_config
    from ..ros.parameters import NODE_NAME

    args = argparse.Namespace(params_file=params_file, scene=None)
    return build_config(args, NODE_NAME)[0]


def _node_step(config) -> None:
    from ..messages import jazzy_typestore, MessageTypes
    from ..ros.core import NodeCore
    from ..ros.dds_types import zero_message
    from ..ros.warmup import warm_up

    store = jazzy_typestore()
    core = NodeCore(config, MessageTypes.rosbags(store))
    warm_up(core, lambda: zero_message(store, core.input_type))


def _replay_step(storage: str, work: Path) -> None:
    from ..bench.bags import vehicle_imu, write_imu_bag
    from ..replay.loop import replay, ReplayConfig

    bag = write_imu_bag(work / f"in_{storage}", vehicle_imu(BAG_SECONDS, rate=BAG_RATE), storage=storage)
    summary = replay(bag, work / f"out_{storage}", ReplayConfig(plot=False))
    stopped = summary.get("interrupted_by")
    if stopped:                 # the replay stopped in order on a signal: so does this command
        raise Terminated("terminated") if stopped == "SIGTERM" else KeyboardInterrupt()
    if summary.get("error"):
        raise RuntimeError(summary["error"])


def steps(scene: str, params_file: str | None, work: Path) -> list[tuple[str, Callable[[], None]]]:
    """The steps of the command: (what, function) in order."""
    config = _node_config(params_file)
    return [(f"scene {scene}", lambda: _scene_step(scene)),
            ("node (per-message path)", lambda: _node_step(config)),
            ("replay (mcap)", lambda: _replay_step("mcap", work)),
            ("replay (sqlite3)", lambda: _replay_step("sqlite3", work))]


def run(args: argparse.Namespace) -> int:
    prog = "gyro-platform compile"
    work = Path(tempfile.mkdtemp(prefix="gyro_platform_compile_"))
    failed = 0
    try:
        try:
            todo = steps(args.scene, args.params_file, work)
            _scene_exists(args.scene)
        except (ValueError, OSError) as e:       # ScenarioError, ConfigError
            print(f"{prog}: error: {e}", file=sys.stderr)
            return EXIT_USAGE
        print(f"{prog}: kernels cached in {cache_dir()}", flush=True)
        t_all = time.perf_counter()
        for what, step in todo:
            t0 = time.perf_counter()
            try:
                step()
            except Exception as e:      # noqa: BLE001 - one line; the other steps still run
                failed += 1
                print(f"{prog}: {what}: failed: {type(e).__name__}: {e}", file=sys.stderr)
                continue
            print(f"  {what}: {time.perf_counter() - t0:.1f} s", flush=True)
        print(f"{prog}: {len(todo) - failed} of {len(todo)} steps in {time.perf_counter() - t_all:.1f} s", flush=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return EXIT_FAILED if failed else EXIT_OK
