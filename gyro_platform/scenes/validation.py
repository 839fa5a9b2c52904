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

"""Validation of a scene file's values: :class:`Validator` checks mappings, numbers, integers,
strings, choices and vectors and raises :class:`ScenarioError` naming the file and the key path
(``scene 'x.yaml': motion.bank_deg: expected a number``); :func:`join_path` builds those paths,
:func:`type_name` names what was found, :func:`param_value` checks a parameter override."""
from __future__ import annotations

import math
from typing import Any, Iterable

import numpy as np

from .scene_yaml import as_float


class ScenarioError(ValueError):
    """A scene file is invalid; the message names the file and the key path."""


class Validator:
    """Checks of the values read from the scene file ``source``: each returns the value (converted)
    or raises ScenarioError naming the file, the key path and what was expected."""

    def __init__(self, source: str):
        self.source = source

    def fail(self, path: str, msg: str):
        where = f"{path}: " if path else ""
        raise ScenarioError(f"scene '{self.source}': {where}{msg}")

    def mapping(self, v, path: str, allowed: Iterable[str], required: Iterable[str] = ()) -> dict:
        if not isinstance(v, dict):
            self.fail(path, f"expected a mapping, got {type_name(v)}")
        allowed = tuple(allowed)
        for k in v:
            if not isinstance(k, str):
                self.fail(path, f"keys must be strings, got {k!r}")
            if k not in allowed:
                self.fail(join_path(path, k), f"unknown key (allowed: {', '.join(allowed)})")
        for k in required:
            if k not in v or v[k] is None:
                self.fail(join_path(path, k), "required key is missing")
        return v

    def number(self, v, path: str, lo: float | None = None, hi: float | None = None,
               lo_open: bool = False) -> float:
        x = as_float(v)
        if x is None:
            self.fail(path, f"expected a number, got {type_name(v)} {v!r}")
        if not math.isfinite(x):
            self.fail(path, f"expected a finite number, got {v!r}")
        if lo is not None and (x <= lo if lo_open else x < lo):
            self.fail(path, f"must be {'>' if lo_open else '≥'} {lo:g}, got {x:g}")
        if hi is not None and x > hi:
            self.fail(path, f"must be ≤ {hi:g}, got {x:g}")
        return x

    def integer(self, v, path: str, lo: int | None = None, hi: int | None = None) -> int:
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
            self.fail(path, f"expected an integer, got {type_name(v)} {v!r}")
        if lo is not None and v < lo:
            self.fail(path, f"must be ≥ {lo}, got {v}")
        if hi is not None and v > hi:
            self.fail(path, f"must be ≤ {hi}, got {v}")
        return int(v)

    def string(self, v, path: str) -> str:
        if not isinstance(v, str):
            self.fail(path, f"expected a string, got {type_name(v)} {v!r}")
        return v

    def choice(self, v, path: str, allowed: Iterable[str]) -> str:
        allowed = tuple(allowed)
        if not isinstance(v, str) or v not in allowed:
            self.fail(path, f"expected one of {', '.join(allowed)}, got {v!r}")
        return v

    def vector(self, v, path: str, n: int = 3) -> np.ndarray:
        if not isinstance(v, (list, tuple)) or len(v) != n:
            self.fail(path, f"expected a list of {n} numbers, got {type_name(v)} {v!r}")
        return np.array([self.number(x, f"{path}[{i}]") for i, x in enumerate(v)])

    def scalar_or_vector(self, v, path: str, n: int = 3, lo: float | None = None) -> np.ndarray:
        if isinstance(v, (list, tuple)):
            arr = self.vector(v, path, n)
            for i, x in enumerate(arr):
                if lo is not None and x < lo:
                    self.fail(f"{path}[{i}]", f"must be ≥ {lo:g}, got {x:g}")
            return arr
        return np.full(n, self.number(v, path, lo=lo))


def param_value(v: Validator, val: Any, path: str) -> Any:
    """A parameter override: a number or a flat list of numbers (no booleans, no nesting)."""
    if isinstance(val, (list, tuple)):
        return [v.number(x, f"{path}[{i}]") for i, x in enumerate(val)]
    return v.number(val, path)


def join_path(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


def type_name(v) -> str:
    return {dict: "a mapping", list: "a list", str: "a string", bool: "a boolean",
            type(None): "nothing"}.get(type(v), type(v).__name__)


__all__ = ["ScenarioError", "Validator", "param_value", "join_path", "type_name"]
