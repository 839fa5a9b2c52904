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

"""Plain-DDS transport (rmw_cyclonedds wire format without ROS): bytes, names, QoS, and
topic-driven scenarios against the node running as a separate process over loopback DDS.

Everything runs on loopback only (``config/cyclonedds_loopback.xml``: 127.0.0.1, no multicast),
on a ROS_DOMAIN_ID derived from the test run's pid; every wait has a timeout and the node
process is always terminated (killed when it does not stop).
"""
from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import threading
import time
import zlib
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("cyclonedds", reason="the DDS transport needs the 'cyclonedds' package (pip install .[dds])")

from rosbags.typesys.base import Nodetype  # noqa: E402

from gyro_platform import messages as m  # noqa: E402
from gyro_platform.ros import dds, dds_discovery, dds_names, dds_types  # noqa: E402
from gyro_platform.physics.params import NAV1  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
LOOPBACK_XML = ROOT / "config" / "cyclonedds_loopback.xml"
STORE = m.jazzy_typestore()
T = STORE.types
IDL = dds_types.IdlTypes(STORE)

#: every message type the node uses on the wire (inputs, outputs, graph announcement, reset)
WIRE_TYPES = (m.IMU, m.TWIST, m.TWIST_STAMPED, m.JOINT_STATE, m.VECTOR3_STAMPED, m.WRENCH_STAMPED,
              m.DIAGNOSTIC_ARRAY, dds_names.DISCOVERY_TYPE, "std_msgs/msg/Empty")


# =========================================================================================
# messages with content that exercises CDR: strings of every length mod 8 (alignment), empty
# and non-empty sequences, NaN/±Inf/−0, extreme integers, multi-byte UTF-8
# =========================================================================================
SPECIAL_FLOATS = (math.nan, -math.nan, math.inf, -math.inf, -0.0, 5e-324, 1.7976931348623157e308)
STRINGS = ("", "a", "ab", "abc", "abcd", "abcde", "abcdef", "abcdefg", "base_link", "é", "gyro_housing10")
INT_RANGES = {"int8": (-128, 127), "uint8": (0, 255), "byte": (-128, 127), "char": (0, 255),
              "int16": (-2**15, 2**15 - 1), "uint16": (0, 2**16 - 1), "int32": (-2**31, 2**31 - 1),
              "uint32": (0, 2**32 - 1), "int64": (-2**63, 2**63 - 1), "uint64": (0, 2**64 - 1)}


def random_message(ros_type: str, rng: np.random.Generator, empty: bool = False):
    """A rosbags message of ``ros_type`` filled from its field definitions."""
    def value(desc):
        kind, args = desc
        if kind == Nodetype.BASE:
            name, bound = args
            if name == "string":
                s = "" if empty else STRINGS[rng.integers(len(STRINGS))]
                return s[:bound] if bound else s
            if name in ("float32", "float64"):
                x = SPECIAL_FLOATS[rng.integers(len(SPECIAL_FLOATS))] if rng.random() < 0.3 else float(rng.normal())
                return float(np.float32(x)) if name == "float32" else x
            if name == "bool":
                return bool(rng.integers(2))
            lo, hi = INT_RANGES[name]
            mid = int(rng.integers(lo, hi, endpoint=True, dtype=np.int64 if lo < 0 else np.uint64))
            return int(rng.choice([lo, hi, 0, mid]))
        if kind == Nodetype.NAME:
            return random_message(args, rng, empty)
        sub, n = args
        count = n if kind == Nodetype.ARRAY else (0 if empty else int(rng.integers(0, 5)))
        if kind == Nodetype.SEQUENCE and n:
            count = min(count, n)
        items = [value(sub) for _ in range(count)]
        if sub[0] == Nodetype.BASE and sub[1][0] != "string":
            from rosbags.serde.utils import ndtype
            return np.array(items, dtype=ndtype(sub[1][0]))
        return items

    fields = STORE.fielddefs[ros_type][1]
    return T[ros_type](**{name: value(desc) for name, desc in fields})


def imu(t: float, w=(0.0, 0.0, 0.0), frame: str = "base_link", acc=(0.0, 0.0, 9.81)):
    sec, nsec = divmod(int(round(t * 1e9)), 1_000_000_000)
    return T[m.IMU](
        header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec), frame_id=frame),
        orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=np.zeros(9),
        angular_velocity=T["geometry_msgs/msg/Vector3"](x=float(w[0]), y=float(w[1]), z=float(w[2])),
        angular_velocity_covariance=np.zeros(9),
        linear_acceleration=T["geometry_msgs/msg/Vector3"](x=float(acc[0]), y=float(acc[1]), z=float(acc[2])),
        linear_acceleration_covariance=np.zeros(9))


def twist_stamped(t: float, w=(0.0, 0.0, 0.0), frame: str = "base_link"):
    sec, nsec = divmod(int(round(t * 1e9)), 1_000_000_000)
    v = T["geometry_msgs/msg/Vector3"]
    return T[m.TWIST_STAMPED](
        header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec), frame_id=frame),
        twist=T[m.TWIST](linear=v(x=1.0, y=2.0, z=3.0), angular=v(x=float(w[0]), y=float(w[1]), z=float(w[2]))))


def handmade_messages():
    """One hand-made message per output type with NaNs, empty sequences and odd string lengths."""
    def hdr(s, n, f):
        return T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=s, nanosec=n), frame_id=f)

    v = lambda x, y, z: T["geometry_msgs/msg/Vector3"](x=x, y=y, z=z)  # noqa: E731
    kv = T["diagnostic_msgs/msg/KeyValue"]
    st = T["diagnostic_msgs/msg/DiagnosticStatus"]
    return [
        imu(1.5, (0.1, math.nan, -0.0)),
        T[m.TWIST](linear=v(math.inf, -math.inf, 0.0), angular=v(0.5, -0.5, 1e-300)),
        twist_stamped(1_700_000_000.123456789, (0.0, 0.5, 0.0), frame="imu"),
        T[m.JOINT_STATE](header=hdr(1, 2, ""), name=["alpha4", "beta5", "beta7", "alpha9", "beta10", "mount_roll",
                                                     "mount_pitch", "mount_yaw"],
                         position=np.array([0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8]),
                         velocity=np.array([1.0] * 5 + [math.nan] * 3), effort=np.array([2e-4] * 5 + [math.nan] * 3)),
        T[m.JOINT_STATE](header=hdr(0, 0, "x"), name=[], position=np.array([]), velocity=np.array([]),
                         effort=np.array([])),
        T[m.VECTOR3_STAMPED](header=hdr(7, 999_999_999, "platform"), vector=v(1e-6, math.nan, -3e-6)),
        T[m.WRENCH_STAMPED](header=hdr(3, 4, "gyro_housing10"),
                            wrench=T["geometry_msgs/msg/Wrench"](force=v(0.0, 0.0, 0.0), torque=v(1e-3, -2e-3, 3e-3))),
        T[m.DIAGNOSTIC_ARRAY](header=hdr(5, 6, ""), status=[
            st(level=st.WARN, name="gyro_platform: input", message="last input dropped: non_finite",
               hardware_id="gyro_platform", values=[kv(key="received", value="12"), kv(key="a", value=""),
                                                    kv(key="", value="xyz")]),
            st(level=st.OK, name="", message="", hardware_id="", values=[])]),
        T[m.DIAGNOSTIC_ARRAY](header=hdr(0, 0, ""), status=[]),
    ]


