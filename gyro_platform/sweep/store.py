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

A re-run into the same folder skips the runs whose record is finished (``ok``, ``refused``,
``failed_input``); ``failed`` and ``lost`` runs run again.
"""
from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

from .runs import figure_columns, FINISHED


class StoreError(ValueError):
    """The output folder cannot take this sweep (another sweep's folder, not writable)."""


def atomic_write(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` so that readers see the old file or the whole new one."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    with open(tmp, "wb") as fh:
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)


def _finite(x: Any) -> Any:
    """``x`` with every non-finite float (NaN: a figure that could not be made, σ of one run)
    replaced by None, so that the text is strict JSON (``null``), not JavaScript's ``NaN``."""
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite(v) for v in x]
    if hasattr(x, "tolist"):                # numpy scalars and arrays
        return _finite(x.tolist())
    return x


def json_bytes(obj: Any, indent: int | None = None) -> bytes:
    """Strict JSON of ``obj`` (non-finite numbers as ``null``, numpy values as Python ones,
    other objects — paths — by ``str``)."""
    return json.dumps(_finite(obj), indent=indent, default=str, allow_nan=False).encode()


class ResultStore:
    """Run records of one sweep in ``out``; the records are the truth, the table is derived."""

    def __init__(self, out: Path, fingerprint: str, description: dict[str, Any]):
        self.out = Path(out)
        self.runs_dir = self.out / "runs"
        self.fingerprint = fingerprint
        self.description = description

    def open(self) -> "ResultStore":
        """Create the folder, or check that it holds this same sweep."""
        meta = self.out / "sweep.json"
        try:
            if meta.is_file():
                have = json.loads(meta.read_text()).get("fingerprint")
                if have != self.fingerprint:
                    raise StoreError(f"{self.out} holds another sweep (fingerprint {have}, this one "
                                     f"{self.fingerprint}); choose another --out")
            self.runs_dir.mkdir(parents=True, exist_ok=True)
            atomic_write(meta, json.dumps({"fingerprint": self.fingerprint, **self.description},
                                          indent=2, default=str).encode())
        except (OSError, json.JSONDecodeError) as e:
            raise StoreError(f"cannot use {self.out}: {getattr(e, 'strerror', None) or e}") from None
        return self

    def _path(self, run: int) -> Path:
        return self.runs_dir / f"run_{run:06d}.json"

    def put(self, record: dict[str, Any]) -> None:
        atomic_write(self._path(int(record["run"])), json_bytes(record))

    def records(self) -> list[dict[str, Any]]:
        """Every whole record, by run index (unreadable leftovers are ignored)."""
        out = []
        for p in sorted(self.runs_dir.glob("run_*.json")):
            try:
                out.append(json.loads(p.read_text()))
            except (OSError, json.JSONDecodeError):
                continue
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
            tmp = path.with_name(f".{path.name}.tmp")
            write(str(tmp))
            os.replace(tmp, path)
        return parquet, csv
