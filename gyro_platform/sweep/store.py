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

"""The sweep's output folder: crash-safe run records and the results table.

Layout of ``OUT/``::

    sweep.json            what this folder holds (sweep file, fingerprint); a different sweep is refused
    runs/run_000042.json  one record per run, written atomically (temporary file, fsync, rename):
                          a kill leaves every record whole or absent, never half written
    results.parquet       the table of all records (one row per run), rebuilt from runs/
    results.csv           the same table as CSV
    budget.png            the plots (see ``plots``)

    .lock                 held (``fcntl.flock``) by the sweep writing here: a second sweep into the
                          folder is refused; the kernel drops it when its holder dies (SIGKILL too)

A re-run into the same folder skips the runs whose record is finished (``ok``, ``refused``,
``failed_input``); ``failed`` and ``lost`` runs run again, and so do runs whose record file is
damaged (truncated, not JSON, JSON that is not that run's record): ``ResultStore.damaged`` names
them. Every file is written under a unique temporary name beside it (``replacing``) and renamed
over it; a write that fails (disk full) removes its temporary and raises ``OutputError`` naming
the file.
"""
from __future__ import annotations

from contextlib import contextmanager
import fcntl
import json
import math
import os
from pathlib import Path
import re
from typing import Any, Iterator
import uuid

from .runs import figure_columns, FINISHED, STATUSES
from ..errors import OutputError
from ..filesystem import write_failure
from ..reports.jsonio import dumps_strict

RECORD_NAME = re.compile(r"run_(\d+)\.json")


class StoreError(ValueError):
    """The output folder cannot take this sweep (another sweep's folder, another sweep writing
    into it now, not writable)."""