def assert_byte_identical(msg):
    ros_type = msg.__msgtype__
    ref = bytes(STORE.serialize_cdr(msg, ros_type))          # rosbags: CDR little endian + header
    obj = IDL.to_idl(msg)
    wire = obj.serialize(use_version_2=False)                # what the DDS writer sends (XCDR1)
    assert wire[:4] == b"\x00\x01\x00\x00"                   # CDR_LE encapsulation, options 0
    assert wire == ref, f"{ros_type}: DDS bytes differ from rosbags' CDR"
    assert obj.serialize() == ref                             # the class' default is XCDR1 too
    back = IDL.deserialize(ref, ros_type)                     # and the way back is lossless
    assert bytes(STORE.serialize_cdr(back, ros_type)) == ref


# =========================================================================================
# bytes
# =========================================================================================
@pytest.mark.parametrize("msg", handmade_messages(), ids=lambda x: x.__msgtype__.split("/")[-1])
def test_handmade_messages_are_byte_identical_to_rosbags_cdr(msg):
    assert_byte_identical(msg)


@pytest.mark.parametrize("ros_type", WIRE_TYPES)
def test_random_messages_are_byte_identical_to_rosbags_cdr(ros_type):
    rng = np.random.default_rng(zlib.crc32(ros_type.encode()))
    assert_byte_identical(random_message(ros_type, rng, empty=True))
    for _ in range(40):
        assert_byte_identical(random_message(ros_type, rng))


#: what the node command's own store (``messages.typedefs.core_typestore``) must carry: the wire
#: types and those of TF and /robot_description
NODE_TYPES = WIRE_TYPES + ("tf2_msgs/msg/TFMessage", "std_msgs/msg/String", m.QUATERNION_STAMPED)


@pytest.mark.parametrize("ros_type", NODE_TYPES)
def test_the_node_commands_small_store_sends_what_jazzys_store_sends(ros_type):
    """``gyro-platform node --transport dds`` builds its IDL classes from the package's small
    store, not rosbags' whole Jazzy store: the same DDS type names, type hashes and bytes."""
    from gyro_platform.messages.typedefs import core_typestore

    small = dds_types.IdlTypes(core_typestore())
    assert small.type_hash(ros_type) == IDL.type_hash(ros_type) is not None
    assert small.idl_class(ros_type).__idl_typename__ == IDL.idl_class(ros_type).__idl_typename__
    rng = np.random.default_rng(zlib.crc32(ros_type.encode()) + 1)
    for k in range(20):
        msg = random_message(ros_type, rng, empty=k == 0)
        assert small.serialize(msg, ros_type) == IDL.serialize(msg, ros_type)


def test_the_node_command_does_not_build_jazzys_whole_store():
    code = ("import sys\nfrom gyro_platform.cli import main\n"
            "rc = main(['node', '--transport', 'dds', '--duration', '0.2', '--cyclonedds-config', sys.argv[1]])\n"
            "print(rc, 'rosbags.typesys.stores.ros2_jazzy' in sys.modules)")
    env = dict(os.environ, ROS_DOMAIN_ID=str(150 + os.getpid() % 80))
    p = subprocess.run([sys.executable, "-c", code, str(LOOPBACK_XML)], cwd=ROOT, env=env, capture_output=True,
                       text=True, timeout=300)
    assert p.stdout.split()[-2:] == ["0", "False"], p.stdout + p.stderr


def test_zero_messages_for_the_warm_up_are_valid():
    for ros_type in WIRE_TYPES:
        assert_byte_identical(dds_types.zero_message(STORE, ros_type))


def test_all_string_lengths_mod_8_before_a_double():
    """frame_id of length 0..16 moves the next float64's padding through every case."""
    for n in range(17):
        msg = T[m.VECTOR3_STAMPED](
            header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=n, nanosec=1), frame_id="f" * n),
            vector=T["geometry_msgs/msg/Vector3"](x=math.nan, y=float(n), z=-0.0))
        assert_byte_identical(msg)


def test_nan_payload_and_sign_survive_the_round_trip():
    msg = imu(2.0, (math.nan, -math.nan, -0.0))
    back = IDL.deserialize(IDL.serialize(msg), m.IMU)
    w = back.angular_velocity
    assert math.isnan(w.x) and math.isnan(w.y) and math.copysign(1.0, w.z) == -1.0
    assert math.copysign(1.0, w.y) == math.copysign(1.0, -math.nan)


def test_generated_classes_follow_rmw_cyclonedds_type_names_and_layout():
    from cyclonedds.idl import types as it
    from cyclonedds.idl._type_normalize import get_extended_type_hints

    imu_cls = IDL.idl_class(m.IMU)
    assert imu_cls.__idl_typename__ == "sensor_msgs::msg::dds_::Imu_"
    hints = get_extended_type_hints(imu_cls)
    assert list(hints) == [f for f, _ in STORE.fielddefs[m.IMU][1]]
    assert hints["orientation_covariance"] == it.array(it.float64, 9)
    assert hints["header"].__idl_typename__ == "std_msgs::msg::dds_::Header_"
    time_hints = get_extended_type_hints(hints["header"])["stamp"]
    assert time_hints.__idl_typename__ == "builtin_interfaces::msg::dds_::Time_"
    js = get_extended_type_hints(IDL.idl_class(m.JOINT_STATE))
    assert js["name"] == it.sequence(str) and js["position"] == it.sequence(it.float64)
    gid = get_extended_type_hints(IDL.idl_class(dds_names.DISCOVERY_TYPE))["gid"]
    assert get_extended_type_hints(gid)["data"] == it.array(it.uint8, 16)
    node = get_extended_type_hints(IDL.idl_class("rmw_dds_common/msg/NodeEntitiesInfo"))
    assert node["node_name"] == it.bounded_str(256)
    for t in WIRE_TYPES:
        cls = IDL.idl_class(t)
        cls.__idl__.populate()
        assert cls.__idl__.keyless                                   # no @key: keyless topics
        assert cls.__idl__.default_version == 1                      # XCDR1 by default as well
        assert IDL.idl_class(t) is cls                               # cached


def test_unknown_type_is_a_clean_error():
    with pytest.raises(KeyError, match="not in the typestore"):
        IDL.idl_class("nope_msgs/msg/Nothing")


# =========================================================================================
# names
# =========================================================================================
@pytest.mark.parametrize("name,node,ns,expected", [
    ("imu", "platform", "/", "/imu"),
    ("imu", "platform", "", "/imu"),
    ("imu", "platform", "vehicle", "/vehicle/imu"),
    ("imu", "platform", "/vehicle/", "/vehicle/imu"),
    ("gimbal/joint_states", "platform", "/a/b", "/a/b/gimbal/joint_states"),
    ("/diagnostics", "platform", "/a/b", "/diagnostics"),
    ("~", "platform", "/a", "/a/platform"),
    ("~/reset", "platform", "/a", "/a/platform/reset"),
    ("~/reset", "platform", "/", "/platform/reset"),
    ("{node}/x", "platform", "/a", "/a/platform/x"),
    ("{ns}/x", "platform", "/a", "/a/x"),
    ("{ns}/x", "platform", "/", "/x"),
    ("{namespace}/x", "platform", "/a", "/a/x"),
])
def test_topic_names_expand_as_rclpy(name, node, ns, expected):
    full = dds_names.expand_topic_name(name, node, ns)
    assert full == expected
    assert dds_names.dds_topic_name(full) == "rt" + expected
    assert dds_names.ros_topic_name("rt" + expected) == expected


