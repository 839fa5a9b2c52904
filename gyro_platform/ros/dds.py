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

"""ROS 2 on plain DDS: the node's second transport, without a ROS install.

Speaks the DDS wire format of ``rmw_cyclonedds_cpp`` through the ``cyclonedds`` Python package,
so the node joins a ROS 2 graph (``RMW_IMPLEMENTATION=rmw_cyclonedds_cpp``, same
``ROS_DOMAIN_ID``) and ROS 2 tools see its topics. Pieces:

* **Naming** (:mod:`gyro_platform.ros.dds_names`): rcl's name expansion and validation, DDS
  topic and type names, the domain id; **discovery** without multicast
  (:mod:`gyro_platform.ros.dds_discovery`).
* **Types and QoS** (:mod:`gyro_platform.ros.dds_types`): IDL classes generated from the rosbags
  typestore (XCDR1, byte-identical to rmw_cyclonedds), conversions both ways, the rclpy QoS
  profiles in DDS terms with rmw's type-hash user data.
* **Graph** (:class:`DdsNode`, this module): one DomainParticipant per node (``ROS_DOMAIN_ID``;
  participant user data ``enclave=/;``), publishers and subscriptions on ROS names, and the
  ``ros_discovery_info`` announcement (``rmw_dds_common/ParticipantEntitiesInfo``) that lets
  ``ros2 node list`` show the node.
* **The platform node** (:class:`PlatformDdsNode`): the thin adapter around
  :class:`gyro_platform.ros.core.NodeCore` — inputs in, the core's (topic, message) pairs out,
  ``/diagnostics`` periodically (plus a ``gyro_platform: transport`` status, as the rclpy node),
  ``/robot_description`` and ``/tf_static`` (latched) and ``/tf`` (the joints, from the URDF of
  :mod:`gyro_platform.ros.urdf`; ``platform`` → ``platform_reference``, from the core), ``~/reset``
  (``std_msgs/msg/Empty``) instead of the rclpy reset service, wall-clock jumps forwarded to
  the core.

Overload: the input reader keeps the last 5 samples (the sensor-data QoS), so a publisher faster
than the node cannot build a backlog (latency ≤ 5 samples' processing) nor grow memory: DDS
overwrites the oldest. DDS does not report such overwrites, so a second, data-less reader on
the input topic counts arrivals in C (as rejections of a KEEP_ALL reader with room for one
sample) and the node counts what it takes; the difference is reported as ``samples_lost`` in the
transport diagnostics and fed to the core's ``InputLoss`` (``gyro_platform: node`` WARN "input
overload" while it grows). No Python runs in Cyclone's threads (no listeners):
the node sleeps in a WaitSet.
"""
from __future__ import annotations

import threading
import time
from typing import Any, Callable, Iterable

import numpy as np

from .dds_names import (dds_topic_name, DISCOVERY_TOPIC, DISCOVERY_TYPE, domain_id_from_env, expand_topic_name,
                        normalize_namespace, validate_node_name)
from .dds_types import (dds_qos, DEFAULT, DISCOVERY_INFO, IdlTypes, LATCHED, QosProfile, SENSOR_DATA, TF,
                        type_hash_user_data, zero_message)
from ..pipeline.gate_rules import NS


# =========================================================================================
# a ROS 2 node on DDS: participant, endpoints, graph announcement
# =========================================================================================
class DdsPublisher:
    """A writer on a ROS topic; ``publish(msg)`` takes a rosbags message."""

    def __init__(self, node: "DdsNode", topic: str, ros_type: str, profile: QosProfile):
        from cyclonedds.pub import DataWriter

        self.node, self.topic, self.ros_type, self.profile = node, topic, ros_type, profile
        self.dds_topic = node._topic(topic, ros_type)
        self.writer = DataWriter(node.participant, self.dds_topic,
                                 qos=dds_qos(profile, type_hash_user_data(node.types.type_hash(ros_type))))
        #: ROS message -> IDL sample (the warm-up serialises through it too)
        self.to_idl = node.types.to_idl_fn(ros_type)
        self.published = 0

    def publish(self, msg: Any) -> None:
        self.writer.write(self.to_idl(msg))
        self.published += 1

    @property
    def matched(self) -> int:
        """Number of matched subscriptions right now."""
        return int(self.writer.get_publication_matched_status().current_count)

    @property
    def gid(self) -> bytes:
        return self.writer.guid.bytes


