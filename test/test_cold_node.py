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

"""A node on a cold kernel cache (``ros.warmup.start_core``, ``engine.remote``): ready at once,
answered by the interpreted kernels in a helper process while the compiled ones are made in
another, then switched to them in the same state — every output message and the statistics
equal to a compiled core's fed the same messages. The safety nets: a killed helper or compile
process (the rest compiles here), a record that replays differently (the helper keeps
answering), a live model change while compiling (refused in one line, taken after), and the
processes gone when the node stops.

The first test starts from an empty cache (it waits for a real background compile, ~30-60 s);
the others force a cold start on the warm cache (its compile process only loads)."""
from __future__ import annotations

import os
from pathlib import Path
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from gyro_platform.engine.remote import ColdStart, WarmingSimulator
from gyro_platform.messages import jazzy_typestore, MessageTypes
from gyro_platform.ros.config import NodeConfig, parameter_defaults
from gyro_platform.ros.core import NodeCore

ROOT = Path(__file__).resolve().parents[1]
STORE = jazzy_typestore()
TYPES = MessageTypes.rosbags(STORE)
T = STORE.types
PARAMS = {"output_rate": 100.0}


def imu(k: int, w) -> tuple[object, int]:
    """The k-th 1 kHz Imu message (rate ``w`` rad/s, at rest under gravity) and its receive time."""
    t = 1_000_000_000 + k * 1_000_000
    v3 = T["geometry_msgs/msg/Vector3"]
    return T["sensor_msgs/msg/Imu"](
        header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=t // 10**9, nanosec=t % 10**9),
                                        frame_id="base_link"),
        orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0), orientation_covariance=np.zeros(9),
        angular_velocity=v3(x=float(w[0]), y=float(w[1]), z=float(w[2])), angular_velocity_covariance=np.zeros(9),
        linear_acceleration=v3(x=0.0, y=0.0, z=9.81), linear_acceleration_covariance=np.zeros(9)), t


def rates(n: int) -> np.ndarray:
    """A vehicle's angular rate, rad/s: slow oscillations with sensor noise."""
    k = np.arange(n)[:, None]
    return 0.02 * np.sin(k * 2e-3 * np.array([1.0, 1.3, 0.7])) + np.random.default_rng(3).normal(0, 0.002, (n, 3))


def outputs(core: NodeCore, w: np.ndarray, start: int = 0, stop: int | None = None) -> list[tuple[int, str, str]]:
    return [(k, topic, repr(m)) for k in range(start, len(w) if stop is None else stop)
            for topic, m in core.on_message(*imu(k, w[k]))]


@pytest.fixture
def cold():
    """A cold start of the default node configuration on the (warm) cache, its notices kept."""
    cfg = NodeConfig.from_ros_params(PARAMS)
    notes: list[str] = []
    c = ColdStart(cfg.params, cfg.options, "test", notes.append)
    c.notes = notes
    c.config = cfg
    yield c
    c.close()


def until_switched(core: NodeCore, w: np.ndarray, k: int) -> tuple[list, int]:
    """Feed messages from ``k`` until the core's simulator is on the compiled kernels."""
    got = []
    deadline = time.monotonic() + 120
    while core.sim.local is None:
        assert time.monotonic() < deadline, "no switch within 120 s"
        got += outputs(core, w, k, k + 1)
        k += 1
    return got, k