@pytest.mark.parametrize("name", ["", "a//b", "a/", "~a", "1abc", "a/2b", "a b", "{bad}/x", "a-b", "/"])
def test_invalid_topic_names_are_rejected(name):
    with pytest.raises(dds_names.NameError_):
        dds_names.expand_topic_name(name, "platform", "/")


@pytest.mark.parametrize("node,ns", [("1node", "/"), ("a-b", "/"), ("ok", "/a//b"), ("ok", "/1a")])
def test_invalid_node_names_and_namespaces_are_rejected(node, ns):
    with pytest.raises(dds_names.NameError_):
        dds_names.expand_topic_name("x", node, ns)


def test_type_names_and_topics_of_the_node():
    assert dds_names.dds_type_name(m.IMU) == "sensor_msgs::msg::dds_::Imu_"
    assert dds_names.dds_type_name(m.TWIST_STAMPED) == "geometry_msgs::msg::dds_::TwistStamped_"
    assert dds_names.dds_type_name(m.DIAGNOSTIC_ARRAY) == "diagnostic_msgs::msg::dds_::DiagnosticArray_"
    assert dds_names.ros_type_name("sensor_msgs::msg::dds_::JointState_") == m.JOINT_STATE
    assert dds_names.ros_type_name("JointState") is None
    with pytest.raises(ValueError):
        dds_names.dds_type_name("Imu")
    outs = {dds_names.dds_topic_name(t) for t in m.output_topics("/robot")}
    assert {"rt/robot/gimbal/joint_states", "rt/robot/drift/rate", "rt/robot/bearing/rotor11/torque",
            "rt/diagnostics"} <= outs
    assert dds_names.dds_topic_name("/") == "rt/" and dds_names.ros_topic_name("ros_discovery_info") is None


def test_domain_id_from_env(monkeypatch):
    monkeypatch.setenv("ROS_DOMAIN_ID", "42")
    assert dds_names.domain_id_from_env() == 42
    assert dds_names.domain_id_from_env(7) == 7
    monkeypatch.delenv("ROS_DOMAIN_ID")
    assert dds_names.domain_id_from_env() == 0
    for bad in ("x", "233", "-1"):
        monkeypatch.setenv("ROS_DOMAIN_ID", bad)
        with pytest.raises(ValueError, match="ROS_DOMAIN_ID"):
            dds_names.domain_id_from_env()


# =========================================================================================
# QoS
# =========================================================================================
def test_qos_profiles_match_the_rclpy_node():
    from cyclonedds.core import Policy

    sensor = dds_types.dds_qos(dds_types.SENSOR_DATA)
    assert sensor[Policy.Reliability] == Policy.Reliability.BestEffort
    assert sensor[Policy.History] == Policy.History.KeepLast(5)
    assert sensor[Policy.Durability] == Policy.Durability.Volatile
    out = dds_types.dds_qos(dds_types.DEFAULT, dds_types.type_hash_user_data(IDL.type_hash(m.JOINT_STATE)))
    assert isinstance(out[Policy.Reliability], Policy.Reliability.Reliable)
    assert out[Policy.History] == Policy.History.KeepLast(10)
    assert out[Policy.Durability] == Policy.Durability.Volatile
    for q in (sensor, out, dds_types.dds_qos(dds_types.DISCOVERY_INFO)):
        assert q[Policy.DataRepresentation] == Policy.DataRepresentation(use_cdrv0_representation=True)
    assert out[Policy.Userdata].data.startswith(b"typehash=RIHS01_") and out[Policy.Userdata].data.endswith(b";")
    assert dds_types.dds_qos(dds_types.DISCOVERY_INFO)[Policy.Durability] == Policy.Durability.TransientLocal


# =========================================================================================
# scenarios: the node as a separate process, driven over loopback DDS
# =========================================================================================
NODE = "gyro_platform_node"
READY_TIMEOUT = 300.0      # s: the first start in a fresh clone compiles the numba kernels
WAIT = 10.0                # s: discovery, one output, one diagnostics period …
Q10 = 1e-4                 # N m, gimbal bias torque on beta10
L11 = float(NAV1.L[2])     # kg m²/s, rotor 11 momentum C·Ω
COLLECT = dds_types.QosProfile("reliable", "volatile", 1000)   # test readers: lose nothing
_domains = iter(range(10_000))


def next_domain() -> int:
    """A ROS_DOMAIN_ID for one test: from the pid, in 1..100 (ROS's safe range 0–101)."""
    return 1 + (os.getpid() + 7 * next(_domains)) % 100


def stamp_s(msg) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def rss_kib(pid: int) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    raise AssertionError("no VmRSS")


@pytest.fixture(autouse=True, scope="module")
def loopback_only():
    """Every participant of this module (test side too) uses the loopback-only config."""
    old = os.environ.get("CYCLONEDDS_URI")
    os.environ["CYCLONEDDS_URI"] = LOOPBACK_XML.as_uri()
    yield
    if old is None:
        os.environ.pop("CYCLONEDDS_URI", None)
    else:
        os.environ["CYCLONEDDS_URI"] = old


