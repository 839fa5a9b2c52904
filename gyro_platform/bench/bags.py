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

"""The benchmark's input bags: a 1 kHz ``sensor_msgs/Imu`` bag of its own making (a ground
vehicle's motion with sensor noise, written with rosbags, cached), the shared husky recording
found as the ``husky_replay`` scene finds it, and short copies of bags for ``--quick``.

Frames: the Imu messages are in ``base_link`` (FLU, REP-103); rates rad/s, specific force m/s².
Bags are written to a temporary name and renamed, so an interrupted run never leaves a cache
entry that looks complete.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
import os
from pathlib import Path
import shutil
import tempfile

import numpy as np

from ..engine.hardcases import engine_vibration
from ..messages import jazzy_typestore
from ..scenes.motions import G, RandomMotion

__all__ = ["VehicleImu", "vehicle_imu", "write_imu_bag", "cached_imu_bag", "husky_bag", "short_copy",
           "cache_dir", "IMU_TOPIC", "HUSKY_SCENE"]

IMU_TOPIC = "/imu/data"
HUSKY_SCENE = "husky_replay"
#: bump when the generated bag's content changes (the cache key)
BAG_VERSION = 2
#: epoch of the first header stamp (ns): 2026-01-01, well inside the signed 64-bit ns range
T0_NS = 1_767_225_600 * 1_000_000_000


@dataclass(frozen=True)
class VehicleImu:
    """Samples of an IMU on a ground vehicle: times ``t`` (s from the start), body rates
    ``omega`` (N, 3; rad/s, FLU) and specific force ``force`` (N, 3; m/s²), noise included."""

    t: np.ndarray
    omega: np.ndarray
    force: np.ndarray


def vehicle_imu(duration: float, rate: float = 1000.0, seed: int = 12, jitter: float = 0.0,
                vibration: bool = False, parked: bool = False) -> VehicleImu:
    """A ground vehicle on a rough road: band-limited roll/pitch (RMS 2°/1.5°, 0.2–3 Hz), heading
    changes (RMS 25°, 0.005–0.2 Hz), body accelerations (RMS 0.8/0.4/0.5 m/s² x/y/z, 0.05–2 Hz) on
    top of gravity, plus a MEMS-grade gyro (white noise 0.005 °/s/√Hz, bias 0.05 °/s) and
    accelerometer (100 µg/√Hz, bias 5 mg). ``jitter`` > 0: sample times moved by up to
    ±jitter periods (uniform), as a driver's header stamps are (the samples are those times').
    ``vibration``: plus a 37 Hz engine vibration of 0.3 rad/s (``engine.hardcases.engine_vibration``).
    ``parked``: the same sensor on the vehicle at rest, level (its noise and bias on zero rates and
    on gravity's reaction, 0, 0, +g in body axes)."""
    road = RandomMotion(seed, angle_rms=(math.radians(2.0), math.radians(1.5), 0.0), band=(0.2, 3.0))
    heading = RandomMotion(seed + 1, angle_rms=(0.0, 0.0, math.radians(25.0)), band=(0.005, 0.2))
    t, w_road, f = road.arrays(duration, rate)      # f: gravity's reaction in body axes
    if jitter > 0.0:
        t = t + np.random.default_rng(seed + 3).uniform(-jitter, jitter, t.size) / rate
        t[0] = max(t[0], 0.0)
        w_road = road.omega(t)
        f = road.specific_force(t)
    w = w_road + heading.omega(t)          # small-angle composition: adequate for a test signal
    rng = np.random.default_rng(seed + 2)
    n = 12                                 # body accelerations: sums of n sines, given RMS per axis
    fr = rng.uniform(0.05, 2.0, (3, n)) * 2 * math.pi
    ph = rng.uniform(0, 2 * math.pi, (3, n))
    amp = np.array([0.8, 0.4, 0.5])[:, None] * math.sqrt(2.0 / n)
    f = f + (amp[:, :, None] * np.sin(fr[:, :, None] * t[None, None, :] + ph[:, :, None])).sum(axis=1).T
    if parked:           # (the motion above is still drawn: the noise below is the road input's)
        w = np.zeros_like(w)
        f = np.tile([0.0, 0.0, G], (t.size, 1))
    sq = math.sqrt(rate)
    w = w + math.radians(0.05) * rng.standard_normal(3) + math.radians(0.005) * sq * rng.standard_normal(w.shape)
    f = f + 5e-3 * 9.80665 * rng.standard_normal(3) + 100e-6 * 9.80665 * sq * rng.standard_normal(f.shape)
    if vibration:
        w = w + engine_vibration(t, noise=False)
    return VehicleImu(t, w, f)


def _imu_messages(imu: VehicleImu, frame_id: str):
    """(record ns, CDR bytes) of each sample, header stamp = record time."""
    store = jazzy_typestore()
    T = store.types
    cov_w = np.diag([math.radians(0.005) ** 2 * 1000.0] * 3).reshape(9)
    cov_f = np.diag([(100e-6 * 9.80665) ** 2 * 1000.0] * 3).reshape(9)
    cov_q = np.zeros(9)
    cov_q[0] = -1.0                        # REP-145: no orientation estimate
    q = T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)
    V = T["geometry_msgs/msg/Vector3"]
    ns = T0_NS + np.round(imu.t * 1e9).astype(np.int64)
    for i in range(imu.t.size):
        sec, nsec = divmod(int(ns[i]), 1_000_000_000)
        msg = T["sensor_msgs/msg/Imu"](
            header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec),
                                            frame_id=frame_id),
            orientation=q, orientation_covariance=cov_q,
            angular_velocity=V(x=float(imu.omega[i, 0]), y=float(imu.omega[i, 1]), z=float(imu.omega[i, 2])),
            angular_velocity_covariance=cov_w,
            linear_acceleration=V(x=float(imu.force[i, 0]), y=float(imu.force[i, 1]), z=float(imu.force[i, 2])),
            linear_acceleration_covariance=cov_f)
        yield int(ns[i]), store.serialize_cdr(msg, "sensor_msgs/msg/Imu")


