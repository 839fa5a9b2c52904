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

"""Output paths: :func:`check_output_path` refuses an unwritable output before a run, and
:func:`write_failure` says which write errors are the disk's (full, read-only, size limit), not a
bug; :func:`child_env`: the environment of a child ``python -m gyro_platform…`` that imports this
very package. A leaf room: imports ``errors`` and the standard library."""
import errno
import os
from pathlib import Path
import sqlite3
import tempfile

from .errors import OutputError

#: the folder holding the gyro_platform package (a source tree or site-packages)
PACKAGE_PARENT = Path(__file__).resolve().parents[1]


def child_env(**extra: str) -> dict[str, str]:
    """This process's environment with ``extra`` set and the folder holding this package first
    on ``PYTHONPATH``: a child ``python -m gyro_platform…`` (the plot helper, the second compile
    process, the benches' whole commands) imports this package, not another installed one."""
    env = dict(os.environ, **extra)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(PACKAGE_PARENT), env.get("PYTHONPATH")]))
    return env


#: OSError numbers of a write that cannot succeed (not a bug, not the input)
WRITE_ERRNOS = frozenset({errno.ENOSPC, errno.EFBIG, errno.EDQUOT, errno.EROFS, errno.EIO, errno.EACCES,
                          errno.EPERM, errno.ENOTDIR, errno.EISDIR, errno.EEXIST})


def write_failure(exc: BaseException) -> str | None:
    """One line for an exception raised while writing outputs, None if it is not a write
    failure: ``OSError`` of ``WRITE_ERRNOS`` (disk full ``ENOSPC``, file size limit ``EFBIG``,
    read-only, I/O error …) and SQLite's "database or disk is full" / "disk I/O error"."""
    if isinstance(exc, OutputError):
        return str(exc)
    if isinstance(exc, OSError) and exc.errno in WRITE_ERRNOS:
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        return f"{where}{exc.strerror or exc}"
    if isinstance(exc, sqlite3.Error) or type(exc).__module__ == "apsw":     # either SQLite binding
        text = str(exc)
        if any(w in text for w in ("full", "disk", "I/O", "readonly", "unable to open")):
            return f"SQLite: {text}"
    cause = exc.__cause__ or exc.__context__
    if cause is not None and cause is not exc:
        inner = write_failure(cause)
        if inner is not None:
            return inner
    return None


def _nearest_existing(path: Path) -> Path:
    p = path
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def _probe_folder(folder: Path, flag: str, path: Path) -> None:
    """A folder can take new files: make and remove a temporary file there."""
    if not folder.is_dir():
        raise OutputError(f"{flag} {path}: {folder} is a file, not a folder")
    try:
        fd, name = tempfile.mkstemp(prefix=".gyro-write-probe-", dir=folder)
        os.close(fd)
        os.unlink(name)
    except OSError as e:
        raise OutputError(f"{flag} {path}: cannot write in {folder}: {e.strerror or e}") from None


def check_output_path(path, flag: str = "--out", *, new: bool = False,
                      files: tuple[str, ...] = (), siblings: tuple = ()) -> None:
    """Refuse an output path that cannot be written, before anything runs (OutputError, one line).

    ``path``: the output folder (``new``: it must not exist, e.g. a bag); ``files``: names the
    command will write inside it (they must not be folders); ``siblings``: further paths it will
    write next to it (``OUT.summary.json``): not folders, writable if they exist. The nearest
    existing folder on the way is probed by creating and removing a temporary file (read-only
    file systems, permissions, a path under a file)."""
    path = Path(path)
    if new and (path.exists() or path.is_symlink()):
        raise OutputError(f"{flag} {path}: exists already; choose another (nothing is overwritten)")
    if path.exists() and not path.is_dir():
        raise OutputError(f"{flag} {path}: is a file, not a folder")
    _probe_folder(_nearest_existing(path), flag, path)
    for name in files:
        if (path / name).is_dir():
            raise OutputError(f"{flag} {path}: {path / name} is a folder; the command writes a file there")
    for s in map(Path, siblings):
        if s.is_dir():
            raise OutputError(f"{flag} {path}: {s} is a folder; the command writes a file there")
        if s.exists() and not os.access(s, os.W_OK):
            raise OutputError(f"{flag} {path}: {s} exists and cannot be overwritten")