class NodeProcess:
    """``gyro-platform node --transport dds`` in a subprocess (log in a file, never a pipe)."""

    def __init__(self, tmp_path: Path, params: dict | None, domain: int, *args: str):
        import yaml

        self.domain = domain
        self.log_path = tmp_path / f"node_{domain}.log"
        cmd = [sys.executable, "-m", "gyro_platform.cli", "node", "--transport", "dds",
               "--cyclonedds-config", str(LOOPBACK_XML), *args]
        if params is not None:
            pfile = tmp_path / f"params_{domain}.yaml"
            pfile.write_text(yaml.safe_dump({"/**": {"ros__parameters": params}}))
            cmd += ["--params-file", str(pfile)]
        env = dict(os.environ, ROS_DOMAIN_ID=str(domain), CYCLONEDDS_URI=LOOPBACK_XML.as_uri(),
                   PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep))
        self._log = open(self.log_path, "w")
        self.proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=self._log, stderr=subprocess.STDOUT,
                                     stdin=subprocess.DEVNULL)

    @property
    def log(self) -> str:
        return self.log_path.read_text(errors="replace")

    def wait_log(self, text: str, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if text in self.log:
                return
            if self.proc.poll() is not None:
                raise AssertionError(f"node exited ({self.proc.returncode}) before {text!r}:\n{self.log}")
            time.sleep(0.05)
        raise AssertionError(f"no {text!r} from the node within {timeout} s:\n{self.log}")

    def alive(self) -> bool:
        return self.proc.poll() is None

    def stop(self, sig: int = signal.SIGINT, timeout: float = 20.0) -> int | None:
        """Signal, wait, kill if needed; returns the exit code (None if it had to be killed)."""
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(10)
                self._log.close()
                return None
        self._log.close()
        return self.proc.returncode


@pytest.fixture
def start_node(tmp_path, request):
    """Factory: start the DDS node (waits for its ready line); always stopped at teardown."""
    procs: list[NodeProcess] = []

    def stop_all():
        for p in procs:
            p.stop()

    request.addfinalizer(stop_all)

    def start(params: dict | None, *args: str, domain: int | None = None, wait_ready: bool = True) -> NodeProcess:
        p = NodeProcess(tmp_path, params, next_domain() if domain is None else domain, *args)
        procs.append(p)
        if wait_ready:
            p.wait_log("ready:", READY_TIMEOUT)
        return p

    return start


class Driver:
    """The test's side of the graph: a DdsNode on the node's domain publishing inputs and
    collecting outputs (reliable, deep history: nothing is lost on the test side)."""

    def __init__(self, domain: int, namespace: str = "/", name: str = "scenario_driver"):
        assert os.environ.get("CYCLONEDDS_URI") == LOOPBACK_XML.as_uri(), "test participants must be loopback-only"
        self.node = dds.DdsNode(name, namespace, domain, types=IDL)
        self.subs: dict[str, dds.DdsSubscription] = {}
        self.got: dict[str, list] = {}

    def publisher(self, ros_type: str, topic: str, profile=dds_types.SENSOR_DATA) -> dds.DdsPublisher:
        return self.node.create_publisher(ros_type, topic, profile)

    def subscribe(self, ros_type: str, topic: str, profile=COLLECT) -> dds.DdsSubscription:
        sub = self.node.create_subscription(ros_type, topic, profile)
        self.subs[sub.topic] = sub
        self.got[sub.topic] = []
        return sub

    def pump(self) -> None:
        for topic, sub in self.subs.items():
            self.got[topic] += [msg for msg, _ in sub.take(1000)]

    def wait_for(self, topic: str, pred, timeout: float = WAIT, fresh: bool = False):
        """First collected message on ``topic`` (fully qualified) satisfying ``pred``; with
        ``fresh`` only messages that arrive from now on."""
        deadline = time.monotonic() + timeout
        self.pump()
        seen = len(self.got[topic]) if fresh else 0
        while True:
            self.pump()
            msgs = self.got[topic]
            for msg in msgs[seen:]:
                if pred(msg):
                    return msg
            seen = len(msgs)
            if time.monotonic() >= deadline:
                raise AssertionError(f"no matching message on {topic} within {timeout} s ({seen} seen)")
            time.sleep(0.002)

    def diagnostics_status(self, name: str, pred=lambda kv: True, timeout: float = WAIT) -> dict:
        """Values of status ``name`` in the next /diagnostics (published from now on) whose
        values satisfy ``pred``."""
        def values(arr):
            for st in arr.status:
                if st.name == name:
                    return {kv.key: kv.value for kv in st.values} | {"_level": int(st.level), "_message": st.message}
            return None

        msg = self.wait_for("/diagnostics", lambda a: values(a) is not None and pred(values(a)), timeout, fresh=True)
        return values(msg)

    def close(self) -> None:
        self.node.close()


@pytest.fixture
def driver_factory(request):
    made: list[Driver] = []

    def make(domain: int, namespace: str = "/", name: str = "scenario_driver") -> Driver:
        d = Driver(domain, namespace, name)
        made.append(d)
        return d

    request.addfinalizer(lambda: [d.close() for d in made])
    return make


def connect(driver: Driver, inputs: list, outputs: list, timeout: float = WAIT, publishers: int = 1) -> None:
    """Wait until discovery is complete on both sides (best-effort samples sent before the
    node's reader knows the writer are dropped): our endpoints matched the node's (an input
    publisher matches 2 readers: the input and its arrival counter), and the node's input
    reader reports ``publishers`` matched writers in its transport diagnostics."""
    assert dds.wait_matched(inputs, timeout, count=2) and dds.wait_matched(outputs, timeout), (
        f"discovery: inputs matched {[p.matched for p in inputs]}, outputs matched {[s.matched for s in outputs]}")
    if inputs:
        if "/diagnostics" not in driver.subs:
            driver.subscribe(m.DIAGNOSTIC_ARRAY, "/diagnostics")
            assert dds.wait_matched([driver.subs["/diagnostics"]], timeout)
        driver.diagnostics_status("gyro_platform: transport",
                                  lambda v: v["input_publishers_matched"] == str(publishers), timeout)


JS, ANGLE, RATE, DIAG = "/gimbal/joint_states", "/drift/angle", "/drift/rate", "/diagnostics"


def lockstep(driver: Driver, pub, msgs, topic: str = JS, timeout: float = WAIT) -> list[float]:
    """Publish each message and wait for the output stamped like it (output_rate 0: one output
    per accepted sample); returns the round-trip times (s)."""
    rtts = []
    for msg in msgs:
        t = stamp_s(msg)
        t0 = time.perf_counter()
        pub.publish(msg)
        driver.wait_for(topic, lambda o, t=t: abs(stamp_s(o) - t) < 1e-9, timeout)
        rtts.append(time.perf_counter() - t0)
    return rtts


CARRIED = {"mode": "carried", "output_rate": 0.0}


def test_carried_free_gyro_follows_constant_vehicle_rate(start_node, driver_factory):
    """Carried mode, Ω2 = 0.5 rad/s from Imu samples over DDS: the free gyro keeps its
    direction, so α4 = −0.5·t (rad) and α̇4 = −0.5 rad/s, the other gimbals stay at 0; outputs
    carry the input's time base; bearing wrenches come in their frames."""
    node = start_node(CARRIED)
    drv = driver_factory(node.domain)
    pub = drv.publisher(m.IMU, "imu")
    js = drv.subscribe(m.JOINT_STATE, "gimbal/joint_states")
    wrench = drv.subscribe(m.WRENCH_STAMPED, "bearing/gimbal4/torque")
    connect(drv, [pub], [js, wrench])
    t0, rate = 1_000.0, 200.0
    inputs = [imu(t0 + k / rate, (0.0, 0.5, 0.0)) for k in range(401)]
    rtts = lockstep(drv, pub, inputs)
    out = drv.got["/gimbal/joint_states"]
    assert len(out) == 401 and stamp_s(out[0]) == pytest.approx(t0, abs=1e-9)
    assert list(out[0].name[:5]) == ["alpha4", "beta5", "beta7", "alpha9", "beta10"]
    for msg in out:
        t = stamp_s(msg) - t0
        assert msg.position[0] == pytest.approx(-0.5 * t, abs=1e-6)
        assert msg.velocity[0] == pytest.approx(-0.5, abs=1e-6)
        np.testing.assert_allclose(msg.position[1:5], 0.0, atol=1e-6)
    assert stamp_s(out[-1]) - t0 == pytest.approx(2.0, abs=1e-9)
    drv.pump()
    w = drv.got["/bearing/gimbal4/torque"]
    assert len(w) == 401 and {x.header.frame_id for x in w} == {"gyro_frame4"}
    assert all(np.isfinite([x.wrench.torque.x, x.wrench.torque.y, x.wrench.torque.z]).all() for x in w)

    # one core, two shells: the same inputs through NodeCore in this process give the same bytes
    from gyro_platform.ros.config import NodeConfig
    from gyro_platform.ros.core import NodeCore

    core = NodeCore(NodeConfig.from_ros_params(CARRIED), m.MessageTypes.rosbags())
    local = {"gimbal/joint_states": [], "bearing/gimbal4/torque": []}
    for k, msg in enumerate(inputs):
        for topic, o in core.on_message(msg, 1_700_000_000_000_000_000 + k * 5_000_000):
            if topic in local:
                local[topic].append(bytes(STORE.serialize_cdr(o, o.__msgtype__)))
    for topic, got in (("gimbal/joint_states", out), ("bearing/gimbal4/torque", w)):
        assert [bytes(STORE.serialize_cdr(o, o.__msgtype__)) for o in got] == local[topic]
    print(f"lock-step round trip Imu -> JointState over loopback DDS: median {1e3 * np.median(rtts):.2f} ms, "
          f"p95 {1e3 * np.percentile(rtts, 95):.2f} ms, max {1e3 * max(rtts):.2f} ms")


def paced(pub, msgs, period: float) -> None:
    """Publish at most one message per ``period`` s of wall time."""
    t_next = time.perf_counter()
    for msg in msgs:
        pub.publish(msg)
        t_next += period
        delay = t_next - time.perf_counter()
        if delay > 0:
            time.sleep(delay)


def slope(ts, vs, t0: float, t1: float) -> float:
    ts, vs = np.asarray(ts), np.asarray(vs)
    sel = (ts >= t0) & (ts <= t1)
    assert sel.sum() >= 50, f"only {sel.sum()} points in [{t0}, {t1}] s"
    return float(np.polyfit(ts[sel], vs[sel], 1)[0])


def test_stabilised_bias_torque_drifts_at_minus_q10_over_l11(start_node, driver_factory):
    """Stabilised platform at rest, bias torque Q10 = 1e-4 N m on gimbal 10: gyro 11 precesses
    and the servo drags the platform along, drift rate about z = −Q10/L11 = −1.98944e-3 rad/s
    (slope of /drift/angle z, and the mean of /drift/rate z), x and y do not drift."""
    assert -Q10 / L11 == pytest.approx(-1.98944e-3, rel=1e-5)
    node = start_node({"mode": "stabilised", "effects": ["defaults", "bias_torque"],
                       "physics": {"bias_torque": [0.0, 0.0, 0.0, 0.0, Q10]}, "output_rate": 100.0})
    drv = driver_factory(node.domain)
    pub = drv.publisher(m.IMU, "imu")
    subs = [drv.subscribe(m.VECTOR3_STAMPED, "drift/angle"), drv.subscribe(m.VECTOR3_STAMPED, "drift/rate"),
            drv.subscribe(m.JOINT_STATE, "gimbal/joint_states")]
    connect(drv, [pub], subs)
    t0, rate, T = 5_000.0, 200.0, 3.0
    paced(pub, [imu(t0 + k / rate) for k in range(int(T * rate) + 1)], 1.0 / rate)
    drv.wait_for(ANGLE, lambda o: stamp_s(o) - t0 > T - 0.05)
    angle, drift_rate = drv.got[ANGLE], drv.got[RATE]
    origin = stamp_s(angle[0])             # the gate's origin: the first accepted sample
    assert origin == pytest.approx(t0, abs=0.05)
    assert {a.header.frame_id for a in angle} == {"platform"}
    t = [stamp_s(a) - origin for a in angle]
    z = slope(t, [a.vector.z for a in angle], 0.5, T)
    assert z == pytest.approx(-Q10 / L11, rel=1e-3)
    for axis in ("x", "y"):
        assert abs(slope(t, [getattr(a.vector, axis) for a in angle], 0.5, T)) < 1e-3 * abs(z)
    late = [r.vector.z for r in drift_rate if stamp_s(r) - origin >= 0.5]
    assert np.mean(late) == pytest.approx(-Q10 / L11, rel=1e-2)
    js = [j for j in drv.got[JS] if stamp_s(j) - origin >= 0.5]
    assert list(js[0].name[5:]) == ["mount_roll", "mount_pitch", "mount_yaw", "rotor6", "rotor8", "rotor11"]
    assert all(np.all(np.isfinite(j.velocity)) and np.all(np.isfinite(j.effort)) for j in js)   # no NaN
    tj = [stamp_s(j) - origin for j in js]
    assert slope(tj, [j.position[1] for j in js], 0.5, T) == pytest.approx(Q10 / L11, rel=5e-2)   # beta5 = -theta3


def test_twist_stamped_input_namespace_qos_and_graph(start_node, driver_factory):
    """TwistStamped input in namespace /veh: Ω3 = 0.4 rad/s turns α9 and β5 by −0.4·t and β7 by
    +0.4·t. The node's endpoints, as discovered over DDS, carry the ROS names, type names and
    QoS of the rclpy node (XCDR1 only, typehash user data), and ros_discovery_info lists them."""
    from cyclonedds.core import Policy
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    node = start_node({"mode": "carried", "output_rate": 0.0, "input_type": "twist_stamped"}, "--namespace", "veh")
    drv = driver_factory(node.domain, "/veh")
    pub = drv.publisher(m.TWIST_STAMPED, "twist")
    js = drv.subscribe(m.JOINT_STATE, "gimbal/joint_states")
    diag = drv.subscribe(m.DIAGNOSTIC_ARRAY, "/diagnostics")
    connect(drv, [pub], [js, diag])
    t0 = 42.0
    lockstep(
        drv, pub, [twist_stamped(t0 + k * 0.01, (0.0, 0.0, 0.4)) for k in range(201)], topic="/veh/gimbal/joint_states"
    )
    out = drv.got["/veh/gimbal/joint_states"]
    assert len(out) == 201
    for msg in out:
        t = stamp_s(msg) - t0
        np.testing.assert_allclose(msg.position[:5], [0.0, -0.4 * t, 0.4 * t, -0.4 * t, 0.0], atol=1e-6)

    # -- what the node offers, seen through discovery
    (h,) = js.reader.get_matched_publications()
    w = js.reader.get_matched_publication_data(h)
    assert (w.topic_name, w.type_name) == ("rt/veh/gimbal/joint_states", "sensor_msgs::msg::dds_::JointState_")
    assert isinstance(w.qos[Policy.Reliability], Policy.Reliability.Reliable)
    assert w.qos[Policy.History] == Policy.History.KeepLast(10)
    assert w.qos[Policy.Durability] == Policy.Durability.Volatile
    assert w.qos[Policy.DataRepresentation] == Policy.DataRepresentation(use_cdrv0_representation=True)
    assert w.qos[Policy.Userdata].data == f"typehash={STORE.hash_rihs01(m.JOINT_STATE)};".encode()
    readers = [pub.writer.get_matched_subscription_data(h) for h in pub.writer.get_matched_subscriptions()]
    (r,) = [x for x in readers if x.qos[Policy.History] == Policy.History.KeepLast(5)]    # the input
    (c,) = [x for x in readers if x.qos[Policy.History] == Policy.History.KeepAll]        # arrival counter
    assert c.qos[Policy.ResourceLimits].max_samples == 1 and c.participant_key == r.participant_key
    for x in (r, c):
        assert (x.topic_name, x.type_name) == ("rt/veh/twist", "geometry_msgs::msg::dds_::TwistStamped_")
        assert x.qos[Policy.Reliability] == Policy.Reliability.BestEffort
        assert x.qos[Policy.Durability] == Policy.Durability.Volatile
        assert x.qos[Policy.DataRepresentation] == Policy.DataRepresentation(use_cdrv0_representation=True)
    (h,) = diag.reader.get_matched_publications()
    assert diag.reader.get_matched_publication_data(h).topic_name == "rt/diagnostics"   # absolute: no namespace

    # -- ros_discovery_info (transient local: the node's last announcement is delivered late too)
    cls = IDL.idl_class(dds_names.DISCOVERY_TYPE)
    reader = DataReader(drv.node.participant, Topic(drv.node.participant, dds_names.DISCOVERY_TOPIC, cls),
                        qos=dds_types.dds_qos(dds_types.DISCOVERY_INFO))
    info = None
    deadline = time.monotonic() + WAIT
    while info is None and time.monotonic() < deadline:
        for s in reader.take(N=100):
            msg = IDL.from_idl(s, dds_names.DISCOVERY_TYPE)
            if any(n.node_name == NODE for n in msg.node_entities_info_seq):
                info = msg
        time.sleep(0.05)
    assert info is not None, "no ros_discovery_info from the node"
    (entry,) = info.node_entities_info_seq
    assert entry.node_namespace == "/veh"
    assert bytes(info.gid.data) == w.participant_key.bytes
    writers = {bytes(g.data) for g in entry.writer_gid_seq}
    readers = {bytes(g.data) for g in entry.reader_gid_seq}
    assert w.key.bytes in writers and {r.key.bytes, c.key.bytes} <= readers
    # outputs + diagnostics + robot_description, /tf, /tf_static; input, counter, reset
    assert len(writers) == len(m.output_topics()) + 3 and len(readers) == 3

    # -- another domain sees nothing
    other = driver_factory(1 + (node.domain % 100), "/veh", name="other_domain")
    probe = other.subscribe(m.JOINT_STATE, "gimbal/joint_states")
    assert not dds.wait_matched([probe], 1.5)


def test_bad_input_over_the_wire_is_dropped_and_counted(start_node, driver_factory):
    """NaN and over-range samples are dropped with their reason in /diagnostics and produce no
    output; a publisher of another type on the input topic is not matched by DDS and changes
    nothing; ~/reset restarts the simulation; through all of it the node keeps running."""
    node = start_node(CARRIED)
    drv = driver_factory(node.domain)
    pub = drv.publisher(m.IMU, "imu")
    js = drv.subscribe(m.JOINT_STATE, "gimbal/joint_states")
    diag = drv.subscribe(m.DIAGNOSTIC_ARRAY, "/diagnostics")
    reset = drv.publisher("std_msgs/msg/Empty", f"/{NODE}/reset", dds_types.DEFAULT)
    connect(drv, [pub], [js, diag])
    assert dds.wait_matched([reset], WAIT)
    w = (0.0, 0.5, 0.0)
    lockstep(drv, pub, [imu(10.0 + k * 0.01, w) for k in range(10)])

    # malformed samples: no output for them, counted by reason
    pub.publish(imu(10.10, (math.nan, 0.5, 0.0)))
    pub.publish(imu(10.11, (0.0, 100.0, 0.0)))
    pub.publish(imu(10.12, w, acc=(math.inf, 0.0, 0.0)))
    lockstep(drv, pub, [imu(10.13 + k * 0.01, w) for k in range(5)])
    stamps = [round(stamp_s(j), 6) for j in drv.got[JS]]
    assert not {10.10, 10.11, 10.12} & set(stamps)
    last = drv.got[JS][-1]
    assert last.position[0] == pytest.approx(-0.5 * (stamp_s(last) - 10.0), abs=1e-6)   # unharmed
    gate = drv.diagnostics_status("gyro_platform: input", lambda v: v.get("received") == "18")
    assert gate["dropped_by_reason.non_finite"] == "2" and gate["dropped_by_reason.over_rate"] == "1"

    # a publisher of another type on the input topic: DDS does not match it, nothing happens
    intruder = driver_factory(node.domain, name="intruder")
    wrong = intruder.publisher(m.VECTOR3_STAMPED, "imu")
    assert not dds.wait_matched([wrong], 2.0)
    n_js = len(drv.got[JS])
    for k in range(50):
        wrong.publish(T[m.VECTOR3_STAMPED](
            header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=11, nanosec=k), frame_id="x"),
            vector=T["geometry_msgs/msg/Vector3"](x=1.0, y=2.0, z=3.0)))
    time.sleep(0.5)
    drv.pump()
    assert len(drv.got[JS]) == n_js and node.alive()
    transport = drv.diagnostics_status("gyro_platform: transport", lambda v: True)
    assert transport["input_publishers_matched"] == "1" and transport["samples_undecodable"] == "0"
    gate = drv.diagnostics_status("gyro_platform: input")
    assert gate["received"] == "18"                          # the intruder's samples never reached the core

    # ~/reset: the next sample starts a new time base (stamps go on without a gap)
    reset.publish(T["std_msgs/msg/Empty"](structure_needs_at_least_one_member=0))
    node_status = drv.diagnostics_status("gyro_platform: node", lambda v: v.get("resets_by_reason.reset_topic") == "1")
    assert node_status["last_reset_reason"] == "reset_topic"
    lockstep(drv, pub, [imu(10.18 + k * 0.01, w) for k in range(20)])
    after = [j for j in drv.got[JS] if stamp_s(j) >= 10.175]
    assert after[0].position[0] == 0.0                       # without the reset: -0.5 * 0.18
    assert after[-1].position[0] == pytest.approx(-0.5 * 0.19, abs=1e-6)
    assert node.alive()