def test_a_cold_node_is_ready_at_once_and_switches_to_the_compiled_kernels_in_the_same_state(tmp_path):
    """Empty cache: ``start_core`` returns while the background compile runs (the node's
    ``ready``), the interpreted answers until it ends, the record replays bit for bit, and every
    output of the whole run equals a compiled core's (made after, on the filled cache)."""
    probe = textwrap.dedent("""
        import json, sys, time
        sys.path.insert(0, sys.argv[1])
        from test_cold_node import imu, outputs, rates, PARAMS, STORE, TYPES
        from gyro_platform.physics.jit import compile_notices
        from gyro_platform.ros.config import NodeConfig
        from gyro_platform.ros.core import NodeCore
        from gyro_platform.ros.dds_types import zero_message
        from gyro_platform.ros.warmup import start_core

        compile_notices("probe")
        cfg = NodeConfig.from_ros_params(PARAMS)
        notes = []
        core = start_core(cfg, TYPES, lambda: zero_message(STORE, cfg.input_type_name), prog="probe",
                          notice=notes.append)
        cold = core.make_simulator.__self__
        compiling = cold.compiler.poll() is None
        w = rates(200_000)
        got, k = [], 0
        while core.sim.local is None and k < len(w) - 2000:
            got += outputs(core, w, k, k + 1)
            k += 1
        switched_at = k
        got += outputs(core, w, k, k + 2000)
        bound = core.sim.push_plain.__self__ is core.sim.local
        ref = NodeCore(cfg, TYPES)
        want = outputs(ref, w, 0, k + 2000)
        print(json.dumps({"compiling_at_ready": compiling, "switched_at": switched_at, "n_out": len(got),
                          "identical": got == want, "stats": core.sim.stats == ref.sim.stats, "bound": bound,
                          "notes": notes}))
    """)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    p = subprocess.run([sys.executable, "-c", probe, str(ROOT / "test")], cwd=ROOT, env=env, capture_output=True,
                       text=True, timeout=1200)
    assert p.returncode == 0, p.stderr[-3000:]
    import json
    r = json.loads(p.stdout.splitlines()[-1])
    assert r["compiling_at_ready"], r                          # ready before the kernels were compiled
    assert r["switched_at"] > 0 and r["n_out"] > 1000, r       # answered while they compiled, then compiled
    assert r["identical"] and r["stats"] and r["bound"], r
    assert "not compiled yet" in r["notes"][0] and "identical to the interpreted run" in r["notes"][-1], r
    assert "probe (background compile): compiling the simulation kernels" in p.stderr, p.stderr[-2000:]
    assert "probe: compiling" not in p.stderr, p.stderr[-2000:]      # nothing compiled in the node's process


def test_a_forced_cold_start_matches_a_compiled_core_and_binds_the_compiled_methods(cold):
    os.kill(cold.compiler.pid, signal.SIGSTOP)          # both cores on the helper before the switch
    core = NodeCore(cold.config, TYPES, simulator=cold.simulator)
    other = NodeCore(cold.config, TYPES, simulator=cold.simulator)      # e.g. the warm-up's scratch core
    assert isinstance(core.sim, WarmingSimulator) and core.sim.system.stabilised
    assert core.snapshot()["kernels"] == "interpreted, compiling in the background"      # in /diagnostics
    w = rates(6000)
    other_got = outputs(other, w, 0, 300)
    os.kill(cold.compiler.pid, signal.SIGCONT)
    got, k = until_switched(core, w, 0)
    assert core.snapshot()["kernels"] == "compiled"
    got += outputs(core, w, k)
    ref = NodeCore(cold.config, TYPES)
    assert got == outputs(ref, w) and core.sim.stats == ref.sim.stats
    assert core.sim.push_plain.__self__ is core.sim.local            # nothing in between any more
    assert cold.rc == 0 and cold.switched == 1
    assert "identical to the interpreted run" in cold.notes[-1], cold.notes
    assert cold.helper.poll() is not None                           # the helper is retired after the switch
    # the other core, still on the retired helper: its own record replayed at its next call
    other_got += outputs(other, w, 300, 1000)
    assert other.sim.local is not None and cold.switched == 2
    assert other_got == outputs(NodeCore(cold.config, TYPES), w, 0, 1000)
    assert type(core.make_simulator(cold.params, cold.options)).__name__ == "Simulator"   # compiled from now on


