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

"""ROS 2 (rclpy, Jazzy) node of the gyro platform: a thin adapter around :class:`core.NodeCore`.

The only module of the package that imports rclpy. Everything the node does with a message —
mounting, time gate, integration, output grid, diagnostics content, parameter validation —
is in :mod:`gyro_platform.ros.core` (ROS-free, tested without ROS); this file wires it to rclpy:

* parameters: every entry of ``parameters.PARAMETERS`` declared with a ``ParameterDescriptor``
  (description, ``FloatingPointRange`` for every double, ``read_only``); a ``scene`` supplies
  the defaults of the model parameters (declared after it); changes go through
  ``core.set_parameters``. An empty string array (``sensor_mountings``) is declared by type
  and then set to ``[]`` explicitly, so ``ros2 param dump`` / ``get`` see a value;
* warm-up: before subscribing, a throwaway core runs a few synthetic samples
  (``warmup.start_core``), so numba loads every kernel and the first real Imu is answered at
  once; kernels not in the cache are not waited for (the interpreted ones answer while they
  compile in the background: ``engine.remote``); "ready" is logged after that;
* input: one subscription (``qos_profile_sensor_data``; history, depth and reliability
  overridable by ``qos_overrides.<topic>.subscription.*``) on ``imu_topic`` (``sensor_msgs/Imu``)
  or ``twist_topic`` (``geometry_msgs/Twist`` or ``TwistStamped``, by ``input_type``); each
  sample is integrated in its callback, receive time = the node clock (sim time with
  ``use_sim_time``). Lost input (QoS message-lost events and gaps in the header stamps; Cyclone
  DDS reports neither keep-last overwrites nor publication sequence numbers) is counted by
  ``overload.InputLoss`` and turns ``gyro_platform: node`` WARN;
* outputs: one publisher per output topic (reliable, keep last 10): ``gimbal/joint_states``,
  ``drift/angle``, ``drift/rate``, ``bearing/<name>/torque``, and ``/tf`` (keep last 100, as
  tf2_ros broadcasts) of ``platform`` → ``platform_reference``; the joints' TF and
  ``/robot_description`` come from ``robot_state_publisher`` (started by the launch file with the
  URDF of :mod:`gyro_platform.ros.urdf`) fed by ``gimbal/joint_states``;
* ``/diagnostics``: the core's DiagnosticArray plus ``gyro_platform: transport`` on a steady
  timer (it runs with ``use_sim_time`` and no /clock: then WARN "waiting for /clock", logged
  once) — the same status names as the plain-DDS transport;
* ``~/reset`` (``std_srvs/srv/Trigger``) and a backward jump of the node clock (looped
  ``ros2 bag play --clock --loop``) restart the simulation (once per loop: see
  ``NodeCore.on_clock_jump``).

Run: ``ros2 run gyro_platform platform_node --ros-args --params-file config/platform.yaml``.
Ctrl-C (also the second SIGINT ``ros2 launch`` sends) ends it quietly with exit code 0.
"""
from __future__ import annotations

import signal
import sys
import threading
import time
from typing import Any

try:
    from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor, SetParametersResult
    import rclpy
    from rclpy.clock import Clock, ClockType, JumpThreshold
    from rclpy.duration import Duration
    from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
    from rclpy.executors import ExternalShutdownException
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, qos_profile_sensor_data, QoSProfile, ReliabilityPolicy
    from rclpy.qos_overriding_options import QoSOverridingOptions
    from std_srvs.srv import Trigger
except ImportError as e:  # pragma: no cover - depends on the machine
    raise ImportError(
        f"gyro_platform.ros.node needs rclpy and the ROS 2 message packages ({e}); source a ROS 2 Jazzy "
        "install (source /opt/ros/jazzy/setup.bash) or use the ROS-free core "
        "(gyro_platform.ros.core) / 'gyro-platform node' on plain DDS") from e

from .config import NodeConfig, parameter_defaults, unknown_parameter_lines
from .core import DIAGNOSTICS_TOPIC
from .parameters import ConfigError, NODE_NAME, PARAMETERS, ParamSpec, SPECS
from .warmup import freeze_startup_objects, start_core
from ..messages import DIAGNOSTIC_ARRAY, MessageTypes, TF_TOPIC, transport_status
from ..physics.jit import compile_notices

#: output publishers: reliable, volatile, keep last 10 (the rclpy default profile, spelled out)
OUTPUT_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.VOLATILE)
#: ``/tf``: reliable, volatile, keep last 100 (tf2_ros' TransformBroadcaster)
TF_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100, reliability=ReliabilityPolicy.RELIABLE,
                    durability=DurabilityPolicy.VOLATILE)