def test_flooding_publisher_is_dropped_with_a_diagnostic_not_queued(start_node, driver_factory):
    """A publisher far faster than real time (as fast as Python writes, stamps 1 ms apart, for
    ≤ 3 s): the node drops what it cannot process (reported in /diagnostics, WARN), keeps no
    backlog (a sample sent right after the flood is answered at once, not after the tens of
    thousands queued before it) and its memory stays flat. Across the dropped samples the
    constant rate is integrated exactly (max_gap raised so that the gaps do not reset)."""
    node = start_node({**CARRIED, "gate": {"max_gap": 3600.0}})
    drv = driver_factory(node.domain)
    pub = drv.publisher(m.IMU, "imu")
    js = drv.subscribe(m.JOINT_STATE, "gimbal/joint_states")
    diag = drv.subscribe(m.DIAGNOSTIC_ARRAY, "/diagnostics")
    connect(drv, [pub], [js, diag])
    w = (0.0, 0.5, 0.0)
    lockstep(drv, pub, [imu(100.0 + k * 1e-3, w) for k in range(50)])
    time.sleep(0.5)
    rss0 = rss_kib(node.proc.pid)
    peak = [rss0]
    stop = threading.Event()

    def watch():
        while not stop.wait(0.1):
            peak[0] = max(peak[0], rss_kib(node.proc.pid))

    watcher = threading.Thread(target=watch, daemon=True)
    watcher.start()
    sent, t_start = 0, time.perf_counter()
    msg = imu(0.0, w)
    try:
        while sent < 100_000 and time.perf_counter() - t_start < 3.0:
            t = 100.05 + sent * 1e-3
            msg.header.stamp.sec, msg.header.stamp.nanosec = int(t), int(round((t % 1) * 1e9))
            pub.publish(msg)
            sent += 1
    finally:
        flood_s = time.perf_counter() - t_start
        stop.set()
        watcher.join(5)
    t_last = 100.05 + (sent - 1) * 1e-3
    # right after the flood: the next sample is answered promptly (no backlog in front of it)
    t_marker = t_last + 1e-3
    t0 = time.perf_counter()
    pub.publish(imu(t_marker, w))
    marker = drv.wait_for(JS, lambda o: abs(stamp_s(o) - t_marker) < 1e-9, timeout=WAIT)
    catch_up = time.perf_counter() - t0
    assert marker.position[0] == pytest.approx(-0.5 * (t_marker - 100.0), abs=1e-6)   # gaps integrated, exact
    st = drv.diagnostics_status("gyro_platform: transport", lambda v: int(v["processed"]) >= 51, timeout=WAIT)
    lost, processed, arrived = int(st["samples_lost"]), int(st["processed"]), int(st["samples_arrived"])
    assert processed < sent / 2, f"processed {processed} of {sent}: the flood was not fast enough to test"
    assert lost > sent / 4 and lost <= arrived - processed
    warned = [s for a in drv.got[DIAG] for s in a.status
              if s.name == "gyro_platform: node" and s.level == s.WARN and "input overload" in s.message]
    assert warned, "no WARN 'input overload' in /diagnostics"
    rss1 = rss_kib(node.proc.pid)
    assert peak[0] - rss0 < 30 * 1024 and rss1 - rss0 < 30 * 1024, (rss0, peak[0], rss1)
    assert node.alive()
    print(f"flood: {sent} samples in {flood_s:.2f} s ({sent / flood_s:.0f}/s); node processed {processed}, "
          f"lost {lost}; answer after the flood {1e3 * catch_up:.1f} ms; RSS {rss0 / 1024:.1f} -> peak "
          f"{peak[0] / 1024:.1f} -> {rss1 / 1024:.1f} MiB")


