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

"""The one JSON writer of every file a command leaves (summaries, sweep records, bench results).

Policy: the text is strict JSON (RFC 8259), which any parser reads:

* a non-finite number (NaN: a figure that could not be made, such as σ of one run; ±Inf) is
  ``null`` — Python's ``json`` would write ``NaN`` / ``Infinity``, which is JavaScript, not JSON;
* numpy scalars and arrays become Python numbers and lists (``bool_`` a boolean), tuples lists;
* a key that is no string becomes the JSON text of its value (``1`` → ``"1"``, ``True`` →
  ``"true"``), as ``json`` does with the keys it accepts;
* anything else (a path, an enum) is written as its ``str``.

The conversion is done before ``json.dumps`` (``allow_nan=False``: a non-finite number that
got past it is a bug and raises ``ValueError``). A leaf: the standard library only; numpy values
are recognised by their ``tolist`` method.
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any


def plain_json(x: Any) -> Any:
    """``x`` as Python values that strict JSON holds (the policy above)."""
    if isinstance(x, float):                # float and numpy.float64
        return float(x) if math.isfinite(x) else None
    if x is None or isinstance(x, (str, bool, int)):
        return x
    if isinstance(x, dict):
        return {_key(k): plain_json(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [plain_json(v) for v in x]
    if callable(getattr(x, "tolist", None)):    # numpy scalars and arrays
        return plain_json(x.tolist())
    return str(x)


def _key(k: Any) -> str:
    """A dict key as a JSON object key (a string)."""
    if isinstance(k, str):
        return k
    v = plain_json(k)
    return v if isinstance(v, str) else json.dumps(v)


def dumps_strict(obj: Any, indent: int | None = None) -> str:
    """Strict JSON text of ``obj`` (:func:`plain_json`: non-finite numbers as ``null``, numpy
    values as Python ones, other objects by ``str``)."""
    return json.dumps(plain_json(obj), indent=indent, allow_nan=False)


def write_json(path: Any, obj: Any, indent: int | None = 2) -> Path:
    """``obj`` as strict JSON (:func:`dumps_strict`) in the file ``path`` (ending in a newline;
    its folder made); the path."""
    path = Path(path)
    text = dumps_strict(obj, indent) + "\n"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


__all__ = ["plain_json", "dumps_strict", "write_json"]