#: a backward jump of the node clock larger than this resets the simulation
CLOCK_JUMP_BACK = Duration(nanoseconds=-1_000_000)   # 1 ms


def descriptor(spec: ParamSpec) -> ParameterDescriptor:
    """ROS parameter descriptor of one ``parameters.ParamSpec``."""
    d = ParameterDescriptor(description=spec.description + (f" [{spec.unit}]" if spec.unit else ""),
                            additional_constraints=spec.constraints(), read_only=spec.read_only)
    if spec.type == "double" and spec.range is not None:
        d.floating_point_range = [FloatingPointRange(from_value=float(spec.range[0]),
                                                     to_value=float(spec.range[1]), step=0.0)]
    return d


def _ros_value(v: Any) -> Any:
    """A core default as a ROS parameter value (tuples → lists)."""
    return list(v) if isinstance(v, tuple) else v


class PlatformNode(Node):
    """The gyro platform node (name ``gyro_platform_node``). ``kwargs`` go to ``rclpy.node.Node``
    (``cli_args``, ``parameter_overrides``, ``namespace`` …). Raises ``ConfigError`` when the
    parameters are invalid (the message names the parameter)."""

    def __init__(self, **kwargs: Any):
        super().__init__(NODE_NAME, **kwargs)
        self._lock = threading.Lock()
        config = NodeConfig.from_ros_params(self._declare_parameters())
        types = MessageTypes.rclpy()
        t0 = time.monotonic()
        self.core = start_core(config, types, types[config.input_type_name], prog=NODE_NAME,
                               notice=self.get_logger().info)
        warm_s = time.monotonic() - t0
        self.processed = 0
        self.published = 0
        self.lost_events = 0

        self._pubs = {topic: self.create_publisher(types[typ], topic, TF_QOS if topic == TF_TOPIC else OUTPUT_QOS)
                      for topic, typ in self.core.output_topics().items()}
        self._diag_pub = self.create_publisher(types[DIAGNOSTIC_ARRAY], DIAGNOSTICS_TOPIC, OUTPUT_QOS)
        # a steady clock: with use_sim_time and no /clock the node clock stands at 0 and a timer
        # on it never fires — /diagnostics must still say what is going on
        self._diag_timer = self.create_timer(1.0 / config["diagnostics_rate"], self._publish_diagnostics,
                                             clock=Clock(clock_type=ClockType.STEADY_TIME))
        self._clock_state = ""                  # "", "waiting", "running": what was logged about /clock
        self._wrong_types: list[str] = []       # input publishers of another type, as last logged
        self._reset_srv = self.create_service(Trigger, "~/reset", self._on_reset)
        self._jump_handle = self.get_clock().create_jump_callback(
            JumpThreshold(min_forward=None, min_backward=CLOCK_JUMP_BACK, on_clock_change=False),
            post_callback=self._on_clock_jump)
        for line in unknown_parameter_lines(getattr(self, "_parameter_overrides", {})):
            self.get_logger().warning(line)
        self.add_on_set_parameters_callback(self._on_set_parameters)   # after declaring: only real changes
        self._sub = self._subscribe(types[self.core.input_type])        # last: the node is ready
        o = config.options
        self.get_logger().info(
            f"ready: {self.core.input_type} on {self.resolve_topic_name(self.core.input_topic)} -> "
            f"{len(self._pubs)} output topics at {config['output_rate']:g} Hz (0 = every sample); "
            f"{o.mode}/{o.fidelity}, effects {sorted(o.effects)}"
            + (f", scene {config['scene']}" if config["scene"] else "")
            + f"; kernels warmed up in {warm_s:.1f} s")

    def _subscribe(self, msg_type: type) -> Any:
        """The input subscription with a QoS message-lost callback (when the RMW supports it)."""
        try:
            from rclpy import event_handler
        except ImportError:  # pragma: no cover - older rclpy
            event_handler = None
        SubscriptionEventCallbacks = getattr(event_handler, "SubscriptionEventCallbacks", None)
        UnsupportedEventTypeError = getattr(event_handler, "UnsupportedEventTypeError", RuntimeError)
        # history, depth and reliability overridable at start (qos_overrides.<topic>.subscription.*)
        overrides = QoSOverridingOptions.with_default_policies()
        if SubscriptionEventCallbacks is not None:
            try:
                return self.create_subscription(
                    msg_type, self.core.input_topic, self._on_input, qos_profile_sensor_data,
                    event_callbacks=SubscriptionEventCallbacks(message_lost=self._on_message_lost),
                    qos_overriding_options=overrides)
            except UnsupportedEventTypeError:
                self.get_logger().info("this RMW reports no message-lost events; input loss is seen in stamp gaps only")
        return self.create_subscription(msg_type, self.core.input_topic, self._on_input, qos_profile_sensor_data,
                                        qos_overriding_options=overrides)

    # ---- parameters ---------------------------------------------------------------------
    def _declare_parameters(self) -> dict[str, Any]:
        """Declare every core parameter (``scene`` first: its model values are the defaults of
        the others); returns name → value as set (overrides from params file / -p applied)."""
        scene = self.declare_parameter("scene", SPECS["scene"].default, descriptor(SPECS["scene"])).value
        defaults = parameter_defaults(scene)
        values: dict[str, Any] = {"scene": scene}
        for spec in PARAMETERS:
            if spec.name == "scene":
                continue
            default = defaults[spec.name]
            if spec.type == "string[]" and not default:
                # rclpy infers an empty list as a byte array: declare the type, then give an
                # unset parameter the value [] (an unset one makes GetParameters, hence
                # 'ros2 param dump', answer nothing at all)
                self.declare_parameter(spec.name, Parameter.Type.STRING_ARRAY, descriptor(spec))
                p = self.get_parameter_or(spec.name, None)
                if p is None or p.value is None:
                    self.set_parameters([Parameter(spec.name, Parameter.Type.STRING_ARRAY, [])])
                    p = None
                values[spec.name] = [] if p is None else list(p.value)
            else:
                values[spec.name] = self.declare_parameter(spec.name, _ros_value(default), descriptor(spec)).value
        return values

    def _on_set_parameters(self, params: list) -> SetParametersResult:
        changes = {p.name: p.value for p in params if p.name in SPECS}
        if not changes:                     # use_sim_time, diagnostic_updater.period, qos overrides …
            return SetParametersResult(successful=True)
        with self._lock:
            ok, reason = self.core.set_parameters(changes)
        if ok:
            self.get_logger().info(f"parameters applied: {sorted(changes)}")
        else:
            self.get_logger().warning(f"parameters refused: {reason}")
        return SetParametersResult(successful=ok, reason=reason)

    # ---- input / outputs ----------------------------------------------------------------
    def _on_input(self, msg: Any) -> None:
        now = self.get_clock().now().nanoseconds
        with self._lock:
            out = self.core.on_message(msg, now)
            self.processed += 1
            notices = self.core.take_notices() if self.core.notices else ()
        for line in notices:
            self.get_logger().info(line)
        for topic, m in out:
            self._pubs[topic].publish(m)
        self.published += len(out)

    def _on_message_lost(self, info: Any) -> None:
        """QoS event: the middleware lost ``total_count_change`` input samples."""
        n = int(getattr(info, "total_count_change", 0))
        with self._lock:
            self.lost_events += n
            self.core.loss.on_transport_loss(n, self.get_clock().now().nanoseconds)

    def _on_reset(self, request: Any, response: Any) -> Any:
        with self._lock:
            self.core.reset("service")
        response.success = True
        response.message = "simulation restarted; the next input sample starts a new time base"
        self.get_logger().info("reset by ~/reset")
        return response

    def _on_clock_jump(self, jump: Any) -> None:
        delta = jump.delta.nanoseconds
        with self._lock:
            done = self.core.on_clock_jump(delta < 0, delta, self.get_clock().now().nanoseconds)
        if delta < 0:
            self.get_logger().info(f"clock jumped back {-delta * 1e-9:.3f} s" + {
                "reset": "; simulation restarted",
                "same_loop": " with the input stamps (one loop of a replay): already restarted",
                "deferred": ("; samples stamped before the jump are still queued: integrated first, the "
                             "simulation restarts at the first sample of the new time")}.get(done, ""))

    # ---- diagnostics --------------------------------------------------------------------
    def _publish_diagnostics(self) -> None:
        """The core's DiagnosticArray (input, platform, node) plus ``gyro_platform: transport``;
        on a steady timer. With ``use_sim_time`` and no /clock yet the node status is raised to
        WARN 'waiting for /clock …' (and that is logged once)."""
        clock = self.get_clock()
        now = clock.now().nanoseconds
        sim = clock.ros_time_is_active
        waiting = sim and now == 0
        topic = self.resolve_topic_name(self.core.input_topic)
        kinds = [i.topic_type for i in self.get_publishers_info_by_topic(topic)]
        own = self.core.input_type
        others = sorted(set(kinds) - {own})
        with self._lock:
            arr = self.core.diagnostics(now)
            values = {"transport": "rclpy", "input_topic": topic,
                      "input_publishers_matched": kinds.count(own),
                      "input_publishers_other_types": ", ".join(others),
                      "samples_lost_reported_by_rmw": self.lost_events, "processed": self.processed,
                      "published": self.published,
                      "clock": ("waiting for /clock (use_sim_time)" if waiting
                                else "sim (/clock)" if sim else "system")}
        if waiting:
            node = next(st for st in arr.status if st.name.endswith(": node"))
            node.message = f"waiting for /clock (use_sim_time is true; none received); {node.message}"
            if node.level == node.OK:
                node.level = node.WARN
        if others and own not in kinds:
            # a publisher of another type never matches (DDS raises no event for it): say so
            node = next(st for st in arr.status if st.name.endswith(": node"))
            node.message = f"input {topic} has publishers of {', '.join(others)} only, not {own}; {node.message}"
            node.level = max(node.level, node.WARN)
            if others != self._wrong_types:
                self.get_logger().warning(f"{topic} is published as {', '.join(others)}, not {own} (this node's "
                                          "input_type): those samples never reach it")
        self._wrong_types = others
        arr.status.append(transport_status(self.core.types, values))
        self._diag_pub.publish(arr)
        self._log_clock_state("waiting" if waiting else (("running" if sim else "system") if self._clock_state else ""))

    def _log_clock_state(self, state: str) -> None:
        """One line when the node starts waiting for /clock, one when it comes, one when
        ``use_sim_time`` is set false meanwhile."""
        if state == self._clock_state or not state:
            return
        if state == "waiting":
            self.get_logger().warning(
                "use_sim_time is true and no /clock is published: waiting for /clock (inputs are taken on their "
                "header stamps; receive times and the /diagnostics stamp stay 0 until it comes)")
        elif state == "running":
            self.get_logger().info("/clock received: the node clock runs on sim time")
        else:
            self.get_logger().info("use_sim_time is false: the node clock runs on system time")
        self._clock_state = state