def test_publisher_that_disappears_and_comes_back(start_node, driver_factory):
    """The only input publisher goes away (its participant is deleted) and a new one comes back
    2 s later with stamps that follow the wall clock: the node keeps running (STALE while no
    input comes), the gate restarts the simulation on the gap (reason ``gap``) and the physics
    go on from the new origin."""
    node = start_node(CARRIED)
    drv = driver_factory(node.domain)
    js = drv.subscribe(m.JOINT_STATE, "gimbal/joint_states")
    diag = drv.subscribe(m.DIAGNOSTIC_ARRAY, "/diagnostics")
    first = driver_factory(node.domain, name="vehicle_a")
    pub = first.publisher(m.IMU, "imu")
    connect(drv, [pub], [js, diag])
    w = (0.0, 0.5, 0.0)
    t0 = 300.0
    lockstep(drv, pub, [imu(t0 + k * 0.01, w) for k in range(50)])
    first.close()                                          # the publisher disappears
    st = drv.diagnostics_status("gyro_platform: transport", lambda v: v["input_publishers_matched"] == "0")
    assert int(st["processed"]) == 50
    stale = drv.diagnostics_status("gyro_platform: node", lambda v: v["_level"] == 3, timeout=WAIT)  # STALE
    assert "no input" in stale["_message"]
    assert node.alive()

    second = driver_factory(node.domain, name="vehicle_b")
    pub2 = second.publisher(m.IMU, "imu")
    connect(drv, [pub2], [])
    t1 = t0 + 0.49 + 2.0                                   # 2 s later: a gap > max_gap (1 s)
    lockstep(drv, pub2, [imu(t1 + k * 0.01, w) for k in range(50)])
    after = [j for j in drv.got[JS] if stamp_s(j) >= t1 - 1e-9]
    assert len(after) == 50 and after[0].position[0] == 0.0
    for j in after:
        assert j.position[0] == pytest.approx(-0.5 * (stamp_s(j) - t1), abs=1e-6)
    gate = drv.diagnostics_status("gyro_platform: input", lambda v: v["received"] == "100")
    assert gate["resets_by_reason.gap"] == "1"
    assert node.alive()


