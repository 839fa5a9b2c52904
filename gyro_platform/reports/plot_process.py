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

"""A helper process that draws a command's plot (``Recorder.plot``).

Importing matplotlib takes ~0.75 s on a 2 GHz core, about a fifth of a whole ``replay`` or
``run`` command. :func:`start`, called when the command begins, starts ``python -m
gyro_platform.reports.plot_process``: it imports matplotlib on another core while this process
starts up and simulates, then waits for one job on its stdin. :func:`draw` sends it the
figure's series (``recording.PlotData``, arrays of ~1 MB: not the recorder's objects, whose
pickling would cost more than the import), the path, the title and the summary, and waits
until the PNG is written. Whatever goes wrong with the helper (it could not start, died, was
killed, timed out, could not unpickle the job, failed to draw), :func:`draw` draws in this
process instead, as without a helper: the plot never depends on it. The helper ignores SIGINT
(a Ctrl-C stops the command in order, which then still plots), exits at the end of its
stdin (the command ended without a plot), and once its plot is written exits at once
(``signals.exit_now``: no interpreter teardown for the command to wait for). May import
``recording``, ``filesystem`` and ``signals`` only.
"""
from __future__ import annotations

import atexit
from pathlib import Path
import pickle
import subprocess
import sys
from typing import Any

from ..filesystem import child_env
from ..signals import exit_now

#: the longest wait for the helper's plot (s), after which it is killed and this process draws
TIMEOUT_S = 120.0

_helper: subprocess.Popen | None = None


def start() -> None:
    """Start this process's helper (once; nothing when it cannot be started)."""
    global _helper
    if _helper is not None:
        return
    try:
        _helper = subprocess.Popen([sys.executable, "-m", "gyro_platform.reports.plot_process"], stdin=subprocess.PIPE,
                                   stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=child_env())
    except (OSError, ValueError):
        _helper = None
        return
    atexit.register(stop)


def stop() -> None:
    """End the helper if it is still there (its job not sent)."""
    global _helper
    helper, _helper = _helper, None
    if helper is not None and helper.poll() is None:
        helper.kill()
        helper.wait()


def draw(rec: Any, path: Any, title: str | None = None, summary: dict | None = None) -> Path:
    """``recording.save_plot(rec.plot_data(), path, title, summary)`` (``rec``: a
    ``recording.Recorder`` or anything with ``plot_data()``; ``summary`` by default
    ``rec.summary()``): by the helper when one was started and it draws it, else here (the
    same figure; the same errors raised)."""
    global _helper
    helper, _helper = _helper, None
    if summary is None:
        summary = rec.summary()
    data = rec.plot_data()
    if helper is not None:
        try:
            job = pickle.dumps((data, str(path), title, summary), protocol=pickle.HIGHEST_PROTOCOL)
            reply, _ = helper.communicate(job, timeout=TIMEOUT_S)
            if helper.returncode == 0 and reply == b"ok\n":
                return Path(path)
        except (OSError, ValueError, pickle.PicklingError, subprocess.TimeoutExpired):
            pass
        finally:
            if helper.poll() is None:
                helper.kill()
                helper.wait()
    from .recording import save_plot

    return save_plot(data, path, title, summary)


def _main() -> int:
    """The helper: matplotlib imported first, then one job from stdin."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    import matplotlib.backends.backend_agg  # noqa: F401  (the slow import, done while waiting)
    import matplotlib.figure  # noqa: F401
    import matplotlib.ticker  # noqa: F401

    from .recording import save_plot

    try:
        data, path, title, summary = pickle.load(sys.stdin.buffer)
    except EOFError:
        return 0                                # the command ended without a plot
    save_plot(data, path, title, summary)
    sys.stdout.write("ok\n")
    # the PNG is written and closed: no teardown of matplotlib and NumPy (~0.1 s that the
    # command would wait for at its end)
    exit_now(0)


if __name__ == "__main__":
    sys.exit(_main())