class DdsSubscription:
    """A reader on a ROS topic. ``take()`` returns ``[(rosbags message, SampleInfo)]``;
    :meth:`condition` gives a ReadCondition for a WaitSet (no Python listener: a listener
    runs Python, i.e. takes the GIL, for every arriving sample in Cyclone's receive thread,
    which under a flood throttles reception and builds a backlog in the socket buffer).

    ``count_arrivals``: a second, data-less reader on the same topic (KEEP_ALL with room for
    one sample, never read) counts every arriving sample in C as a rejection; with it,
    ``arrived`` is exact and ``lost`` = samples DDS overwrote in the keep-last queue before
    they were taken (arrived before a draining take and not taken: a lower bound while
    samples arrive, exact at rest).
    """

    def __init__(self, node: "DdsNode", topic: str, ros_type: str, profile: QosProfile,
                 count_arrivals: bool = False):
        from cyclonedds.core import Policy, Qos
        from cyclonedds.sub import DataReader

        self.node, self.topic, self.ros_type, self.profile = node, topic, ros_type, profile
        self.dds_topic = node._topic(topic, ros_type)
        user_data = type_hash_user_data(node.types.type_hash(ros_type))
        self.reader = DataReader(node.participant, self.dds_topic, qos=dds_qos(profile, user_data))
        self.counter = None
        if count_arrivals:
            qos = dds_qos(profile, user_data)
            self.counter = DataReader(node.participant, self.dds_topic, qos=Qos(
                *(qos[k] for k in (Policy.Reliability, Policy.Durability, Policy.DataRepresentation, Policy.Userdata)
                  if k in qos),
                Policy.History.KeepAll,
                Policy.ResourceLimits(max_samples=1, max_instances=1, max_samples_per_instance=1)))
        self._from = node.types.from_idl_fn(ros_type)
        self.taken = 0
        self.lost = 0
        self.undecodable = 0

    @property
    def arrived(self) -> int | None:
        """Samples that reached this participant (None without ``count_arrivals``)."""
        if self.counter is None:
            return None
        rejected = int(self.counter.get_sample_rejected_status().total_count)
        return rejected + 1 if (rejected or self.taken) else 0   # + the one the counter holds

    def condition(self) -> Any:
        """A ReadCondition that is triggered while samples wait in the queue."""
        from cyclonedds.core import InstanceState, ReadCondition, SampleState, ViewState

        return ReadCondition(self.reader, SampleState.Any | ViewState.Any | InstanceState.Any)

    def take(self, n: int = 64) -> list[tuple[Any, Any]]:
        """Take up to ``n`` samples (oldest first) as rosbags messages with their SampleInfo.
        Samples are taken one by one, so one that cannot be decoded (a peer with another
        definition under the same type name) is counted in ``undecodable`` and skipped alone."""
        arrived = self.arrived            # each of these is taken below or was overwritten
        res = []
        for _ in range(n):
            try:
                got = self.reader.take(N=1)
            except Exception:  # noqa: BLE001 - undecodable CDR: the sample is gone, count it
                self.taken += 1
                self.undecodable += 1
                continue
            if not got:
                break
            s = got[0]
            self.taken += 1
            info = getattr(s, "sample_info", None)
            if info is None or not info.valid_data:   # instance state change (writer gone): no data
                continue
            try:
                res.append((self._from(s), info))
            except Exception:  # noqa: BLE001 - a conversion failure must not stop the node
                self.undecodable += 1
        else:
            return res                    # the queue may not be drained: no loss estimate now
        if arrived is not None:
            self.lost = max(self.lost, arrived - self.taken)
        return res

    @property
    def matched(self) -> int:
        """Number of matched publications right now."""
        return int(self.reader.get_subscription_matched_status().current_count)

    @property
    def gids(self) -> list[bytes]:
        return [self.reader.guid.bytes] + ([self.counter.guid.bytes] if self.counter is not None else [])