def test_signals_and_duration_stop_the_node_cleanly(start_node, driver_factory):
    """SIGTERM and SIGINT end the node with exit 0 after a last /diagnostics; --duration ends
    it by itself; the first log line names the transport."""
    for sig in (signal.SIGTERM, signal.SIGINT):
        node = start_node(CARRIED)
        drv = driver_factory(node.domain)
        diag = drv.subscribe(m.DIAGNOSTIC_ARRAY, "/diagnostics")
        assert dds.wait_matched([diag], WAIT)
        drv.diagnostics_status("gyro_platform: transport")            # the periodic one
        assert node.stop(sig, timeout=20.0) == 0, node.log
        assert "stopped after" in node.log
        drv.pump()
        assert drv.got[DIAG], "no diagnostics at all"
        assert node.log.splitlines()[0].endswith("transport: dds")
    node = start_node(None, "--duration", "1.5", wait_ready=False)
    assert node.proc.wait(READY_TIMEOUT) == 0, node.log
    assert "stopped after 1.5 s" in node.log


@pytest.mark.parametrize("args,message", [
    (("--params-file", "/nonexistent/params.yaml"), "params_file"),
    (("--scene", "no_such_scene"), "scene file 'no_such_scene' not found"),
    (("--namespace", "1bad"), "invalid namespace"),
    (("--domain-id", "500"), "outside 0..232"),
    (("--duration", "0"), "must be > 0"),
])
def test_bad_arguments_fail_with_a_clean_message(tmp_path, args, message):
    env = dict(os.environ, CYCLONEDDS_URI=LOOPBACK_XML.as_uri(), ROS_DOMAIN_ID=str(next_domain()),
               PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep))
    r = subprocess.run([sys.executable, "-m", "gyro_platform.cli", "node", "--transport", "dds", "--duration", "1",
                        *args], cwd=ROOT, env=env, capture_output=True, text=True, timeout=READY_TIMEOUT)
    assert r.returncode == 2, r.stderr
    assert message in r.stderr and "Traceback" not in r.stderr


def test_bad_parameter_value_names_the_parameter(tmp_path):
    pfile = tmp_path / "p.yaml"
    pfile.write_text("/**:\n  ros__parameters:\n    output_rate: 10\n")
    env = dict(os.environ, CYCLONEDDS_URI=LOOPBACK_XML.as_uri(), ROS_DOMAIN_ID=str(next_domain()),
               PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep))
    r = subprocess.run([sys.executable, "-m", "gyro_platform.cli", "node", "--transport", "dds",
                        "--params-file", str(pfile)], cwd=ROOT, env=env, capture_output=True, text=True,
                       timeout=READY_TIMEOUT)
    assert r.returncode == 2 and "parameter 'output_rate'" in r.stderr and "10.0" in r.stderr, r.stderr


@pytest.mark.parametrize("text,message", [
    ("imu_topic: bad topic", "parameter 'imu_topic': invalid topic name"),
    ("imu_topic: drift/angle", "parameter 'imu_topic': /drift/angle is one of the node's own output topics"),
])
def test_an_input_topic_the_node_cannot_subscribe_is_one_line_exit_2(tmp_path, text, message):
    """It was a NameError_ / TypeError traceback and exit 1 from inside the DDS adapter."""
    pfile = tmp_path / "p.yaml"
    pfile.write_text(f"/**:\n  ros__parameters:\n    {text}\n")
    env = dict(os.environ, CYCLONEDDS_URI=LOOPBACK_XML.as_uri(), ROS_DOMAIN_ID=str(next_domain()),
               PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep))
    r = subprocess.run([sys.executable, "-m", "gyro_platform.cli", "node", "--transport", "dds", "--duration", "1",
                        "--params-file", str(pfile)], cwd=ROOT, env=env, capture_output=True, text=True,
                       timeout=READY_TIMEOUT)
    assert r.returncode == 2 and message in r.stderr and "Traceback" not in r.stderr, r.stderr


