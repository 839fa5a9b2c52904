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

"""Transport-independent core of the platform node (ROS-free): :class:`NodeCore`.

The rclpy node (:mod:`gyro_platform.ros.node`) and a plain-DDS adapter are thin shells around
:class:`NodeCore`: they hand it every input message with its receive time and publish what it
returns. The core owns the input gate (:class:`~gyro_platform.pipeline.gate.TimeGate`), the
:class:`~gyro_platform.engine.simulator.Simulator`, the output-rate grid, the callback timing,
the input-loss count (:class:`~gyro_platform.ros.overload.InputLoss`), live parameter changes
and the diagnostics; it never raises on input data (every bad sample is counted in the
diagnostics). Its configuration is a :class:`~gyro_platform.ros.config.NodeConfig` (the
parameters: :mod:`gyro_platform.ros.parameters`).

Topic names returned by :meth:`NodeCore.on_message` are relative to the node namespace
(``gimbal/joint_states`` …), as in the topic table of :mod:`gyro_platform.messages`; rclpy
resolves them itself, other transports with ``messages.resolve(name, namespace)``. Output
messages are stamped with the sample time (the input header stamp, or the receive time when the
stamps are not set); diagnostics with the ``now_ns`` the caller passes.

The per-message path is :class:`gyro_platform.pipeline.Pipeline` (the one replay and scenes
use): ``reading_from_msg`` → gate → ``apply_decision`` → output grid. Outputs are computed only
at output instants, into message objects built once and refilled (the transports publish
synchronously): the pairs :meth:`NodeCore.on_message` returns are valid until its next call.
A reset (``~/reset``, a clock jump back, a gap or a jump back in the stamps) is a fresh start:
new simulator state, time origin and output grid at the next sample, input-loss window cleared
(after a gap the loss count keeps its period and judges the gap itself: a pause, or samples
lost when the receive times show none — :class:`~gyro_platform.ros.overload.InputLoss`).
"""
from __future__ import annotations

from collections import Counter, deque
from dataclasses import dataclass
import time
from typing import Any, Callable, Mapping

from .config import NodeConfig
from .overload import InputLoss
from .parameters import ConfigError, SPECS
from .. import messages as msgs
from ..engine.conditioning import GIMBAL_LOCK_WARN
from ..engine.outputs import C_QUAT, C_ROTOR, outputs_of_row
from ..errors import SimulationError
from ..messages import MessageTypes, Reading
from ..pipeline.gate import TimeGate
from ..pipeline.gate_rules import NS
from ..pipeline.grid import grid_index
from ..pipeline.stream import Pipeline

DIAGNOSTICS_TOPIC = "/diagnostics"
#: real-time margin (1 − callback time / input period) below which diagnostics WARN
MARGIN_WARN = 0.2
#: input frame_ids counted by name in the diagnostics (more are counted together as 'other')
MAX_FRAMES = msgs.FRAMES_NAMED
#: how long (s of the caller's clock) a rejected sample or an internal error keeps the status raised
RECENT_S = 10.0
#: this many restarts within RECENT_S turn the node WARN (an input slower than gate.max_gap
#: restarts at every sample and never integrates)
RESTART_STORM = 5


# =========================================================================================
# the core
# =========================================================================================
@dataclass
class _Timing:
    """Per-message processing time (ns, the core's clock) against the input period."""

    ema_ns: float | None = None
    max_ns: int = 0
    last_ns: int = 0
    n: int = 0

    def add(self, dt: int, a: float = 0.05) -> None:
        self.n += 1
        self.last_ns = dt
        if dt > self.max_ns:
            self.max_ns = dt
        e = self.ema_ns
        self.ema_ns = float(dt) if e is None else e + a * (dt - e)