@pytest.mark.parametrize("victim", ["helper", "compiler"])
def test_a_killed_helper_or_compile_process_leaves_the_rest_to_this_process(cold, victim):
    """SIGKILL of the interpreting helper (the next call finds it gone) or of the compile
    process (it ended with a failure): the record is replayed into a Simulator compiled here,
    said in one line, and the outputs stay those of a compiled core."""
    os.kill(cold.compiler.pid, signal.SIGKILL if victim == "compiler" else signal.SIGSTOP)
    core = NodeCore(cold.config, TYPES, simulator=cold.simulator)
    w = rates(3000)
    got = outputs(core, w, 0, 500)
    if victim == "helper":                      # the compile still running (stopped): no switch yet
        assert core.sim.local is None
        os.kill(cold.helper.pid, signal.SIGKILL)
        cold.helper.wait()
    got += outputs(core, w, 500)
    if victim == "helper":
        os.kill(cold.compiler.pid, signal.SIGCONT)
    assert core.sim.local is not None
    assert got == outputs(NodeCore(cold.config, TYPES), w)
    said = " ".join(cold.notes)
    assert ("the helper ended" if victim == "helper" else "ended with status -9") + "; compiling here" in said


def test_a_live_model_change_waits_for_the_compiled_kernels(cold):
    """While the compile runs, a parameter that rebuilds the model is refused with its reason
    (the node answers the ROS parameter request so); after the switch it is taken."""
    os.kill(cold.compiler.pid, signal.SIGSTOP)                     # still compiling, for sure
    core = NodeCore(cold.config, TYPES, simulator=cold.simulator)
    w = rates(3000)
    kp = parameter_defaults("")["physics.servo_kp"]
    new_kp = [1.1 * x for x in kp] if isinstance(kp, (list, tuple)) else 1.1 * kp
    try:
        outputs(core, w, 0, 200)
        ok, why = core.set_parameters({"physics.servo_kp": new_kp})
        assert not ok and "cannot change while its kernels compile" in why, why
        ok, why = core.set_parameters({"output_rate": 50.0})    # not the model: taken
        assert ok, why
    finally:
        os.kill(cold.compiler.pid, signal.SIGCONT)
    until_switched(core, w, 200)
    ok, why = core.set_parameters({"physics.servo_kp": new_kp})
    assert ok, why


def test_a_record_that_replays_differently_keeps_the_interpreted_answers(cold):
    """The check before the switch: a record the compiled Simulator does not reproduce (here
    one call the helper never saw) is said loudly and the helper keeps answering, correctly."""
    os.kill(cold.compiler.pid, signal.SIGSTOP)                     # no switch before the record is changed
    core = NodeCore(cold.config, TYPES, simulator=cold.simulator)
    w = rates(4000)
    try:
        got = outputs(core, w, 0, 100)
        core.sim.record.insert(50, ("reset", (), None))
    finally:
        os.kill(cold.compiler.pid, signal.SIGCONT)
    k, deadline = 100, time.monotonic() + 120
    while not core.sim.kept:
        assert time.monotonic() < deadline and core.sim.local is None, cold.notes
        got += outputs(core, w, k, k + 1)
        k += 1
    assert any("NOT switching" in n for n in cold.notes) and cold.rc == 0, cold.notes
    got += outputs(core, w, k, k + 500)
    assert core.sim.local is None
    assert got == outputs(NodeCore(cold.config, TYPES), w, 0, k + 500)
    # and if that helper then dies, its state cannot be rebuilt: a counted restart, not a silent one
    os.kill(cold.helper.pid, signal.SIGKILL)
    cold.helper.wait()
    assert outputs(core, w, k + 500, k + 1000) and core.sim.local is not None
    assert core.outcomes["restarted"] == 1 and core.snapshot()["kernels"] == "compiled", dict(core.outcomes)


def test_close_ends_both_processes_at_once(cold):
    os.kill(cold.compiler.pid, signal.SIGSTOP)          # a compile that would not end by itself
    NodeCore(cold.config, TYPES, simulator=cold.simulator)
    t0 = time.monotonic()
    cold.close()
    assert cold.compiler.poll() is not None and cold.helper.poll() is not None
    assert time.monotonic() - t0 < 5                   # terminated, not waited for (a loose bound)
    cold.close()                                        # idempotent