def _ignore_further_interrupts() -> None:
    """After the first Ctrl-C: a second SIGINT (``ros2 launch`` sends one on shutdown) must not
    raise KeyboardInterrupt inside ``destroy_node``; the node is stopping anyway."""
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    except (ValueError, OSError):  # pragma: no cover - not the main thread
        pass


def _interrupt_once() -> None:
    """Ctrl-C raises KeyboardInterrupt once: the handler itself ignores every later SIGINT.
    ``ros2 launch`` sends its own SIGINT right after the terminal's (process group), and a busy
    node (a parameter storm) may still be unwinding the first when it comes: a second
    KeyboardInterrupt there escaped ``main`` with a traceback (exit −2)."""
    def handler(signum: int, frame: Any) -> None:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        raise KeyboardInterrupt

    try:
        signal.signal(signal.SIGINT, handler)
    except (ValueError, OSError):  # pragma: no cover - not the main thread
        pass


def rcl_reason(e: BaseException) -> str:
    """rcl's error text in one line, without the C source locations it appends (``, at ./src/…``)."""
    text = " ".join(str(e).split())
    return text.split(", at ./")[0].split(" at ./src/")[0]


def main(args: list[str] | None = None) -> int:
    """``ros2 run gyro_platform platform_node [--ros-args …]``: spin until Ctrl-C (exit 0); exit 2
    with one line on stderr when the parameters are invalid, or when rcl cannot read its
    arguments (a params file it cannot find or parse, a malformed ``-p``)."""
    compile_notices(NODE_NAME)          # kernels compiling before "ready": said on stderr (physics.jit)
    _interrupt_once()            # before rclpy.init: rclpy's handler calls it after its own
    try:
        rclpy.init(args=args)
    except KeyboardInterrupt:
        return 0
    except Exception as e:  # noqa: BLE001 - rcl's RCLError: a params file it cannot parse or find, a bad -p
        print(f"{NODE_NAME}: cannot start: {rcl_reason(e)}", file=sys.stderr)
        return 2
    node = None
    code = 0
    try:
        node = PlatformNode()
        freeze_startup_objects()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (ConfigError, ValueError, InvalidParameterTypeException, InvalidParameterValueException) as e:
        # bad parameters or a model that cannot be built: one clear line, no traceback
        print(f"gyro_platform_node: cannot start: {e}", file=sys.stderr)
        code = 2
    except Exception:
        if rclpy.ok():
            raise
        # Ctrl-C between 'ready' and spin: rclpy's handler shut the context down under the
        # executor being made (RCLError) — a stop like any other
    finally:
        _ignore_further_interrupts()
        try:
            if node is not None:
                node.destroy_node()
            rclpy.try_shutdown()
        except KeyboardInterrupt:  # pragma: no cover - a signal between the two statements
            pass
    return code


if __name__ == "__main__":
    sys.exit(main())