def test_use_sim_time_on_dds_is_said_to_be_ignored(tmp_path):
    pfile = tmp_path / "p.yaml"
    pfile.write_text("/**:\n  ros__parameters:\n    use_sim_time: true\n")
    env = dict(os.environ, CYCLONEDDS_URI=LOOPBACK_XML.as_uri(), ROS_DOMAIN_ID=str(next_domain()),
               PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep))
    r = subprocess.run([sys.executable, "-m", "gyro_platform.cli", "node", "--transport", "dds", "--duration", "0.5",
                        "--params-file", str(pfile)], cwd=ROOT, env=env, capture_output=True, text=True,
                       timeout=READY_TIMEOUT)
    assert r.returncode == 0, r.stderr
    assert "warning: use_sim_time is ignored on the DDS transport" in r.stderr


# =========================================================================================
# node_main: transport choice and the rclpy path (with a stand-in for gyro_platform.ros.node)
# =========================================================================================
def test_auto_falls_back_to_dds_without_rclpy(monkeypatch):
    import gyro_platform.ros
    from gyro_platform.ros import command as node_main
    monkeypatch.setitem(sys.modules, "gyro_platform.ros.node", None)      # import fails, as without ROS
    monkeypatch.delattr(gyro_platform.ros, "node", raising=False)        # (ROS's python may hold it already)
    ok, why = node_main.rclpy_available()
    assert not ok and why


def test_wall_clock_jumps_are_detected(monkeypatch):
    """The DDS node's clock is the wall clock: a jump against the monotonic clock is reported
    (backward → the core resets when reset_on_clock_jump), small drift is not."""
    offset = [0]
    real = time.time_ns
    monkeypatch.setattr(dds.time, "time_ns", lambda: real() + offset[0])
    watch = dds._ClockWatch()
    assert watch.check() is None
    offset[0] = -5 * dds.NS
    kind, delta = watch.check()
    assert kind == "backward" and delta == pytest.approx(-5 * dds.NS, abs=0.1 * dds.NS)
    assert watch.check() is None
    offset[0] += 2 * dds.NS
    assert watch.check()[0] == "forward"
    offset[0] += dds.NS // 100
    assert watch.check() is None


def test_robot_description_and_tf_from_the_dds_node(start_node, driver_factory):
    """The DDS node publishes what robot_state_publisher would under rclpy: the URDF on
    robot_description and the fixed joints on /tf_static (both latched: a late reader gets
    them), and with every JointState the moving joints on /tf, stamped like it, chaining
    base_link → platform to the simulated platform attitude (URDF forward kinematics at the
    published joint positions); frames carry frame_prefix."""
    from scipy.spatial.transform import Rotation
    from urdf_parser_py.urdf import URDF

    from gyro_platform.physics.params import NAV1
    from gyro_platform.ros.urdf import platform_model

    mounting = (0.0, 0.0, math.sin(math.pi / 8), math.cos(math.pi / 8))      # 45° about z
    node = start_node({"mode": "carried", "output_rate": 0.0, "frame_prefix": "robot1/",
                       "physics": {"mounting": list(mounting)}},
                      "--namespace", "robot1")
    drv = driver_factory(node.domain, "/robot1")
    time.sleep(1.0)                                              # late joiners: latched topics still arrive
    desc = drv.subscribe("std_msgs/msg/String", "robot_description", dds_types.LATCHED)
    static = drv.subscribe("tf2_msgs/msg/TFMessage", "/tf_static", dds_types.LATCHED)
    tf = drv.subscribe("tf2_msgs/msg/TFMessage", "/tf", COLLECT)
    js = drv.subscribe(m.JOINT_STATE, "gimbal/joint_states")
    pub = drv.publisher(m.IMU, "imu")
    connect(drv, [pub], [desc, static, tf, js])
    robot = URDF.from_xml_string(drv.wait_for("/robot1/robot_description", lambda s: True).data)
    assert robot.get_root() == "base_link"
    st = drv.wait_for("/tf_static", lambda s: True)
    (mount,) = st.transforms                                     # carried: base_link → platform, fixed
    assert (mount.header.frame_id, mount.child_frame_id) == ("robot1/base_link", "robot1/platform")
    q = mount.transform.rotation
    assert Rotation.from_quat([q.x, q.y, q.z, q.w]).as_euler("xyz")[2] == pytest.approx(math.pi / 4, abs=1e-12)
    for k in range(5):
        pub.publish(imu(10.0 + 0.01 * k, w=(0.2, -0.1, 0.3)))
    last = drv.wait_for("/robot1/gimbal/joint_states", lambda j: stamp_s(j) == pytest.approx(10.04, abs=1e-9))
    moving = drv.wait_for("/tf", lambda t: stamp_s(t.transforms[0]) == stamp_s(last))
    model = platform_model(NAV1.with_(mounting=mounting), stabilised=False)
    assert sorted(t.child_frame_id for t in moving.transforms) == sorted(
        "robot1/" + j.child for j in model.joints if j.type != "fixed")
    pos = dict(zip(last.name, last.position))
    for t in moving.transforms:
        joint = next(j for j in model.joints if "robot1/" + j.child == t.child_frame_id)
        r = t.transform.rotation
        np.testing.assert_allclose(Rotation.from_quat([r.x, r.y, r.z, r.w]).as_matrix(),
                                   Rotation.from_rotvec(np.asarray(joint.axis) * pos[joint.name]).as_matrix(),
                                   atol=1e-12)
        assert t.header.frame_id == "robot1/" + joint.parent


def test_default_discovery_without_multicast_is_localhost_unicast():
    """A host whose only up interface is a loopback without MULTICAST (flags 0x9, as in a
    loopback-only network namespace): unicast localhost discovery and a hint naming what the
    ROS side sets; an explicit CYCLONEDDS_URI or a multicast interface keeps Cyclone's default."""
    lo_only = {"lo": dds_discovery.IFF_UP | dds_discovery.IFF_LOOPBACK}
    uri, hint = dds_discovery.default_discovery({}, lo_only)
    assert "ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST" in hint
    import xml.etree.ElementTree as ET

    ns = {"c": "https://cdds.io/config"}
    root = ET.fromstring(uri)
    assert root.findtext(".//c:AllowMulticast", namespaces=ns) == "false"
    assert root.find(".//c:Peers/c:Peer", ns).get("address") == "localhost"
    assert root.findtext(".//c:ParticipantIndex", namespaces=ns) == "auto"
    assert dds_discovery.default_discovery({"CYCLONEDDS_URI": "file:///x.xml"}, lo_only) == (None, "")
    eth = {**lo_only, "eth0": dds_discovery.IFF_UP | dds_discovery.IFF_MULTICAST}
    assert dds_discovery.default_discovery({}, eth) == (None, "")
    down = {**lo_only, "eth0": dds_discovery.IFF_MULTICAST}                    # multicast-capable but down
    assert dds_discovery.default_discovery({}, down)[0] is not None
    flags = dds_discovery.interface_flags()                                    # this host, read from sysfs
    assert "lo" in flags and flags["lo"] & dds_discovery.IFF_LOOPBACK


def test_discovery_writer_carries_the_type_hash():
    """ros_discovery_info is written with rmw's typehash user data (else ROS processes warn
    "Failed to parse type hash for topic 'ros_discovery_info' … USER_DATA '(null)'")."""
    from cyclonedds.core import Policy

    with dds.DdsNode("hash_probe", "/", next_domain(), types=IDL) as node:
        node.create_publisher(m.JOINT_STATE, "probe")
        ud = node._discovery_writer.get_qos()[Policy.Userdata].data
        assert ud == f"typehash={IDL.type_hash(dds_names.DISCOVERY_TYPE)};".encode()
        assert ud.startswith(b"typehash=RIHS01_") and len(ud) == len("typehash=RIHS01_;") + 64