class OutputMessages:
    """The output messages of one instant (``messages.output_messages`` with the frame
    prefix), built once and refilled in place at each later instant from the simulator's
    output row (``Simulator.output_row``): the one shared stamp, the Vector3s and the
    quaternion (``messages.OUTPUT_COLUMNS``), the JointState's arrays
    (``messages.joint_values_of_row``), and the ``/tf`` of ``platform_reference``
    (``messages.reference_tf``: the attitude's conjugate). Names, frames and message objects are
    not touched again. Rebuilt from scratch when the set of outputs changes (mode, rotor rates)."""

    def __init__(self, types: MessageTypes, frame_prefix: str = ""):
        self.types, self.prefix = types, frame_prefix
        self._key: tuple | None = None
        self.pairs: list[tuple[str, Any]] = []
        self._stamp: Any = None
        self._vectors: list[tuple[Any, int]] = []     # (Vector3, first column of the output row)
        self._quat: Any = None
        self._ref_rot: Any = None
        self._js: Any = None

    def fill(self, row: Any, stabilised: bool, t_ns: int) -> list[tuple[str, Any]]:
        """(topic, message) pairs of the output row ``row`` (``Simulator.output_row``; mode
        ``stabilised``) stamped ``t_ns`` (topics relative, as on_message)."""
        v = row.tolist()
        key = (stabilised, v[C_ROTOR] == v[C_ROTOR])
        if key != self._key:
            self._build(outputs_of_row(row, stabilised), t_ns)
            self._key = key
            return self.pairs
        st = self._stamp
        st.sec, st.nanosec = divmod(t_ns if t_ns > 0 else 0, NS)
        for vec, c in self._vectors:
            vec.x = v[c]
            vec.y = v[c + 1]
            vec.z = v[c + 2]
        q = self._quat
        q.x, q.y, q.z, q.w = v[C_QUAT:C_QUAT + 4]
        r = self._ref_rot            # platform → platform_reference: the attitude's conjugate
        r.x, r.y, r.z, r.w = -q.x, -q.y, -q.z, q.w
        pos, vel, eff = msgs.joint_values_of_row(v, stabilised)
        js, fa = self._js, self.types.float_array
        js.position, js.velocity, js.effort = fa(pos), fa(vel), fa(eff)
        return self.pairs

    def _build(self, out: Any, t_ns: int) -> None:
        pairs = [(t.lstrip("/"), m) for t, m in msgs.output_messages(out, self.types, t_ns, "")]
        self._js = pairs[0][1]                # the JointState
        self._stamp = stamp = self._js.header.stamp     # one Time object shared by every header
        self._vectors = []
        for topic, m in pairs[1:]:
            m.header.stamp = stamp
            if self.prefix and m.header.frame_id:
                m.header.frame_id = self.prefix + m.header.frame_id
            if topic == "platform/attitude":
                self._quat = m.quaternion
                tf = msgs.reference_tf(m, self.types, self.prefix)
                self._ref_rot = tf.transforms[0].transform.rotation
            else:
                vec = m.wrench.torque if topic.startswith("bearing/") else m.vector
                self._vectors.append((vec, msgs.OUTPUT_COLUMNS[topic]))
        self.pairs = pairs + [(msgs.TF_TOPIC, tf)]


