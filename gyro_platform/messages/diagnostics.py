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

"""``/diagnostics``: the DiagnosticArray of the gate, platform, node and transport statuses and
the key/value flattening of nested snapshots (``a.b = v``)."""
from __future__ import annotations

import math
from typing import Any, Iterable, Mapping

import numpy as np

from .names import DIAGNOSTIC_ARRAY, HARDWARE_ID, header, MessageTypes
from ..engine.outputs import Outputs

#: value types that are never a Mapping (spares the slow ABC check on the common values)
_PLAIN = frozenset({float, int, str, bool, type(None)})


def _fmt(v: Any) -> str:
    t = type(v)
    if t is float:
        return repr(v)
    if t is int or t is str:
        return str(v)
    if isinstance(v, (np.floating, np.integer)):
        return repr(v.item())
    if isinstance(v, Mapping):
        return ", ".join(f"{k}={_fmt(x)}" for k, x in v.items()) or "-"
    return str(v)


def key_values(types: MessageTypes, items: Iterable[tuple[str, Any]]) -> list[Any]:
    kv = types["diagnostic_msgs/msg/KeyValue"]
    return [kv(key=str(k), value=_fmt(v)) for k, v in items]


def diagnostic_array(gate: Mapping[str, Any] | None, out: Outputs | None, types: MessageTypes,
                     t_ns: int, extra: Mapping[str, Any] | None = None) -> Any:
    """``diagnostic_msgs/DiagnosticArray`` with status "gyro_platform: input" (the gate
    snapshot: counts by reason, last reason, input rate Hz; WARN when the last input was
    dropped or a frame was taken as identity) and "gyro_platform: platform" (``out.status``
    plus ``extra``; ERROR if a value is not finite, STALE before any output)."""
    status_cls = types["diagnostic_msgs/msg/DiagnosticStatus"]
    statuses = []
    if gate is not None:
        level, message = status_cls.OK, "ok"
        if gate.get("last_action") == "drop":
            level, message = status_cls.WARN, f"last input dropped: {gate.get('last_reason')}"
        elif gate.get("notes", {}).get("identity_frame"):  # counted in the values; not a fault
            message = "ok (input frame without mounting taken as base_link)"
        statuses.append(status_cls(level=level, name="gyro_platform: input", message=message,
                                   hardware_id=HARDWARE_ID, values=key_values(types, flatten(gate))))
    items: list[tuple[str, Any]] = []
    if out is not None:
        items = [("t", out.t), *out.status.items()]
    items += list((extra or {}).items())
    if out is None:
        level, message = status_cls.STALE, "no output yet"
    elif all(math.isfinite(float(v)) for _, v in items if isinstance(v, (int, float, np.number))):
        level, message = status_cls.OK, "ok"
    else:
        level, message = status_cls.ERROR, "non-finite value"
    statuses.append(status_cls(level=level, name="gyro_platform: platform", message=message,
                               hardware_id=HARDWARE_ID, values=key_values(types, items)))
    return types[DIAGNOSTIC_ARRAY](header=header(types, t_ns), status=statuses)


#: name of the transport's own diagnostic status (the same on rclpy and on plain DDS)
TRANSPORT_STATUS = f"{HARDWARE_ID}: transport"


def transport_status(types: MessageTypes, values: Mapping[str, Any], warn: str = "") -> Any:
    """``DiagnosticStatus`` ``gyro_platform: transport`` with the transport's counters; WARN
    with ``warn`` as its message when not empty, else OK."""
    cls = types["diagnostic_msgs/msg/DiagnosticStatus"]
    return cls(level=cls.WARN if warn else cls.OK, name=TRANSPORT_STATUS, message=warn or "ok",
               hardware_id=HARDWARE_ID, values=key_values(types, values.items()))


def flatten(d: Mapping[str, Any], prefix: str = "") -> list[tuple[str, Any]]:
    """Nested mappings as ``(dotted.key, value)`` pairs in order (diagnostics' key/values, params files)."""
    res: list[tuple[str, Any]] = []
    for k, v in d.items():
        if type(v) not in _PLAIN and isinstance(v, Mapping):
            res += flatten(v, f"{prefix}{k}.")
        else:
            res.append((f"{prefix}{k}", v))
    return res