class DdsNode:
    """A ROS 2 node on plain DDS: ``name`` in ``namespace`` on ``domain_id`` (default
    ``ROS_DOMAIN_ID``). Create endpoints with :meth:`create_publisher` /
    :meth:`create_subscription` (ROS names, expanded as rclpy does); :meth:`close` deletes
    everything. The node announces itself on ``ros_discovery_info`` (as rmw_cyclonedds does)
    unless ``announce=False``."""

    def __init__(self, name: str, namespace: str = "/", domain_id: int | None = None,
                 types: IdlTypes | None = None, announce: bool = True):
        from cyclonedds.core import Policy, Qos
        from cyclonedds.domain import DomainParticipant

        self.name = validate_node_name(name)
        self.namespace = normalize_namespace(namespace)
        self.domain_id = domain_id_from_env(domain_id)
        self.types = types or IdlTypes()
        self.participant = DomainParticipant(self.domain_id, qos=Qos(Policy.Userdata(data=b"enclave=/;")))
        self._topics: dict[str, Any] = {}
        self.publishers: list[DdsPublisher] = []
        self.subscriptions: list[DdsSubscription] = []
        self._announce = announce
        self._discovery_writer = None
        self.closed = False

    @property
    def fully_qualified_name(self) -> str:
        return f"{self.namespace.rstrip('/')}/{self.name}"

    def resolve(self, topic: str) -> str:
        """Fully qualified ROS name of ``topic`` for this node."""
        return expand_topic_name(topic, self.name, self.namespace)

    def _topic(self, ros_topic: str, ros_type: str) -> Any:
        from cyclonedds.topic import Topic

        name = dds_topic_name(ros_topic)
        t = self._topics.get(name)
        if t is None:
            t = self._topics[name] = Topic(self.participant, name, self.types.idl_class(ros_type))
        elif t.data_type is not self.types.idl_class(ros_type):
            raise TypeError(f"topic {ros_topic} already has type {t.get_type_name()} in this node")
        return t

    def create_publisher(self, ros_type: str, topic: str, profile: QosProfile = DEFAULT) -> DdsPublisher:
        pub = DdsPublisher(self, self.resolve(topic), ros_type, profile)
        self.publishers.append(pub)
        self.announce()
        return pub

    def create_subscription(self, ros_type: str, topic: str, profile: QosProfile = SENSOR_DATA,
                            count_arrivals: bool = False) -> DdsSubscription:
        sub = DdsSubscription(self, self.resolve(topic), ros_type, profile, count_arrivals)
        self.subscriptions.append(sub)
        self.announce()
        return sub

    # ---- ros_discovery_info -------------------------------------------------------------
    def announce(self) -> None:
        """Publish this participant's ``ParticipantEntitiesInfo`` (one node, its reader and writer
        GIDs) on ``ros_discovery_info``, as rmw_cyclonedds does after every graph change."""
        if not self._announce or self.closed:
            return
        from cyclonedds.pub import DataWriter
        from cyclonedds.topic import Topic

        if self._discovery_writer is None:
            t = Topic(self.participant, DISCOVERY_TOPIC, self.types.idl_class(DISCOVERY_TYPE))
            # with the type hash in the user data, as rmw_cyclonedds' own ros_discovery_info
            # endpoints (else every ROS process warns "Failed to parse type hash … '(null)'")
            self._discovery_writer = DataWriter(self.participant, t, qos=dds_qos(
                DISCOVERY_INFO, type_hash_user_data(self.types.type_hash(DISCOVERY_TYPE))))
        T = self.types.typestore.types

        def gid(b: bytes) -> Any:
            data = np.frombuffer(bytes(b).ljust(16, b"\0")[:16], dtype=np.uint8).copy()
            return T["rmw_dds_common/msg/Gid"](data=data)

        node = T["rmw_dds_common/msg/NodeEntitiesInfo"](
            node_namespace=self.namespace, node_name=self.name,
            reader_gid_seq=[gid(g) for s in self.subscriptions for g in s.gids],
            writer_gid_seq=[gid(p.gid) for p in self.publishers])
        info = T[DISCOVERY_TYPE](gid=gid(self.participant.guid.bytes), node_entities_info_seq=[node])
        self._discovery_writer.write(self.types.to_idl(info, DISCOVERY_TYPE))

    def close(self) -> None:
        """Delete the participant and all its entities (idempotent)."""
        if self.closed:
            return
        self.closed = True
        try:
            if self._discovery_writer is not None:   # tell the graph the node is gone
                T = self.types.typestore.types
                info = T[DISCOVERY_TYPE](
                    gid=T["rmw_dds_common/msg/Gid"](data=np.frombuffer(self.participant.guid.bytes, np.uint8).copy()),
                    node_entities_info_seq=[])
                self._discovery_writer.write(self.types.to_idl(info, DISCOVERY_TYPE))
        except Exception:  # noqa: BLE001
            pass
        p = self.participant
        try:
            p.__del__()      # dds_delete of the participant deletes its whole entity tree
        except Exception:  # noqa: BLE001
            pass

    def __enter__(self) -> "DdsNode":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def wait_matched(endpoints: Iterable[Any], timeout: float, count: int = 1, poll: float = 0.02) -> bool:
    """Wait until every endpoint (DdsPublisher/DdsSubscription) has ≥ ``count`` matches, at most
    ``timeout`` s. Returns whether they all matched."""
    endpoints = list(endpoints)
    deadline = time.monotonic() + timeout
    while True:
        if all(e.matched >= count for e in endpoints):
            return True
        if time.monotonic() >= deadline:
            return False
        time.sleep(poll)