class NodeCore:
    """Input message → gate → simulator → output messages, with diagnostics and parameters.

    ``types``: the binding's message classes (``MessageTypes.rosbags()`` or ``.rclpy()``);
    ``clock_ns``: the wall clock used to time callbacks (default ``time.perf_counter_ns``);
    ``simulator``: makes the simulator from (params, options) (default ``Simulator``; a cold
    start's: ``engine.remote.ColdStart.simulator``, see ``warmup.start_core``).
    """

    def __init__(self, config: NodeConfig, types: MessageTypes, *,
                 clock_ns: Callable[[], int] = time.perf_counter_ns, simulator: Callable[..., Any] | None = None):
        if simulator is None:
            from ..engine.simulator import Simulator
            simulator = Simulator
        self.make_simulator = simulator
        self.config = config
        self.types = types
        self._clock_ns = clock_ns
        self.gate = TimeGate(config.gate)
        self.pipe = Pipeline(simulator(config.params, config.options), self.gate, config["output_rate"],
                             config.mounting)
        self.outcomes: Counter[str] = Counter()     # apply_decision results + output_failed
        self.pipe.outcomes = self.outcomes          # one count: the pipeline's
        self.messages = OutputMessages(types, config["frame_prefix"])
        self.timing = _Timing()
        self.resets: Counter[str] = Counter()       # reset reason -> count (core resets and gate resets)
        self.clock_jumps: Counter[str] = Counter()  # "back" / "forward"
        self.received = 0
        self.published = 0                          # output instants published
        self.internal_errors = 0
        self.identity_frames: set[str] = set()      # input frames without mounting, taken as base_link
        self.identity_more = False                  # … beyond MAX_FRAMES of them
        self._restarts_rx: deque[int] = deque(maxlen=RESTART_STORM)   # receive times of the last restarts
        self._gap_said_rx: int | None = None        # receive time of the last gap restart said in a line
        self._gaps_unsaid = 0
        self.frames: dict[str, int] = {}            # input frame_id -> samples (MAX_FRAMES names, then 'other')
        self.notices: list[str] = []                # one-time INFO lines for the transport to log
        self.parameter_changes = 0
        self.last_error: str | None = None
        self.last_reset_reason: str | None = None
        self._last_row: tuple[Any, bool] | None = None     # (output row, stabilised) of the last instant
        self._last_out = None
        self._last_rx_ns: int | None = None
        self._stamp_jump_at: int | None = None    # stamp of the last input jump-back reset (see on_clock_jump)
        self._clock_back_to: int | None = None    # a clock jump's reset waiting for the new time's first sample
        self._last_rejected_rx: int | None = None
        self._last_error_rx: int | None = None
        self.loss = InputLoss()

    @property
    def sim(self) -> Any:
        """The Simulator (rebuilt by live parameter changes)."""
        return self.pipe.sim

    # ---- topics ---------------------------------------------------------------------
    @property
    def input_topic(self) -> str:
        return self.config.input_topic

    @property
    def input_type(self) -> str:
        """ROS type name of the input topic."""
        return self.config.input_type_name

    def input_topics(self) -> dict[str, str]:
        """Input topic (relative to the node namespace) → ROS type: the one subscription."""
        return {self.input_topic: self.input_type}

    @staticmethod
    def output_topics(with_diagnostics: bool = False) -> dict[str, str]:
        """Output topic → ROS type, names relative to the node namespace as :meth:`on_message`
        returns them (``gimbal/joint_states`` …), and ``/tf`` (absolute: ``platform_reference``
        in the TF tree); ``/diagnostics`` (absolute) only if asked."""
        topics = {(t if t == DIAGNOSTICS_TOPIC else t.lstrip("/")): typ for t, typ in msgs.output_topics("").items()
                  if with_diagnostics or t != DIAGNOSTICS_TOPIC}
        return {**topics, msgs.TF_TOPIC: msgs.TF_MESSAGE}

    # ---- input ----------------------------------------------------------------------
    def on_message(self, msg: Any, receive_ns: int | None) -> list[tuple[str, Any]]:
        """Process one input message received at ``receive_ns`` (node clock, ns; None or ≤ 0 =
        unknown). Returns the ``(topic, message)`` pairs to publish now: the outputs when the
        sample starts a new slot of the output grid, else nothing. The messages are reused by
        the next call (publish them before it). Never raises."""
        t0 = self._clock_ns()
        self.received += 1
        rx = int(receive_ns) if receive_ns is not None and receive_ns > 0 else None
        if rx is not None:
            self._last_rx_ns = rx
        result: list[tuple[str, Any]] = []
        try:
            pipe = self.pipe
            reading = msgs.reading_from_msg(msg, pipe.mounting)
            if reading.__class__ is Reading:
                if self._clock_back_to is not None and reading.stamp_ns:
                    self._clock_reset_due(reading.stamp_ns)
                frames, frame = self.frames, reading.frame_id
                if frame in frames:
                    frames[frame] += 1
                else:
                    self._new_frame(frame)
                if reading.identity_assumed:
                    self._identity_notice(frame)
            step = pipe.offer(reading, rx)
            outcome = step.outcome
            if outcome == "pushed":
                if step.source == "header":   # the gate's time source; receive times say nothing about loss
                    self.loss.on_stamp(step.stamp_ns, rx, self.gate.config.max_gap, self._last_rx_ns)
            elif outcome in ("reset", "restarted"):
                self._fresh_start("integration_failed" if outcome == "restarted" else step.decision.reason,
                                  step.decision.stamp_ns, rx)
            elif outcome == "dropped":
                # received, not lost: its stamp is no gap (a sample dropped for its values)
                st = getattr(reading, "stamp_ns", None)
                if st and self.gate.time_source == "header":
                    self.loss.on_stamp(st, rx, self.gate.config.max_gap, self._last_rx_ns)
            elif outcome == "rejected":
                self._last_rejected_rx = rx if rx is not None else self._last_rx_ns
            if step.emit:
                result = self.emit(step.stamp_ns)
        except Exception as e:  # defensive: a message must never take the node down
            self.internal_errors += 1
            self.last_error = f"{type(e).__name__}: {e}"
            self._last_error_rx = rx if rx is not None else self._last_rx_ns
            result = []
        finally:
            self.timing.add(self._clock_ns() - t0)
        return result

    def _new_frame(self, frame: str) -> None:
        """First sample of an input frame_id: counted under its name (the first ``MAX_FRAMES``
        names; later ones together under ``other``)."""
        key = frame if len(self.frames) < MAX_FRAMES else "other"
        self.frames[key] = self.frames.get(key, 0) + 1

    def _identity_notice(self, frame: str) -> None:
        """First sample of a frame_id without mounting: one line, its name kept (the first
        ``MAX_FRAMES``, each cut by ``messages.frame_label``; more are said once)."""
        if frame in self.identity_frames:
            return
        if len(self.identity_frames) >= MAX_FRAMES:
            if not self.identity_more:
                self.identity_more = True
                self.notices.append(f"more than {MAX_FRAMES} input frames have no sensor mounting: taken as "
                                    "base_link, counted as identity_frame, not named further")
            return
        self.identity_frames.add(frame)
        self.notices.append(f"input frame '{msgs.frame_label(frame)}' has no sensor mounting: taken as "
                            "base_link (identity); counted as identity_frame in /diagnostics")

    def _fresh_start(self, reason: str, stamp_ns: int, rx: int | None) -> None:
        """Bookkeeping of a reset the pipeline already applied (simulator reset, grid restarted,
        time origin moved to this sample by the gate's ``rebase_on_reset``)."""
        if self.gate.time_source == "header":
            if reason != "gap":                    # a new time base: as the first sample of a fresh core
                self.loss.restart()
            # after a gap the loss count decides: a pause, or samples lost (a replay faster than its stamps)
            self.loss.on_stamp(stamp_ns, rx, self.config["gate.max_gap"], self._last_rx_ns)
        else:
            self.loss.restart()
        self.resets[reason] += 1
        self.last_reset_reason = reason
        self._stamp_jump_at = self._clock_back_to = None
        at = rx if rx is not None else self._last_rx_ns
        if at is not None:
            self._restarts_rx.append(at)
        if reason == "gap":                     # one line, at most one per RECENT_S of receive time
            if at is None or self._gap_said_rx is None or at - self._gap_said_rx > RECENT_S * NS:
                more = f" ({self._gaps_unsaid} more since the last line)" if self._gaps_unsaid else ""
                self.notices.append(f"input gap longer than gate.max_gap ({self.config['gate.max_gap']:g} s): "
                                    f"simulation restarted{more}")
                self._gap_said_rx, self._gaps_unsaid = at, 0
            else:
                self._gaps_unsaid += 1
        if reason == "jump_back":               # a looped bag: said once per loop, as a clock jump is
            self._stamp_jump_at = stamp_ns
            detail = getattr(getattr(self.gate, "last", None), "detail", "") or "time jumped back"
            self.notices.append(f"input stamps: {detail}; simulation restarted")
        if reason == "integration_failed":
            self._last_rejected_rx = rx if rx is not None else self._last_rx_ns

    def take_notices(self) -> list[str]:
        """The one-time INFO lines gathered since the last call (the transport logs them)."""
        out, self.notices = self.notices, []
        return out

    def _grid(self, stamp_ns: int) -> int:
        return grid_index(stamp_ns, self.gate.origin_ns or 0, self.config["output_rate"])

    def emit(self, stamp_ns: int) -> list[tuple[str, Any]]:
        """The output messages of the simulator's current state, stamped ``stamp_ns`` (``[]`` and
        ``outcomes['output_failed']`` counted when the outputs fail); the pairs are valid until the
        next call. ``on_message`` calls it at output instants; the warm-up at an arbitrary one."""
        sim = self.sim
        try:
            row = sim.output_row()
        except SimulationError as e:
            self.outcomes["output_failed"] += 1
            self.last_error = f"outputs failed: {e}"
            return []
        stabilised = bool(sim.system.stabilised)
        self._last_row, self._last_out = (row, stabilised), None
        self.published += 1
        return self.messages.fill(row, stabilised, stamp_ns)

    @property
    def last_out(self) -> Any:
        """The ``Outputs`` of the last published instant (None before the first), made when
        asked (diagnostics) from the output row kept by :meth:`emit`."""
        if self._last_out is None and self._last_row is not None:
            self._last_out = outputs_of_row(*self._last_row)
        return self._last_out

    # ---- control --------------------------------------------------------------------
    def reset(self, reason: str) -> None:
        """Restart the simulation and the time base (``~/reset`` service, clock jump back …);
        counters are kept, the reset is counted under ``reason``."""
        self.sim.reset()
        self.gate.restart()
        self.loss.restart()
        self.pipe.slot = None
        self.resets[reason] += 1
        self.last_reset_reason = reason
        self._stamp_jump_at = self._clock_back_to = None

    def on_clock_jump(self, backward: bool, delta_ns: int | None = None, now_ns: int | None = None) -> str:
        """The node clock jumped (``delta_ns`` if known) to ``now_ns`` (if known). Backward: reset
        (reason ``clock_jump_back``) when ``reset_on_clock_jump`` is true — unless the input
        stamps jumped back just before (a looped ``ros2 bag play --clock``: the stamps' reset, at
        most ``max_gap`` of stamps ago, was the same loop's, and a second one would throw away the
        samples taken since). With header stamps after ``now_ns`` + ``max_gap`` (the clock
        overtook samples still queued from before its jump) the reset waits for the first sample
        stamped at most that: the queued ones are integrated in their run, and a stamps' jump back
        there is the one reset (``same_loop``). Returns ``"reset"``, ``"same_loop"``,
        ``"deferred"`` or ``""`` (nothing done)."""
        self.clock_jumps["back" if backward else "forward"] += 1
        if not (backward and self.config["reset_on_clock_jump"]):
            return ""
        at, last = self._stamp_jump_at, self.gate.last_stamp_ns
        self._stamp_jump_at = None
        max_gap = self.config["gate.max_gap"] * NS
        if at is not None and last is not None and 0 <= last - at <= max_gap:
            self.clock_jumps["back_same_loop"] += 1
            return "same_loop"
        if now_ns is not None and last is not None and self.gate.time_source == "header" and last > now_ns + max_gap:
            self._clock_back_to = int(now_ns)
            return "deferred"
        self.reset("clock_jump_back")
        return "reset"

    def _clock_reset_due(self, stamp_ns: int) -> None:
        """A sample stamped ``stamp_ns`` while a clock jump's reset waits (:meth:`on_clock_jump`):
        one stamped after the new time + ``max_gap`` is the old run's; the first one not is the
        new time's: the gate's own reset when its stamps jump back (``same_loop``), else this one."""
        if stamp_ns > self._clock_back_to + self.config["gate.max_gap"] * NS:
            return
        self._clock_back_to = None
        last = self.gate.last_stamp_ns
        if last is not None and last - stamp_ns > self.gate.config.reset_on_jump_back * NS:
            self.clock_jumps["back_same_loop"] += 1
            return
        self.reset("clock_jump_back")
        self.notices.append("clock jumped back: simulation restarted at the first sample of the new time")

    def set_parameters(self, changes: Mapping[str, Any]) -> tuple[bool, str]:
        """Validate and apply ``changes`` (name → value) atomically. Returns ``(True, "")`` or
        ``(False, reason)`` naming the parameter; read-only parameters are refused unless the
        value is unchanged. Live changes: gate limits, output rate, mountings, effects and
        servo gains (the simulator is rebuilt with the state carried over)."""
        try:
            for k, v in changes.items():
                spec = SPECS.get(k)
                if spec is None:
                    raise ConfigError(k, "unknown parameter")
                if spec.read_only and spec.coerce(v) != self.config[k]:
                    raise ConfigError(k, "is read-only (it fixes the structure of the node or model); "
                                         "restart the node to change it")
            new = self.config.with_changes(changes)
        except ConfigError as e:
            return False, str(e)
        old = self.config
        if new.params != old.params or new.options != old.options:
            try:
                sim = self.make_simulator(new.params, new.options)
            except Exception as e:  # e.g. precession model invalid for these values
                return False, f"cannot rebuild the model: {e}"
            sim.carry_state_from(self.sim)
            self.pipe.sim = sim
        if new.gate != old.gate:
            self.gate.config = new.gate
        if new.mounting is not old.mounting:
            self.pipe.mounting = new.mounting
        if new["frame_prefix"] != old["frame_prefix"]:
            self.messages = OutputMessages(self.types, new["frame_prefix"])
        self.config = new
        if new["output_rate"] != old["output_rate"]:
            self.pipe.output_rate = new["output_rate"]
            last = self.gate.last_stamp_ns
            self.pipe.slot = self._grid(last) if (last is not None and new["output_rate"] > 0) else None
        self.parameter_changes += 1
        return True, ""

    # ---- diagnostics ----------------------------------------------------------------
    def real_time_margin(self) -> float | None:
        """1 − (mean callback time / input period): 0.8 = 20 % of each period used; < 0 = the
        node falls behind. None before the input period is known."""
        rate = self.gate.input_rate_hz or self.gate.accepted_rate_hz
        if not rate or self.timing.ema_ns is None:
            return None
        return 1.0 - self.timing.ema_ns * 1e-9 * rate

    def snapshot(self, now_ns: int | None = None) -> dict[str, Any]:
        """Counters and health figures (the content of the ``node`` diagnostics status)."""
        g = self.gate.snapshot()
        rate = self.gate.input_rate_hz or self.gate.accepted_rate_hz
        stats = self.sim.stats
        stamp_anomalies = {k: v for k, v in {**g["dropped_by_reason"], **g["resets_by_reason"]}.items()
                           if k in ("zero_stamp", "repeated_stamp", "backward_stamp", "jump_back", "gap", "no_time")}
        lock = None if self.last_out is None else self.last_out.status.get("gimbal_lock_margin")
        return {
            "input_topic": self.input_topic,
            "input_type": self.input_type,
            "messages": self.received,
            "accepted": g["accepted"],
            "dropped": g["dropped"],
            "dropped_by_reason": g["dropped_by_reason"],
            "input_frames": {msgs.frame_label(k): v for k, v in self.frames.items()},
            "frames_taken_as_base_link": ", ".join([*map(msgs.frame_label, sorted(self.identity_frames)),
                                                    *(["…"] if self.identity_more else [])]),
            "stamp_anomalies": stamp_anomalies,
            "input_lost": self.loss.total,
            "input_lost_transport": self.loss.transport,
            "input_lost_stamp_gaps": self.loss.stamp_gaps,
            "simulator": dict(self.outcomes),
            "outputs_published": self.published,
            "output_rate_hz": self.config["output_rate"],
            "resets": sum(self.resets.values()),
            "resets_by_reason": dict(self.resets),
            "last_reset_reason": self.last_reset_reason,
            "clock_jumps": dict(self.clock_jumps),
            "integrator": stats["integrator"],
            "kernels": getattr(self.sim, "kernels", "compiled"),   # engine.remote: interpreted while compiling
            "integrator_steps": stats["n_steps"],
            "integrator_error_estimate_max": stats["max_error_estimate"],
            "input_rate_hz": rate,
            "input_period_ms": None if not rate else 1e3 / rate,
            "callback_time_mean_ms": None if self.timing.ema_ns is None else self.timing.ema_ns * 1e-6,
            "callback_time_max_ms": self.timing.max_ns * 1e-6,
            "real_time_margin": self.real_time_margin(),
            "gimbal_lock_margin": lock,
            "since_last_input_s": (None if now_ns is None or self._last_rx_ns is None
                                   else (now_ns - self._last_rx_ns) / NS),
            "parameter_changes": self.parameter_changes,
            "internal_errors": self.internal_errors,
            "last_error": self.last_error,
        }

    def diagnostics(self, now_ns: int) -> Any:
        """``diagnostic_msgs/DiagnosticArray`` stamped ``now_ns`` (node clock) with statuses
        ``gyro_platform: input`` (gate counters by reason, input rate), ``gyro_platform:
        platform`` (outputs' status, integrator figures) and ``gyro_platform: node`` (see
        :meth:`snapshot`; ERROR when falling behind real time or after an internal error,
        WARN near gimbal lock, on a thin real-time margin or after a rejected sample, STALE
        before the first input or when none came for max_gap). No side effects."""
        stats = self.sim.stats
        extra = {"integrator": stats["integrator"], "n_samples": stats["n_samples"],
                 "integrator_steps": stats["n_steps"], "max_error_estimate": stats["max_error_estimate"],
                 "outputs_published": self.published}
        arr = msgs.diagnostic_array(self.gate.snapshot(), self.last_out, self.types, now_ns, extra)
        snap = self.snapshot(now_ns)
        level, message = self._node_level(snap, now_ns)
        cls = self.types["diagnostic_msgs/msg/DiagnosticStatus"]
        lvl = {0: cls.OK, 1: cls.WARN, 2: cls.ERROR, 3: cls.STALE}[level]
        items = [(k, "n/a" if v is None else v) for k, v in msgs.flatten(snap)]
        arr.status.append(cls(level=lvl, name=f"{msgs.HARDWARE_ID}: node", message=message,
                              hardware_id=msgs.HARDWARE_ID, values=msgs.key_values(self.types, items)))
        return arr

    def _node_level(self, snap: dict[str, Any], now_ns: int) -> tuple[int, str]:
        def recent(rx: int | None) -> bool:
            return rx is not None and (now_ns - rx) <= RECENT_S * NS

        if self.received == 0:
            return 3, "no input yet"
        since = snap["since_last_input_s"]
        if since is not None and since > self.config["gate.max_gap"]:
            return 3, f"no input for {since:.3g} s"
        margin = snap["real_time_margin"]
        if self.internal_errors and recent(self._last_error_rx):
            return 2, f"internal error: {self.last_error}"
        if margin is not None and margin < 0:
            return 2, f"falling behind real time (margin {margin:.2f})"
        lock = snap["gimbal_lock_margin"]
        if lock is not None and lock < GIMBAL_LOCK_WARN:
            return 1, f"near gimbal lock (min |cos| of inner gimbals {lock:.3g})"
        if recent(self.loss.last_rx_ns):
            return 1, (f"input overload: samples lost (transport {self.loss.transport}, stamp gaps "
                       f"{self.loss.stamp_gaps}); the node or its transport is slower than the input")
        if len(self._restarts_rx) == RESTART_STORM and recent(self._restarts_rx[0]):
            return 1, (f"simulation restarting repeatedly ({RESTART_STORM} restarts within {RECENT_S:g} s, the last "
                       f"for {self.last_reset_reason}): is the input slower than gate.max_gap "
                       f"({self.config['gate.max_gap']:g} s)?")
        if recent(self._last_rejected_rx):
            return 1, "simulator rejected or restarted a sample recently"
        if margin is not None and margin < MARGIN_WARN:
            return 1, f"thin real-time margin ({margin:.2f})"
        return 0, "ok"


__all__ = ["NodeCore", "DIAGNOSTICS_TOPIC", "GIMBAL_LOCK_WARN", "MARGIN_WARN", "RECENT_S"]
