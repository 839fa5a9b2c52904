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

"""ROS 2 Jazzy from outside, for the tests: find it, run commands in it, build this package.

Holds :class:`RosEnv` (the environment of a sourced ROS 2 setup file; ``run`` and ``start`` in
it), :class:`Workspace` (a temporary colcon workspace holding this package), :class:`Proc` (a
started process: its output, a clean stop) and :func:`domain_lock` (a ``ROS_DOMAIN_ID`` no
other test on this machine holds). Imports only the standard library: the tests that use it
run in any Python, the project's venv (numpy 2) or ROS's own (numpy 1.26); everything ROS runs
in subprocesses with ROS's python, as a ROS engineer's shell would.

ROS 2 is looked up in this order: the file named by ``GYRO_PLATFORM_ROS_SETUP``; the current
environment when it is sourced (``ROS_DISTRO=jazzy``); ``/opt/ros/jazzy/setup.bash``;
``$ROS2_PREFIX/env.sh`` and ``~/ros2-jazzy-ws/env.sh`` (the prebuilt Jazzy of ``../shared/ros2``).
"""
from __future__ import annotations

import contextlib
from dataclasses import dataclass, field
import fcntl
import functools
import json
import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from typing import Iterator, Mapping, Sequence

REPO = Path(__file__).resolve().parents[1]
PROBE = REPO / "test" / "ros_probe.py"
LOOPBACK_XML = REPO / "config" / "cyclonedds_loopback.xml"
#: a fresh install compiles the numba kernels before 'ready:' (issue 31 sets the target)
READY_TIMEOUT = 400.0
SETUP_VAR = "GYRO_PLATFORM_ROS_SETUP"
#: what the ament linters check (as ``ros2 pkg create``'s tests do over the package)
LINT_PATHS = [str(REPO / p) for p in ("gyro_platform", "launch", "test", "setup.py")]
HOW = ("ROS 2 Jazzy not found: source /opt/ros/jazzy/setup.bash (or set "
       f"{SETUP_VAR}=/path/to/setup.bash) to run the ROS tests")


def _candidates() -> list[tuple[str, Path | None]]:
    """(where, setup file or None for 'the current environment'), in lookup order."""
    out: list[tuple[str, Path | None]] = []
    if os.environ.get(SETUP_VAR):
        out.append((SETUP_VAR, Path(os.environ[SETUP_VAR])))
    if os.environ.get("ROS_DISTRO") == "jazzy" and shutil.which("ros2"):
        out.append(("sourced environment", None))
    prefix = Path(os.environ.get("ROS2_PREFIX", Path.home() / "ros2-jazzy-ws"))
    for f in (Path("/opt/ros/jazzy/setup.bash"), prefix / "env.sh"):
        if f.is_file():
            out.append((str(f), f))
    return out


def _base_environ() -> dict[str, str]:
    """os.environ without this interpreter's venv (its numpy may not be ROS's)."""
    env = dict(os.environ)
    venv = os.environ.get("VIRTUAL_ENV") or (sys.prefix if sys.prefix != sys.base_prefix else "")
    if venv:
        env.pop("VIRTUAL_ENV", None)
        bin_dir = str(Path(venv) / "bin")
        env["PATH"] = os.pathsep.join(p for p in env.get("PATH", "").split(os.pathsep) if p != bin_dir)
    bin_dir = str(Path(sys.executable).parent)
    if sys.prefix != sys.base_prefix:
        env["PATH"] = os.pathsep.join(p for p in env["PATH"].split(os.pathsep) if p != bin_dir)
    return env


@dataclass
class RosEnv:
    """The environment of a sourced ROS 2 Jazzy: ``run`` and ``start`` commands in it."""

    where: str
    environ: dict[str, str]
    python: str

    def env(self, domain: int | None = None, **extra: str) -> dict[str, str]:
        """This environment, on ``domain`` (ROS_DOMAIN_ID) and loopback-only DDS."""
        env = dict(self.environ)
        env.setdefault("RMW_IMPLEMENTATION", "rmw_cyclonedds_cpp")
        env["CYCLONEDDS_URI"] = LOOPBACK_XML.as_uri()
        env["PYTHONUNBUFFERED"] = "1"
        env["RCUTILS_COLORIZED_OUTPUT"] = "0"
        if domain is not None:
            env["ROS_DOMAIN_ID"] = str(domain)
        env.update(extra)
        return env

    def run(self, cmd: str | Sequence[str], *, domain: int | None = None, timeout: float = 120.0,
            cwd: Path | str | None = None, check: bool = False, env: Mapping[str, str] | None = None,
            ) -> subprocess.CompletedProcess:
        """Run ``cmd`` (argv, or a bash line) to its end; stdout and stderr captured as text."""
        argv = ["bash", "-c", cmd] if isinstance(cmd, str) else list(cmd)
        p = subprocess.run(argv, env={**self.env(domain), **(env or {})}, cwd=cwd, capture_output=True,
                           text=True, timeout=timeout)
        if check and p.returncode != 0:
            raise AssertionError(f"{cmd!r} exited {p.returncode}:\n{p.stdout[-3000:]}\n{p.stderr[-3000:]}")
        return p

    def start(self, cmd: str | Sequence[str], *, domain: int | None = None, cwd: Path | str | None = None,
              env: Mapping[str, str] | None = None) -> "Proc":
        """Start ``cmd`` in its own process group; output collected by a thread."""
        argv = ["bash", "-c", f"exec {cmd}"] if isinstance(cmd, str) else list(cmd)
        p = subprocess.Popen(argv, env={**self.env(domain), **(env or {})}, cwd=cwd, stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT, text=True, start_new_session=True)
        return Proc(p)

    def probe(self, spec: Mapping, *, domain: int, timeout: float = 120.0) -> dict:
        """Run test/ros_probe.py (rclpy, in ROS's python) with ``spec``; its JSON report."""
        p = self.run([self.python, str(PROBE), json.dumps(spec)], domain=domain, timeout=timeout)
        if p.returncode != 0:
            raise AssertionError(f"ros_probe exited {p.returncode}:\n{p.stdout[-3000:]}\n{p.stderr[-3000:]}")
        return json.loads(p.stdout.strip().splitlines()[-1])