def _plugin(storage: str):
    from rosbags.rosbag2 import StoragePlugin

    return {"sqlite3": StoragePlugin.SQLITE3, "mcap": StoragePlugin.MCAP}[storage]


def _staging(path: Path) -> Path:
    """Where the bag for ``path`` is written first: a folder of the same name (rosbags names the
    storage file after it, and metadata.yaml lists that name) in a hidden per-process folder."""
    tmp = path.parent / f".partial-{os.getpid()}" / path.name
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.parent.mkdir(parents=True, exist_ok=True)
    return tmp


def _publish(tmp: Path, path: Path) -> Path:
    """Rename the finished bag ``tmp`` to ``path`` (another process may have won the race)."""
    try:
        os.replace(tmp, path) if not path.exists() else shutil.rmtree(tmp)
    except OSError:
        if not path.exists():
            raise
        shutil.rmtree(tmp, ignore_errors=True)
    shutil.rmtree(tmp.parent, ignore_errors=True)
    return path


def write_imu_bag(path: Path, imu: VehicleImu, storage: str = "sqlite3", topic: str = IMU_TOPIC,
                  frame_id: str = "base_link") -> Path:
    """Write ``imu`` as a rosbag2 v9 bag (rosbags ``Writer``) at ``path`` (must not exist)."""
    from rosbags.rosbag2 import Writer

    path = Path(path)
    tmp = _staging(path)
    with Writer(tmp, version=9, storage_plugin=_plugin(storage)) as w:
        conn = w.add_connection(topic, "sensor_msgs/msg/Imu", typestore=jazzy_typestore())
        for ts, raw in _imu_messages(imu, frame_id):
            w.write(conn, ts, raw)
    return _publish(tmp, path)


def cache_dir() -> Path:
    """Where generated bags are kept: ``$GYRO_PLATFORM_BENCH_CACHE`` or ``<tmp>/gyro_platform_bench``."""
    d = Path(os.environ.get("GYRO_PLATFORM_BENCH_CACHE") or Path(tempfile.gettempdir()) / "gyro_platform_bench")
    d.mkdir(parents=True, exist_ok=True)
    return d


def cached_imu_bag(duration: float, storage: str, rate: float = 1000.0, seed: int = 12,
                   jitter: float = 0.0, vibration: bool = False) -> Path:
    """The vehicle Imu bag of ``duration`` s at ``rate`` Hz in ``storage`` (``vehicle_imu``'s
    ``seed``, ``jitter`` and ``vibration``), made once and cached."""
    variant = "" if (seed, jitter) == (12, 0.0) else f"_seed{seed}_jitter{jitter:g}"
    variant += "_vibrating" if vibration else ""
    path = cache_dir() / f"vehicle_imu_v{BAG_VERSION}_{rate:g}hz_{duration:g}s{variant}_{storage}"
    if (path / "metadata.yaml").is_file():
        return path
    shutil.rmtree(path, ignore_errors=True)
    return write_imu_bag(path, vehicle_imu(duration, rate, seed, jitter, vibration), storage)


def husky_bag() -> tuple[Path | None, str]:
    """The husky recording as the ``husky_replay`` scene resolves it: (path, "") or (None, why not)."""
    from ..scenes.schema import load_scene, ScenarioError

    try:
        scene = load_scene(HUSKY_SCENE)
    except ScenarioError as e:
        return None, "not found" if "not found" in str(e) else f"scene {HUSKY_SCENE}: {e}"
    path = scene.motion.path
    return (Path(path), "") if path is not None and Path(path).exists() else (None, "not found")


def short_copy(src: Path, seconds: float) -> Path:
    """A cached copy of bag ``src`` holding its first ``seconds`` s (every topic), same storage."""
    from rosbags.rosbag2 import Reader, Writer

    from ..bags.paths import storage_of

    src = Path(src)
    storage = storage_of(src)
    path = cache_dir() / f"{src.name}_first{seconds:g}s_{storage}"
    if (path / "metadata.yaml").is_file():
        return path
    tmp = _staging(path)
    with Reader(src) as r, Writer(tmp, version=9, storage_plugin=_plugin(storage)) as w:
        conns = {c.id: w.add_connection(c.topic, c.msgtype, msgdef=c.msgdef.data or None, rihs01=c.digest or None,
                                        serialization_format=c.ext.serialization_format,
                                        offered_qos_profiles=c.ext.offered_qos_profiles,
                                        **({} if c.msgdef.data else {"typestore": jazzy_typestore()}))
                 for c in r.connections}
        end = r.start_time + int(seconds * 1e9)
        for c, ts, raw in r.messages():
            if ts > end:
                break
            w.write(conns[c.id], ts, raw)
    return _publish(tmp, path)
