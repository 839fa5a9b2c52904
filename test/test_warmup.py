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

"""Warm-up before "ready" (both transports): every kernel the first real sample needs is
compiled (or loaded from numba's cache) by synthetic samples on a throwaway core, and the
real core is left untouched. Checked in a fresh interpreter, so that kernels compiled by
other tests cannot hide a kernel the warm-up misses."""
from __future__ import annotations

import json
from pathlib import Path
import subprocess
import sys

import pytest

ROOT = Path(__file__).resolve().parents[1]

SCRIPT = r"""
import json, sys
from gyro_platform.physics import effects
from gyro_platform.engine import batch
from gyro_platform.engine.integrators import exponential as integrators
from gyro_platform.physics import model
from gyro_platform.physics import rotations
from gyro_platform.physics import system
from gyro_platform.physics import tree
from gyro_platform.ros.config import NodeConfig
from gyro_platform.ros.core import NodeCore
from gyro_platform.ros.dds_types import zero_message
from gyro_platform.messages import MessageTypes, jazzy_typestore
from gyro_platform.ros.warmup import warm_up

def signatures():
    res = {}
    for mod in (effects, batch, integrators, model, rotations, system, tree):
        for name in dir(mod):
            obj = getattr(mod, name)
            if hasattr(obj, "signatures") and hasattr(obj, "py_func"):
                res[mod.__name__ + "." + name] = len(obj.signatures)
    return res

types = MessageTypes.rosbags()
core = NodeCore(NodeConfig.from_ros_params(json.loads(sys.argv[1])), types)
n = warm_up(core, lambda: zero_message(jazzy_typestore(), core.input_type))
untouched = core.received == 0 and core.published == 0 and core.sim.t_start is None
before = signatures()
for k in range(6):
    msg = zero_message(jazzy_typestore(), core.input_type)
    if hasattr(msg, "header"):
        msg.header.stamp.sec, msg.header.stamp.nanosec = 7, k * 10_000_000
        msg.header.frame_id = "base_link"
    if hasattr(msg, "angular_velocity"):
        msg.angular_velocity.z = 0.1
        msg.linear_acceleration.z = 9.81
    core.on_message(msg, 7_000_000_000 + k * 10_000_000)
after = signatures()
print(json.dumps({"n": n, "outputs": len(core.output_topics()), "untouched": untouched,
                  "published": core.published, "compiled": sum(1 for v in before.values() if v),
                  "new": {k: [before.get(k, 0), v] for k, v in after.items() if v != before.get(k, 0)}}))
"""


@pytest.mark.parametrize("params", [{}, {"mode": "carried", "input_type": "twist_stamped"}])
def test_warm_up_compiles_what_the_first_samples_use(params):
    out = subprocess.run([sys.executable, "-c", SCRIPT, json.dumps(params)], cwd=ROOT, capture_output=True,
                         text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    r = json.loads(out.stdout.strip().splitlines()[-1])
    assert r["untouched"]                                   # the warm-up used a throwaway core
    assert r["n"] >= r["outputs"]                           # it built every output message
    assert r["published"] >= 1 and r["compiled"] > 0
    assert r["new"] == {}, f"kernels compiled only by the first real samples: {r['new']}"


def test_the_node_entry_point_collects_again_once_its_start_up_is_frozen():
    """``ros2 run``'s entry point (``cli.platform_node``) keeps the collector off while the node's
    modules load and it warms up; ``freeze_startup_objects`` (after the warm-up, before the first
    sample) freezes the start-up's objects and switches the collector on again: a node that ran
    for hours without it would keep every reference cycle it ever made."""
    probe = ("import gc; gc.disable(); from gyro_platform.ros.warmup import freeze_startup_objects; "
             "freeze_startup_objects(); print(gc.isenabled(), gc.get_freeze_count())")
    p = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr[-2000:]
    enabled, frozen = p.stdout.split()
    assert enabled == "True" and int(frozen) > 1000, p.stdout