def test_the_dds_node_on_an_empty_cache_is_ready_before_its_kernels_compile_and_stops_on_sigterm(tmp_path):
    """``gyro-platform node --transport dds`` on an empty cache: the notice, then ``ready:``
    while the background compile runs; SIGTERM stops the node (exit 0) and its compile process."""
    from gyro_platform.bench.coldstart import LOOPBACK_XML

    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    p = subprocess.Popen([sys.executable, "-m", "gyro_platform", "node", "--transport", "dds", "--cyclonedds-config",
                          str(LOOPBACK_XML), "--domain-id", "87"], cwd=ROOT, env=env, stdout=subprocess.DEVNULL,
                         stderr=subprocess.PIPE, text=True, start_new_session=True)
    lines: list[str] = []
    try:
        for line in p.stderr:
            lines.append(line)
            if "ready:" in line:
                break
        text = "".join(lines)
        assert "not compiled yet" in text and "ready:" in text, text
        pid = int(text.split("(pid ")[1].split(")")[0])
        assert "gyro-platform node: compiling" not in text            # nothing compiled in the node's process
        os.kill(pid, 0)                                  # the compile process runs on after ready
        p.send_signal(signal.SIGTERM)
        rest = p.communicate(timeout=60)[1]
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    assert p.returncode == 0, text + rest
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)                                  # stopped with the node


def test_a_helper_that_cannot_start_leaves_the_start_to_this_process(monkeypatch):
    """``start_core`` on a (forced) cold cache whose helper dies at once: said in one line, the
    core gets a compiled Simulator here, as without the helper."""
    from contextlib import contextmanager

    from gyro_platform.engine import remote
    from gyro_platform.physics import jit
    from gyro_platform.ros.dds_types import zero_message
    from gyro_platform.ros.warmup import start_core

    @contextmanager
    def refused():
        raise jit.CompileRefused("forced: a kernel is not in the kernel cache")
        yield

    spawn = remote._spawn

    def broken(mode, prog, env):
        proc, to, back = spawn(mode, prog, env)
        if mode == "interpret":
            proc.kill()
            proc.wait()
        return proc, to, back

    monkeypatch.setattr(jit, "can_refuse_compiles", lambda: True)
    monkeypatch.setattr(jit, "compiles_refused", refused)
    monkeypatch.setattr(remote, "_spawn", broken)
    cfg = NodeConfig.from_ros_params(PARAMS)
    notes: list[str] = []
    core = start_core(cfg, TYPES, lambda: zero_message(STORE, cfg.input_type_name), prog="test", notice=notes.append)
    assert type(core.sim).__name__ == "Simulator", notes
    assert "not compiled yet" in notes[0] and notes[-1].endswith("; compiling here"), notes
    w = rates(300)
    assert outputs(core, w) == outputs(NodeCore(cfg, TYPES), w)


def test_bad_input_while_interpreted_gives_the_compiled_cores_outcomes(cold):
    """NaN rates, a repeated and a backward stamp and a 0.5 s gap fed during the interpreted phase
    and across the switch: the same outputs, outcomes and gate counters as a compiled core's
    (errors raised in the helper come back as the same classes; the record replays them)."""
    os.kill(cold.compiler.pid, signal.SIGSTOP)
    core = NodeCore(cold.config, TYPES, simulator=cold.simulator)
    ref = NodeCore(cold.config, TYPES)
    w = rates(4000)
    w[100] = np.nan
    w[101, 1] = np.inf
    order = list(range(0, 300)) + [299, 250] + list(range(300, 1500)) + list(range(2000, 4000))   # repeat, back, gap

    def run(c: NodeCore, ks) -> list:
        return [(k, topic, repr(m)) for k in ks for topic, m in c.on_message(*imu(k, w[k]))]

    got = run(core, order[:1000])
    os.kill(cold.compiler.pid, signal.SIGCONT)
    deadline = time.monotonic() + 120
    i = 1000
    while core.sim.local is None:
        assert time.monotonic() < deadline and i < len(order), cold.notes
        got += run(core, order[i:i + 1])
        i += 1
    got += run(core, order[i:])
    assert got == run(ref, order)
    assert dict(core.outcomes) == dict(ref.outcomes) and core.gate.snapshot() == ref.gate.snapshot()
    assert "identical to the interpreted run" in cold.notes[-1], cold.notes
    assert core.outcomes["rejected"] + core.gate.snapshot()["dropped"] >= 3, dict(core.outcomes)
