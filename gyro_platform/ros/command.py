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

"""``gyro-platform node``: run the platform node on rclpy or on plain DDS (no ROS install).

``gyro-platform node [--transport auto|ros|dds] [--params-file FILE] [--scene S]
[--domain-id N] [--namespace NS] [--node-name NAME] [--cyclonedds-config FILE] [--duration S]``

* ``ros``: the rclpy node :func:`gyro_platform.ros.node.main` (needs a sourced ROS 2 Jazzy);
  ``dds``: :class:`gyro_platform.ros.dds.PlatformDdsNode` around the same
  :class:`gyro_platform.ros.core.NodeCore`, speaking rmw_cyclonedds' wire format through the
  ``cyclonedds`` package; ``auto`` (default): rclpy if it imports, else DDS. The first log line
  says which transport runs and why.
* ``--params-file``: the rclpy params file (``config/platform.yaml``): its ``/**`` section and
  the sections of the node (``gyro_platform_node``, ``/ns/gyro_platform_node``) are merged, and
  their ``ros__parameters`` go to :meth:`NodeConfig.from_ros_params` — every parameter applies
  on DDS too, fixed at start (no parameter services on DDS: ``ros2 param`` cannot reach it);
  ``--scene`` sets the ``scene`` parameter (overriding the file's).
* ``--domain-id`` (default ``ROS_DOMAIN_ID``, else 0), ``--namespace`` (default ``/``),
  ``--cyclonedds-config`` (sets ``CYCLONEDDS_URI`` for this process; e.g.
  ``config/cyclonedds_loopback.xml``), ``--duration`` (s: stop by itself after that long).
  Without either, on a host with no multicast-capable interface the DDS transport uses
  localhost unicast discovery and logs what the ROS side must set (``dds.default_discovery``).
* Both transports warm up (:func:`gyro_platform.ros.warmup.start_core`: the numba kernels
  loaded, or answered by their interpreted form while they compile in the background) before
  they subscribe and log ``ready``; the process then freezes its start-up
  objects out of the garbage collector (:func:`gyro_platform.ros.warmup.freeze_startup_objects`).
* SIGINT / SIGTERM stop the node cleanly (final diagnostics, DDS entities deleted); exit 0 (a
  node's normal stop). A signal during the warm-up, before the node is ready, ends it like any
  command (``errors.StopSignals``: 130 / 143, the DDS entities deleted).
  Exit 2 on a bad parameter or argument, 1 when the transport cannot start.
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path
import signal
import sys
import time
from typing import Any, Callable

from .warmup import freeze_startup_objects, start_core
from ..errors import EXIT_FAILED, EXIT_OK, EXIT_USAGE

TRANSPORTS = ("auto", "ros", "dds")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--transport", choices=TRANSPORTS, default="auto",
                   help="ros: rclpy; dds: plain DDS (cyclonedds, no ROS install); auto: rclpy if it imports, else dds")
    p.add_argument("--params-file", metavar="FILE", help="ROS 2 params file (ros__parameters of /** and of the node)")
    p.add_argument("--scene", metavar="S", help="scene (file or name in config/scenes) giving the model defaults")
    p.add_argument("--domain-id", type=int, metavar="N", help="DDS domain (default: ROS_DOMAIN_ID, else 0)")
    p.add_argument("--namespace", default="/", metavar="NS", help="node namespace (default /)")
    p.add_argument("--node-name", default=None, metavar="NAME", help="node name (default gyro_platform_node)")
    p.add_argument("--cyclonedds-config", metavar="FILE", help="Cyclone DDS XML config (sets CYCLONEDDS_URI)")
    p.add_argument("--duration", type=float, metavar="S", help="stop after S seconds (default: run until a signal)")


def _log(name: str) -> Callable[[str], None]:
    def log(text: str) -> None:
        print(f"[{name}] {text}", file=sys.stderr, flush=True)
    return log


# =========================================================================================
# parameters
# =========================================================================================
def build_config(args: argparse.Namespace, node_name: str) -> tuple[Any, dict[str, Any]]:
    """NodeConfig from ``--params-file`` and ``--scene`` (ConfigError on a bad value), and the
    parameters it was built from (ROS's own, such as ``use_sim_time``, among them)."""
    from .config import load_params_file, NodeConfig

    params = load_params_file(args.params_file, node_name) if args.params_file else {}
    if args.scene:
        params["scene"] = args.scene
    return NodeConfig.from_ros_params(params), params


# =========================================================================================
# transports
# =========================================================================================
def rclpy_available() -> tuple[bool, str]:
    """(True, "") when the rclpy node imports (rclpy and the message packages it needs), else
    (False, why)."""
    try:
        from . import node  # noqa: F401
    except Exception as e:  # noqa: BLE001 - ImportError, or a broken ROS environment
        return False, str(e).split(";")[0]
    return True, ""


def run(args: argparse.Namespace) -> int:
    from .parameters import NODE_NAME

    name = args.node_name or NODE_NAME
    log = _log(name)
    transport = args.transport
    if transport == "auto":
        ok, why = rclpy_available()
        transport = "ros" if ok else "dds"
        log(f"transport: {transport} (auto: " + ("rclpy found)" if ok else f"rclpy not available: {why})"))
    else:
        log(f"transport: {transport}")
    if args.duration is not None and not args.duration > 0:
        log(f"error: --duration {args.duration}: must be > 0")
        return EXIT_USAGE
    if args.cyclonedds_config:
        cfg = Path(args.cyclonedds_config).expanduser()
        if not cfg.is_file():
            log(f"error: --cyclonedds-config {cfg}: no such file")
            return EXIT_USAGE
        os.environ["CYCLONEDDS_URI"] = cfg.resolve().as_uri()
    if args.domain_id is not None:
        if not 0 <= args.domain_id <= 232:
            log(f"error: --domain-id {args.domain_id}: outside 0..232")
            return EXIT_USAGE
        os.environ["ROS_DOMAIN_ID"] = str(args.domain_id)
    return run_ros(args, name, log) if transport == "ros" else run_dds(args, name, log)


def run_dds(args: argparse.Namespace, name: str, log: Callable[[str], None]) -> int:
    from .parameters import ConfigError
    from ..messages import MessageTypes

    try:
        from .dds_types import import_cyclonedds
        import_cyclonedds()
        from . import dds
    except ImportError as e:
        log(f"error: {e}")
        return EXIT_FAILED
    from .dds_discovery import default_discovery, interface_flags
    from .dds_names import domain_id_from_env, normalize_namespace, validate_node_name
    from .dds_types import IdlTypes, zero_message
    from ..messages.typedefs import core_typestore

    uri, hint = default_discovery(dict(os.environ), interface_flags())
    if uri is not None:
        os.environ["CYCLONEDDS_URI"] = uri
        log(hint)
    try:
        config, params = build_config(args, name)
        if params.get("use_sim_time") is True:
            log("warning: use_sim_time is ignored on the DDS transport (no /clock subscription): the node clock is "
                "the wall clock; outputs still carry the input's header stamps")
        validate_node_name(name)
        namespace = normalize_namespace(args.namespace)
        domain = domain_id_from_env(args.domain_id)
    except (ConfigError, ValueError) as e:
        log(f"error: {e}")
        return EXIT_USAGE
    store = core_typestore()        # the node's types only (~10 ms; rosbags' whole Jazzy store: 0.14 s of its start)
    try:
        core = start_core(config, MessageTypes.rosbags(store), lambda: zero_message(store, config.input_type_name),
                          prog=f"gyro-platform node ({name})", notice=log)
    except Exception as e:  # noqa: BLE001 - a model that cannot be built: one line
        log(f"error: cannot start the simulation: {type(e).__name__}: {e}")
        return EXIT_FAILED
    try:
        node = dds.DdsNode(name, namespace, domain, types=IdlTypes(store))
    except Exception as e:  # noqa: BLE001 - DDSException: bad CYCLONEDDS_URI, no interface …
        log(f"error: cannot join DDS domain {domain}: {type(e).__name__}: {e} "
            f"(CYCLONEDDS_URI={os.environ.get('CYCLONEDDS_URI', '')!r})")
        return EXIT_FAILED
    adapter = None
    try:
        adapter = dds.PlatformDdsNode(core, node, diagnostics_period=1.0 / config["diagnostics_rate"], log=log)
        adapter.warm_up()
        freeze_startup_objects()

        def on_signal(signum: int, _frame: Any) -> None:
            adapter.stop()

        old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
        try:
            topics = adapter.topics
            log(f"ready: DDS domain {domain}, node {node.fully_qualified_name}, mode {config['mode']}, "
                f"input {core.input_type} on {topics['in'][0]}, reset on {', '.join(topics['in'][1:]) or '-'}, "
                f"{len(topics['out'])} output topics, output rate {config['output_rate']:g} Hz")
            t0 = time.monotonic()
            adapter.spin(args.duration)
            st = adapter.transport_status()
            log(f"stopped after {time.monotonic() - t0:.1f} s: {st['processed']} inputs processed, "
                f"{st['published']} messages published, {st['samples_lost']} input samples lost")
        finally:
            for s, h in old.items():
                signal.signal(s, h)
    finally:
        (adapter or node).close()
    return EXIT_OK


def run_ros(args: argparse.Namespace, name: str, log: Callable[[str], None]) -> int:
    """The rclpy node with the same options, passed as ROS arguments."""
    try:
        from . import node as ros_node
    except ImportError as e:
        log(f"error: the rclpy node cannot be imported ({e}); use --transport dds")
        return EXIT_FAILED
    ros_args = ["--ros-args", "-r", f"__node:={name}"]
    if args.namespace and args.namespace != "/":
        ros_args += ["-r", f"__ns:=/{args.namespace.strip('/')}"]
    if args.params_file:
        ros_args += ["--params-file", str(Path(args.params_file).expanduser().resolve())]
    if args.scene:
        ros_args += ["-p", f"scene:={args.scene}"]
    if args.duration is not None:   # rclpy turns SIGINT into a clean shutdown
        signal.signal(signal.SIGALRM, lambda *_: os.kill(os.getpid(), signal.SIGINT))
        signal.setitimer(signal.ITIMER_REAL, float(args.duration))
    try:
        rc = ros_node.main(["gyro-platform-node", *ros_args])
    except KeyboardInterrupt:
        rc = 0
    finally:
        if args.duration is not None:
            signal.setitimer(signal.ITIMER_REAL, 0)
    return int(rc or 0)