@contextmanager
def replacing(path: Path, suffix: str = ".tmp") -> Iterator[Path]:
    """A new, unique temporary file beside ``path`` (created with ``O_EXCL`` under a random name:
    two writers never share one; mode 0666 less the umask, as ``open`` makes files) for the
    block to write; renamed over ``path`` when the block ends (readers see the old file or the
    whole new one), removed when it fails. A write failure (disk full, file size limit, I/O
    error) becomes ``OutputError`` naming ``path`` in one line."""
    path = Path(path)
    while True:
        name = str(path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:12]}{suffix}"))
        try:
            os.close(os.open(name, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
            break
        except FileExistsError:
            continue
        except OSError as e:
            raise OutputError(f"{path}: {e.strerror or e}") from e
    try:
        yield Path(name)
        os.replace(name, path)
    except BaseException as e:
        try:
            os.unlink(name)
        except OSError:
            pass
        why = None if isinstance(e, OutputError) else write_failure(e)
        if why is None:
            raise
        if isinstance(e, OSError):              # the temporary's name would only confuse
            why = e.strerror or " ".join(str(e).split())
        raise OutputError(f"{path}: {why}") from e


def atomic_write(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` so that readers see the old file or the whole new one."""
    with replacing(path) as tmp, open(tmp, "wb") as fh:
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())


class SweepLock:
    """``OUT/.lock`` held with ``fcntl.flock`` (exclusive, not waiting) for as long as a sweep
    writes into ``OUT``: a second sweep into the folder gets StoreError. The kernel drops the
    lock when the holder's file closes, so a SIGKILLed sweep leaves no stale lock (the file
    stays, unlocked). Re-entrant within a process (``run_sweep`` inside the command's hold)."""

    held: dict[str, list] = {}          # resolved lock path -> [fd, depth]

    def __init__(self, out: Path):
        self.path = Path(out) / ".lock"

    def __enter__(self) -> "SweepLock":
        self.path.parent.mkdir(parents=True, exist_ok=True)
        key = str(self.path.resolve())
        if key in SweepLock.held:
            SweepLock.held[key][1] += 1
            return self
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 64, 0).decode(errors="replace").strip()
            os.close(fd)
            raise StoreError(f"{self.path.parent}: another sweep is writing into this folder now "
                             f"({holder or 'pid unknown'}, holding {self.path}); wait for it to end or "
                             "choose another --out") from None
        except OSError as e:
            os.close(fd)
            raise StoreError(f"cannot lock {self.path}: {e.strerror or e}") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"pid {os.getpid()}".encode(), 0)
        SweepLock.held[key] = [fd, 1]
        return self

    def __exit__(self, *exc) -> None:
        key = str(self.path.resolve())
        entry = SweepLock.held[key]
        entry[1] -= 1
        if entry[1] == 0:
            del SweepLock.held[key]
            os.close(entry[0])              # releases the flock


def record_problem(rec: Any, run: int) -> str | None:
    """Why ``rec`` (parsed JSON from ``run_{run:06d}.json``) is not that run's record, or None."""
    if not isinstance(rec, dict):
        return f"JSON {type(rec).__name__ if rec is not None else 'null'}, not a run record"
    r = rec.get("run")
    if isinstance(r, bool) or not isinstance(r, int):
        return "not a run record (no integer 'run')"
    if r != run:
        return f"holds run {r}, not run {run}"
    if rec.get("status") not in STATUSES:
        return f"not a run record (status {rec.get('status')!r})"
    return None


def json_bytes(obj: Any, indent: int | None = None) -> bytes:
    """Strict JSON of ``obj`` as UTF-8 (``reports.jsonio.dumps_strict``: a non-finite number —
    a figure that could not be made, σ of one run — is ``null``, numpy values Python ones,
    other objects — paths — by ``str``)."""
    return dumps_strict(obj, indent).encode()


class ResultStore:
    """Run records of one sweep in ``out``; the records are the truth, the table is derived."""

    def __init__(self, out: Path, fingerprint: str, description: dict[str, Any]):
        self.out = Path(out)
        self.runs_dir = self.out / "runs"
        self.fingerprint = fingerprint
        self.description = description
        self.damaged: dict[Path, str] = {}      # record files that are no record -> why (``records``)

    def open(self) -> "ResultStore":
        """Create the folder, or check that it holds this same sweep (call under SweepLock)."""
        meta = self.out / "sweep.json"
        try:
            if meta.is_file():
                have = json.loads(meta.read_text())
                if not isinstance(have, dict):
                    raise StoreError(f"{meta}: damaged (JSON {type(have).__name__}, not a sweep description); "
                                     "remove it to use this folder for this sweep")
                have = have.get("fingerprint")
                if have != self.fingerprint:
                    raise StoreError(f"{self.out} holds another sweep (fingerprint {have}, this one "
                                     f"{self.fingerprint}); choose another --out")
            self.runs_dir.mkdir(parents=True, exist_ok=True)
            atomic_write(meta, json_bytes({"fingerprint": self.fingerprint, **self.description}, indent=2))
        except (OSError, json.JSONDecodeError) as e:
            raise StoreError(f"cannot use {self.out}: {getattr(e, 'strerror', None) or e}") from None
        except UnicodeDecodeError:
            raise StoreError(f"{meta}: damaged (not text); remove it to use this folder for this sweep") from None
        return self

    def _path(self, run: int) -> Path:
        return self.runs_dir / f"run_{run:06d}.json"

    def put(self, record: dict[str, Any]) -> None:
        atomic_write(self._path(int(record["run"])), json_bytes(record))

    def records(self) -> list[dict[str, Any]]:
        """Every whole record, by run index. A record file that is none (truncated, not JSON,
        JSON that is not its run's record) is left out and named in ``damaged``: its run counts
        as not finished, so it runs again and its file is replaced."""
        out, self.damaged = [], {}
        for p in sorted(self.runs_dir.glob("run_*.json")):
            m = RECORD_NAME.fullmatch(p.name)
            if m is None:
                continue
            try:
                rec = json.loads(p.read_bytes())
            except OSError as e:
                self.damaged[p] = f"unreadable: {e.strerror or e}"
                continue
            except ValueError as e:         # JSONDecodeError, UnicodeDecodeError: truncated, not text
                self.damaged[p] = "not JSON (truncated?): " + " ".join(str(e).split())
                continue
            why = record_problem(rec, int(m.group(1)))
            if why is None:
                out.append(rec)
            else:
                self.damaged[p] = why
        return sorted(out, key=lambda r: r["run"])

    def finished(self) -> set[int]:
        return {r["run"] for r in self.records() if r.get("status") in FINISHED}

    def columns(self, records: list[dict[str, Any]]) -> list[str]:
        params = sorted({k for r in records for k in r if k.startswith("param:")})
        return ["run", "status", "message", "bag", *params, *figure_columns()]

    def write_table(self, records: list[dict[str, Any]] | None = None) -> tuple[Path, Path]:
        """Write ``results.parquet`` and ``results.csv`` (atomically) from the records."""
        import pyarrow as pa
        import pyarrow.csv as pacsv
        import pyarrow.parquet as pq

        records = self.records() if records is None else records
        cols = self.columns(records)
        text = {"status", "message", "bag"}
        arrays = {}
        for c in cols:
            vals = [r.get(c) for r in records]
            if c in text:
                arrays[c] = pa.array(["" if v is None else str(v) for v in vals], pa.string())
            elif c == "run":
                arrays[c] = pa.array(vals, pa.int64())
            else:
                arrays[c] = pa.array([math.nan if v is None else float(v) for v in vals], pa.float64())
        table = pa.table(arrays)
        parquet, csv = self.out / "results.parquet", self.out / "results.csv"
        for path, write in ((parquet, lambda p: pq.write_table(table, p)),
                            (csv, lambda p: pacsv.write_csv(table, p))):
            with replacing(path) as tmp:
                write(str(tmp))
        return parquet, csv
