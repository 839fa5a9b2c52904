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

"""What a benchmark section writes: its Markdown table printed and saved, its rows as strict JSON
(``reports.jsonio``) with the machine's context (Python, load, CPUs, UTC date), and its plot; and
the text of a replay's CPU ceiling, the same in the consumer table and the headline."""
from __future__ import annotations

from dataclasses import asdict
import os
from pathlib import Path
import sys
import time
from typing import Any, Callable, Sequence

from ..reports.jsonio import write_json


def write_report(stem: str, rows: Sequence[Any], text: str, out_dir: Path,
                 plot: Callable[[Sequence[Any], Path], None], **meta: Any) -> None:
    """``out_dir/{stem}.json``, ``{stem}.md`` and ``{stem}.png``; ``rows`` are dataclasses with a
    ``ratio``; the table is printed first."""
    out_dir.mkdir(parents=True, exist_ok=True)
    print("\n" + text, end="")
    doc = {"meta": {**meta, "python": sys.version.split()[0], "load_avg": os.getloadavg()[0],
                    "cpus": os.cpu_count(), "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())},
           "rows": [{**asdict(r), "ratio": r.ratio} for r in rows]}
    write_json(out_dir / f"{stem}.json", doc, indent=1)
    (out_dir / f"{stem}.md").write_text(text)
    plot(rows, out_dir / f"{stem}.png")
    print(f"wrote {out_dir / f'{stem}.json'}, {out_dir / f'{stem}.md'}, {out_dir / f'{stem}.png'}")


def cpu_ceiling_text(extra: dict[str, Any]) -> str:
    """What a replay's CPU allows (``extra`` of a consumer row: ``cpu_s``, ``cpu_ceiling_rtf``,
    ``cpus``; ``consumer.cpu_ceiling``): 'CPU 0.60 s: ≤ ×400 on 2 CPUs', or '' without them."""
    if extra.get("cpu_ceiling_rtf") is None:
        return ""
    return f"CPU {extra['cpu_s']:.2f} s: ≤ ×{extra['cpu_ceiling_rtf']:.3g} on {extra['cpus']} CPUs"
