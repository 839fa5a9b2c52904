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

"""A probe node for the ROS tests: publishes rate inputs, records topics and TF, prints JSON.

Run in ROS's python (rclpy) by :meth:`rosenv.RosEnv.probe`, as a separate process beside the
node under test: ``python3 ros_probe.py SPEC_JSON``. SPEC (all keys optional)::

    {"wait_subscriber": "/imu",              # wait (≤ discovery s) until the node subscribes
     "discovery": 20.0,
     "publish": {"topic": "/imu", "type": "imu" | "twist" | "twist_stamped", "rate": 100.0,
                 "count": 200, "w": [wx, wy, wz], "f": [fx, fy, fz], "frame_id": "base_link",
                 "stamp": "now" | "zero" | <t0 in s>,
                 "frames": ["base_link", "imu_link"]},   # frame_id by equal parts of count
     "collect": {"/gimbal/joint_states": "sensor_msgs/msg/JointState", ...},
     "latched": {"/robot_description": "std_msgs/msg/String"},   # transient local readers
     "best_effort": {"/clock": "rosgraph_msgs/msg/Clock"},      # best-effort readers
     "settle": 1.0,                          # s to keep collecting after the last input
     "until": {"/diagnostics": 2},           # or collect until these counts (≤ timeout)
     "timeout": 30.0,
     "tf": [["platform", "gyro_frame4"], ...],   # looked up in a tf2_ros.Buffer at the end
     "command": ["ros2", "bag", "play", ...],   # run while collecting (after "pre"); then settle
     "storm": {"node": "/gyro_platform_node", "rate": 300.0,   # SetParameters requests, one
               "params": [["gate.max_rate", 30.0], ...]}}      # parameter each, during "publish"

The report (last stdout line): ``{"published": n, "topics": {topic: [message dicts]},
"tf": {"target|source": {"stamp": s, "rotation": [x, y, z, w], "translation": [...]}
| {"error": "..."}}, "command": {"returncode": n, "output": tail} (with "command"),
"storm": [{"name", "value", "successful", "reason"} in request order] (with "storm")}``.
"""
import importlib
import json
import subprocess
import sys
import threading
import time

import rclpy
from rclpy.qos import DurabilityPolicy, qos_profile_sensor_data, QoSProfile, ReliabilityPolicy
from rosidl_runtime_py.convert import message_to_ordereddict
import tf2_ros

COLLECT = QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE)
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
BEST_EFFORT = QoSProfile(depth=5000, reliability=ReliabilityPolicy.BEST_EFFORT)
INPUT_TYPES = {"imu": "sensor_msgs/msg/Imu", "twist": "geometry_msgs/msg/Twist",
               "twist_stamped": "geometry_msgs/msg/TwistStamped"}


def msg_type(name):
    """The message class of 'pkg/msg/Name'."""
    pkg, _, cls = name.split("/")
    return getattr(importlib.import_module(f"{pkg}.msg"), cls)


def make_input(kind, t_ns, w, f, frame_id):
    """One rate sample of kind imu / twist / twist_stamped stamped t_ns."""
    m = msg_type(INPUT_TYPES[kind])()
    ang = m.angular_velocity if kind == "imu" else (m.twist.angular if kind == "twist_stamped" else m.angular)
    ang.x, ang.y, ang.z = (float(v) for v in w)
    if kind == "imu":
        m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z = (float(v) for v in f)
    if kind != "twist":
        m.header.stamp.sec, m.header.stamp.nanosec = divmod(int(t_ns), 10**9)
        m.header.frame_id = frame_id
    return m


class Storm:
    """SetParameters requests (one parameter each) at ``rate`` per second, sent from the probe's
    publish loop; responses collected in request order."""

    def __init__(self, node, spec):
        from rcl_interfaces.srv import SetParameters
        self.srv, self.node = SetParameters, node
        from rclpy.qos import qos_profile_parameters  # keep last 1000: no response overwritten
        self.client = node.create_client(SetParameters, spec["node"] + "/set_parameters",
                                         qos_profile=qos_profile_parameters)
        if not self.client.wait_for_service(timeout_sec=float(spec.get("discovery", 20.0))):
            raise SystemExit(f'no service {spec["node"]}/set_parameters')
        self.params = [tuple(p) for p in spec["params"]]
        self.period = 1.0 / float(spec.get("rate", 200.0))
        self.futures = []
        self.start = None

    def send_due(self):
        from rclpy.parameter import Parameter
        now = time.monotonic()
        if self.start is None:
            self.start = now
        while len(self.futures) < len(self.params) and self.start + len(self.futures) * self.period <= now:
            name, value = self.params[len(self.futures)]
            req = self.srv.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
            self.futures.append(self.client.call_async(req))

    def finish(self, spin_for, timeout=60.0):
        while len(self.futures) < len(self.params):
            self.send_due()
            spin_for(0.001)
        spin_for(timeout, lambda: all(f.done() for f in self.futures))

    def results(self):
        out = []
        for (name, value), f in zip(self.params, self.futures):
            r = f.result().results[0] if f.done() and f.result() is not None else None
            out.append({"name": name, "value": value, "successful": None if r is None else bool(r.successful),
                        "reason": None if r is None else r.reason})
        return out


