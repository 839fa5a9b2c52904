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

"""The one JSON writer (``reports.jsonio``): strict JSON, numpy values converted."""
import json
import math
from pathlib import Path

import numpy as np
import pytest

from gyro_platform.reports.jsonio import dumps_strict, plain_json, write_json
from gyro_platform.reports.recording import Recorder


def _strict(text: str):
    def refuse(c):
        raise AssertionError(f"not strict JSON: {c}")
    return json.loads(text, parse_constant=refuse)


def test_non_finite_numbers_are_null_and_numpy_values_python_ones():
    doc = {"nan": math.nan, "inf": [math.inf, -math.inf], "np": np.float64("nan"), "f32": np.float32(1.5),
           "i": np.int64(3), "b": np.bool_(True), "a": np.array([[1.0, np.inf]]), "t": (1, 2), "p": Path("/x"),
           7: "int key", np.int64(8): "numpy key", None: 0, "nested": {"x": [np.nan]}}
    got = _strict(dumps_strict(doc, indent=2))
    assert got == {"nan": None, "inf": [None, None], "np": None, "f32": 1.5, "i": 3, "b": True, "a": [[1.0, None]],
                   "t": [1, 2], "p": "/x", "7": "int key", "8": "numpy key", "null": 0, "nested": {"x": [None]}}
    assert type(plain_json(np.float64(2.0))) is float and type(plain_json(np.int64(2))) is int


@pytest.mark.parametrize("x", [0.1, 1e-300, -2.5e300, 2 ** 53 + 1, "é", True, None])
def test_finite_values_round_trip(x):
    assert json.loads(dumps_strict({"x": x})) == {"x": x}


def test_write_json_makes_the_folder_and_ends_in_a_newline(tmp_path):
    p = write_json(tmp_path / "a" / "b.json", {"x": math.nan})
    assert p.read_text() == '{\n  "x": null\n}\n'


def test_a_recorder_summary_without_outputs_and_with_nan_is_strict(tmp_path):
    p = Recorder().write_json(tmp_path / "s.json", extra={"scene": {"bad": math.nan}})
    assert _strict(p.read_text()) == {"summary": {"n_outputs": 0}, "scene": {"bad": None}}