@dataclass
class Proc:
    """A started process (own process group) whose output a thread collects."""

    popen: subprocess.Popen
    lines: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        for line in self.popen.stdout:
            self.lines.append(line)

    @property
    def output(self) -> str:
        return "".join(self.lines)

    def wait_for(self, text: str, timeout: float) -> bool:
        """True once ``text`` appears in the output; False at timeout or when the process ends."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if text in self.output:
                return True
            if self.popen.poll() is not None:
                self._thread.join(2.0)
                return text in self.output
            time.sleep(0.05)
        return False

    def stop(self, sig: int = signal.SIGINT, timeout: float = 20.0) -> int:
        """Send ``sig`` to the process group, wait; SIGKILL after ``timeout``. The exit code."""
        if self.popen.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.popen.pid, sig)
            try:
                self.popen.wait(timeout)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(self.popen.pid, signal.SIGKILL)
                self.popen.wait(10)
        with contextlib.suppress(ProcessLookupError):     # stragglers of the group
            os.killpg(self.popen.pid, signal.SIGKILL)
        self._thread.join(5.0)
        return self.popen.returncode


@functools.lru_cache(maxsize=1)
def find() -> tuple[RosEnv | None, str]:
    """The ROS 2 Jazzy environment, or (None, why not)."""
    tried = []
    for where, setup in _candidates():
        if setup is None:
            environ = dict(os.environ)
        else:
            p = subprocess.run(["bash", "-c", 'source "$0" >/dev/null 2>&1; env -0', str(setup)],
                               env=_base_environ(), capture_output=True, timeout=60)
            if p.returncode != 0:
                tried.append(f"{where}: sourcing failed")
                continue
            environ = dict(kv.split("=", 1) for kv in p.stdout.decode().split("\0") if "=" in kv)
        python = shutil.which("python3", path=environ.get("PATH")) or "python3"
        check = subprocess.run([python, "-c", "import rclpy, sensor_msgs.msg, launch_ros, tf2_ros"],
                               env=environ, capture_output=True, text=True, timeout=60)
        if check.returncode != 0 or not shutil.which("ros2", path=environ.get("PATH")):
            last = (check.stderr.strip().splitlines() or ["ros2 not on PATH"])[-1]
            tried.append(f"{where}: {last}")
            continue
        return RosEnv(where, environ, python), ""
    return None, HOW + (f' (tried: {"; ".join(tried)})' if tried else "")


@dataclass
class Workspace:
    """A colcon workspace in a temporary folder with this package in ``src/`` (a symlink)."""

    root: Path
    ros: RosEnv
    symlink_install: bool
    build_log: str = ""

    @classmethod
    def build(cls, ros: RosEnv, root: Path, *, symlink_install: bool) -> "Workspace":
        (root / "src").mkdir(parents=True, exist_ok=True)
        link = root / "src" / "gyro_platform"
        if not link.exists():
            link.symlink_to(REPO, target_is_directory=True)
        flags = " --symlink-install" if symlink_install else ""
        p = ros.run(f"colcon build --packages-select gyro_platform{flags} --event-handlers console_direct+",
                    cwd=root, timeout=600)
        ws = cls(root, ros, symlink_install, p.stdout + p.stderr)
        if p.returncode != 0:
            raise AssertionError(f"colcon build{flags} exited {p.returncode}:\n{ws.build_log[-4000:]}")
        return ws

    @property
    def share(self) -> Path:
        return self.root / "install" / "gyro_platform" / "share" / "gyro_platform"

    def sourced(self, cmd: str) -> str:
        """``cmd`` with this workspace's overlay sourced."""
        return f"source {self.root}/install/setup.bash && {cmd}"

    def run(self, cmd: str, **kw) -> subprocess.CompletedProcess:
        return self.ros.run(self.sourced(cmd), **kw)

    def start(self, cmd: str, **kw) -> Proc:
        return self.ros.start(["bash", "-c", self.sourced(f"exec {cmd}")], **kw)


_LOCK_DIR = Path(tempfile.gettempdir()) / "gyro_platform_ros_domains"


@contextlib.contextmanager
def domain_lock(first: int = 102, last: int = 200) -> Iterator[int]:
    """A ROS_DOMAIN_ID in [first, last] held (flock) by no other test on this machine."""
    _LOCK_DIR.mkdir(exist_ok=True)
    start = os.getpid() % (last - first + 1)
    for k in range(last - first + 1):
        d = first + (start + k) % (last - first + 1)
        f = open(_LOCK_DIR / f"{d}.lock", "w")
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            f.close()
            continue
        try:
            yield d
        finally:
            f.close()
        return
    raise RuntimeError(f"no free ROS_DOMAIN_ID in [{first}, {last}]")