def main(spec):
    """Run the probe of ``spec``; the report as a dict."""
    rclpy.init()
    node = rclpy.create_node("ros_probe")
    got = {}
    for table, qos in ((spec.get("collect", {}), COLLECT), (spec.get("latched", {}), LATCHED),
                       (spec.get("best_effort", {}), BEST_EFFORT)):
        for topic, typ in table.items():
            got[topic] = []
            node.create_subscription(msg_type(typ), topic, got[topic].append, qos)
    buffer = tf2_ros.Buffer()
    tf2_ros.TransformListener(buffer, node)

    def spin_for(seconds, done=lambda: False):
        end = time.monotonic() + seconds
        while time.monotonic() < end and not done():
            rclpy.spin_once(node, timeout_sec=0.005)

    discovery = float(spec.get("discovery", 20.0))
    if spec.get("wait_subscriber"):
        spin_for(discovery, lambda: node.count_subscribers(spec["wait_subscriber"]) > 0)
        if node.count_subscribers(spec["wait_subscriber"]) == 0:
            raise SystemExit(f'no subscriber on {spec["wait_subscriber"]} after {discovery} s')
    spin_for(float(spec.get("pre", 0.5)))       # let the node's publishers match our readers
    report = {}
    if spec.get("command"):
        cmd = subprocess.Popen(spec["command"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        out = []
        reader = threading.Thread(target=lambda: out.extend(cmd.stdout), daemon=True)
        reader.start()
        while cmd.poll() is None:
            spin_for(0.05)
        reader.join(5.0)
        report["command"] = {"returncode": cmd.returncode, "output": "".join(out)[-3000:]}
    storm = Storm(node, spec["storm"]) if spec.get("storm") else None
    published = 0
    pub_spec = spec.get("publish")
    if pub_spec:
        kind = pub_spec.get("type", "imu")
        pub = node.create_publisher(msg_type(INPUT_TYPES[kind]), pub_spec["topic"], qos_profile_sensor_data)
        spin_for(1.0, lambda: pub.get_subscription_count() > 0)
        period = 1.0 / float(pub_spec.get("rate", 100.0))
        stamp = pub_spec.get("stamp", "now")
        if stamp == "now":
            t0 = node.get_clock().now().nanoseconds
        else:
            t0 = 0 if stamp == "zero" else int(float(stamp) * 1e9)
        start = time.monotonic()
        count, frames = int(pub_spec.get("count", 100)), pub_spec.get("frames")
        for k in range(count):
            t_ns = 0 if stamp == "zero" else t0 + int(round(k * period * 1e9))
            frame = frames[k * len(frames) // count] if frames else pub_spec.get("frame_id", "base_link")
            pub.publish(make_input(kind, t_ns, pub_spec.get("w", (0.0, 0.0, 0.0)),
                                   pub_spec.get("f", (0.0, 0.0, 9.81)), frame))
            published += 1
            if storm is not None:
                storm.send_due()
            spin_for(max(0.0, start + (k + 1) * period - time.monotonic()))
    if storm is not None:
        storm.finish(spin_for)
        report["storm"] = storm.results()
    until = spec.get("until", {})
    if until:
        spin_for(float(spec.get("timeout", 30.0)), lambda: all(len(got.get(t, ())) >= n for t, n in until.items()))
    else:           # settle: the whole time (all() of no condition would end it at once)
        spin_for(float(spec.get("settle", 1.0)))
    report.update({"published": published, "tf": {},
                   "topics": {t: [json.loads(json.dumps(message_to_ordereddict(m))) for m in ms]
                              for t, ms in got.items()}})
    for target, source in spec.get("tf", []):
        key = f"{target}|{source}"
        try:
            tr = buffer.lookup_transform(target, source, rclpy.time.Time())
        except tf2_ros.TransformException as e:
            report["tf"][key] = {"error": str(e)}
            continue
        r, t = tr.transform.rotation, tr.transform.translation
        report["tf"][key] = {"stamp": tr.header.stamp.sec + tr.header.stamp.nanosec * 1e-9,
                             "rotation": [r.x, r.y, r.z, r.w], "translation": [t.x, t.y, t.z]}
    node.destroy_node()
    rclpy.try_shutdown()
    return report


if __name__ == "__main__":
    print(json.dumps(main(json.loads(sys.argv[1]))))