# =========================================================================================
# the platform node on DDS: thin adapter around NodeCore
# =========================================================================================
class _ClockWatch:
    """Detects jumps of the wall clock (ROS time on a node without sim time) against the
    monotonic clock; ``check()`` → None or (``"backward"``|``"forward"``, jump ns)."""

    def __init__(self, threshold_ns: int = NS):
        self.threshold = threshold_ns
        self._offset = time.time_ns() - time.monotonic_ns()

    def check(self) -> tuple[str, int] | None:
        off = time.time_ns() - time.monotonic_ns()
        d, self._offset = off - self._offset, off
        if d <= -self.threshold:
            return "backward", d
        if d >= self.threshold:
            return "forward", d
        return None


class PlatformDdsNode:
    """The platform node on DDS, a thin adapter around :class:`gyro_platform.ros.core.NodeCore`:
    one subscription on the core's input topic (sensor-data QoS), one reliable publisher per
    output topic and ``/diagnostics`` every ``1 / diagnostics_rate`` s (the core's statuses plus
    ``gyro_platform: transport``), ``~/reset`` (``std_msgs/msg/Empty``) →
    ``core.reset("reset_topic")``, wall-clock jumps → ``core.on_clock_jump``.

    Receive times are the wall clock (``time.time_ns``), as an rclpy node's ROS time without
    sim time. Everything runs in the thread that calls :meth:`spin`, which sleeps in a DDS
    WaitSet (read conditions of its readers and a guard condition for :meth:`stop`): no Python
    runs in Cyclone's threads.
    """

    RESET_TOPIC = "~/reset"
    RESET_TYPE = "std_msgs/msg/Empty"
    TAKE_BATCH = 64

    def __init__(self, core: Any, node: DdsNode, *, diagnostics_period: float = 1.0,
                 log: Callable[[str], None] | None = None, reset_topic: bool = True,
                 robot_description: bool = True):
        from ..messages import DIAGNOSTIC_ARRAY

        self.core = core
        self.node = node
        self.log = log or (lambda s: None)
        self.diagnostics_period = float(diagnostics_period)
        from cyclonedds.core import GuardCondition, WaitSet

        self.stop_event = threading.Event()
        self.input = node.create_subscription(core.input_type, core.input_topic, SENSOR_DATA, count_arrivals=True)
        from ..messages import TF_TOPIC
        outputs = dict(core.output_topics())
        outputs["/diagnostics"] = DIAGNOSTIC_ARRAY
        #: topic as the core names it (relative to the namespace) → publisher
        self.publishers: dict[str, DdsPublisher] = {
            name: node.create_publisher(t, name, TF if name == TF_TOPIC else DEFAULT) for name, t in outputs.items()}
        self.reset_sub = (node.create_subscription(self.RESET_TYPE, self.RESET_TOPIC, DEFAULT)
                          if reset_topic else None)
        self.waitset = WaitSet(node.participant)
        self.guard = GuardCondition(node.participant)
        self._conditions = [self.input.condition()] + ([self.reset_sub.condition()] if self.reset_sub else [])
        for c in (*self._conditions, self.guard):
            self.waitset.attach(c)
        self.clock = _ClockWatch()
        self.processed = 0
        self.published = 0
        self.errors = 0
        self.resets = 0
        self.max_batch = 0
        self.last_error = ""
        self.unknown_topics: set[str] = set()
        self._lost_fed = 0
        self.model = None
        self.frame_prefix = core.config["frame_prefix"]
        if robot_description:
            self._setup_robot_description()

    def warm_up(self) -> None:
        """Compile/load the kernels and build the CDR encoders before the first real sample
        (:func:`gyro_platform.ros.warmup.warm_up`; outputs encoded, not sent), so that the
        first samples are not stalled (and dropped by the keep-last-5 input queue)."""
        from .warmup import warm_up

        def encode(topic: str, msg: Any) -> None:
            if topic in self.publishers:
                self.publishers[topic].to_idl(msg).serialize(use_version_2=False)

        try:
            warm_up(self.core, lambda: zero_message(self.node.types.typestore, self.core.input_type), encode)
            encode("/diagnostics", self.core.diagnostics(time.time_ns()))
        except Exception as e:  # noqa: BLE001 - warming up is an optimisation only
            self.log(f"warm-up skipped: {type(e).__name__}: {e}")

    @property
    def topics(self) -> dict[str, list[str]]:
        """Fully qualified ROS names of the node's endpoints: ``{"in": [...], "out": [...]}``."""
        ins = [self.input.topic] + ([self.reset_sub.topic] if self.reset_sub else [])
        return {"in": ins, "out": [p.topic for p in self.publishers.values()]}

    # ---- one pass -----------------------------------------------------------------------
    def poll(self) -> int:
        """Take and process everything queued now; returns the number of input samples."""
        jump = self.clock.check()
        if jump is not None:
            self.core.on_clock_jump(jump[0] == "backward", jump[1])
            self.log(f"wall clock jumped {jump[0]} by {jump[1] / NS:.3f} s; core told")
        if self.reset_sub is not None and self.reset_sub.take(self.TAKE_BATCH):
            self.core.reset("reset_topic")
            self.resets += 1
            self.log(f"reset requested on {self.reset_sub.topic}")
        batch = self.input.take(self.TAKE_BATCH)
        self.max_batch = max(self.max_batch, len(batch))
        for msg, _info in batch:
            self._process(msg, time.time_ns())
        lost = self.input.lost
        if lost > self._lost_fed:
            self.core.loss.on_transport_loss(lost - self._lost_fed, time.time_ns())
            self._lost_fed = lost
        return len(batch)

    # ---- robot description and TF ---------------------------------------------------
    def _setup_robot_description(self) -> None:
        """``/robot_description`` (URDF, transient local) and ``/tf_static`` (fixed joints)
        published once, latched; ``/tf`` (moving joints) with every JointState output."""
        from .urdf import config_model, config_urdf
        from ..messages import STRING, string_message, TF_MESSAGE, tf_message

        self.model = config_model(self.core.config)
        self.publishers["robot_description"] = self.node.create_publisher(STRING, "robot_description", LATCHED)
        self.publishers["/tf_static"] = self.node.create_publisher(TF_MESSAGE, "/tf_static", LATCHED)
        self.publishers["robot_description"].publish(string_message(config_urdf(self.core.config), self.core.types))
        static = tf_message(self.model, {}, self.core.types, time.time_ns(), self.frame_prefix, static=True)
        if static.transforms:
            self.publishers["/tf_static"].publish(static)

    def _publish_tf(self, joint_state: Any) -> None:
        from ..messages import stamp_ns, tf_message, TF_TOPIC

        positions = dict(zip(joint_state.name, (float(x) for x in joint_state.position)))
        msg = tf_message(self.model, positions, self.core.types, stamp_ns(joint_state.header.stamp), self.frame_prefix)
        self.publishers[TF_TOPIC].publish(msg)
        self.published += 1

    def _process(self, msg: Any, receive_ns: int) -> None:
        try:
            outs = self.core.on_message(msg, receive_ns)
        except Exception as e:  # noqa: BLE001 - the core does not raise; never die on input anyway
            self._error(f"core: {type(e).__name__}: {e}")
            return
        self.processed += 1
        if self.core.notices:
            for line in self.core.take_notices():
                self.log(line)
        for topic, out in outs or ():
            pub = self.publishers.get(topic)
            if pub is None:
                if topic not in self.unknown_topics:
                    self.unknown_topics.add(topic)
                    self.log(f"the core produced a message on {topic!r}, which has no publisher; ignored")
                continue
            try:
                pub.publish(out)
                self.published += 1
                if self.model is not None and topic == "gimbal/joint_states":
                    self._publish_tf(out)
            except Exception as e:  # noqa: BLE001 - e.g. a value out of range for its CDR type
                self._error(f"publish {pub.topic}: {type(e).__name__}: {e}")

    def _error(self, text: str) -> None:
        self.errors += 1
        if text != self.last_error:
            self.log(text)
        self.last_error = text

    # ---- diagnostics --------------------------------------------------------------------
    def transport_status(self) -> dict[str, Any]:
        """Counters of the DDS transport (the values of its diagnostic status)."""
        s = self.input
        d: dict[str, Any] = {
            "domain_id": self.node.domain_id, "input_topic": s.topic, "input_type": s.ros_type,
            "input_publishers_matched": s.matched, "samples_arrived": s.arrived or 0, "samples_taken": s.taken,
            "samples_lost": s.lost, "samples_undecodable": s.undecodable, "queue_depth": s.profile.depth,
            "max_batch": self.max_batch, "processed": self.processed, "published": self.published,
            "reset_requests": self.resets, "transport_errors": self.errors}
        if self.last_error:
            d["last_error"] = self.last_error
        return d

    def diagnostics(self) -> Any:
        """The core's DiagnosticArray (stamped now) plus ``gyro_platform: transport`` (the same
        status names as the rclpy node): WARN after a transport error. Lost input (samples DDS
        overwrote in the keep-last queue: the node is slower than its input) is fed to the
        core's ``InputLoss`` in :meth:`poll` and makes ``gyro_platform: node`` WARN."""
        from ..messages import transport_status

        arr = self.core.diagnostics(time.time_ns())
        warn = f"{self.errors} transport error(s); last: {self.last_error}" if self.errors else ""
        arr.status.append(transport_status(self.core.types,
                                           {"transport": "dds", **self.transport_status()}, warn))
        return arr

    def publish_diagnostics(self) -> None:
        try:
            self.publishers["/diagnostics"].publish(self.diagnostics())
        except Exception as e:  # noqa: BLE001
            self._error(f"diagnostics: {type(e).__name__}: {e}")

    # ---- the loop -----------------------------------------------------------------------
    def spin(self, duration: float | None = None) -> None:
        """Process inputs until :meth:`stop` (e.g. from a signal handler) or until ``duration`` s
        (monotonic) have passed. Diagnostics go out at the start, every period and at the end."""
        t_end = None if duration is None else time.monotonic() + float(duration)
        next_diag = time.monotonic()
        while not self.stop_event.is_set():
            now = time.monotonic()
            if t_end is not None and now >= t_end:
                break
            if now >= next_diag:
                self.publish_diagnostics()
                next_diag = now + self.diagnostics_period
            self.poll()
            wake_at = min(next_diag, now + 0.5, t_end if t_end is not None else next_diag)
            timeout = wake_at - time.monotonic()
            if timeout > 0 and not self.stop_event.is_set():
                self.waitset.wait(max(1, int(timeout * NS)))   # returns early when data waits
        self.publish_diagnostics()

    def stop(self) -> None:
        """Ask :meth:`spin` to return (safe from a signal handler or another thread). A signal
        handler runs when the WaitSet wait returns: within 0.5 s."""
        self.stop_event.set()
        try:
            self.guard.set(True)
        except Exception:  # noqa: BLE001 - already closed
            pass

    def close(self) -> None:
        self.node.close()


__all__ = ["DdsNode", "DdsPublisher", "DdsSubscription", "PlatformDdsNode", "wait_matched", "NS"]
