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

"""The bounds of a row's values are one rule: ``row_verdict``, called by every path of the gate.

On edge values (NaN, ±Inf, exactly ``max_rate`` / ``max_specific_force``, the next float above,
a finite vector whose norm overflows, a missing specific force while it is required, several
rules broken at once) the compiled rule, its Python source, ``TimeGate.offer``,
``TimeGate.offer_plain``, the block pass ``usable_rows`` and ``TimeGate.offer_block`` give the
same verdict, and ``offer`` / ``offer_block`` the same drop reason.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from gyro_platform.messages import Reading
from gyro_platform.messages.blocks import RateBlock
from gyro_platform.pipeline.gate import TimeGate
from gyro_platform.pipeline.gate_kernels import usable_rows
from gyro_platform.pipeline.gate_rules import GateConfig, REASONS, ROW_REASONS, row_verdict

NS = 1_000_000_000
T0 = 1_700_000_000 * NS
NAN, INF = math.nan, math.inf
MAX_RATE, MAX_FORCE = 35.0, 2000.0
ABOVE_RATE = math.nextafter(MAX_RATE, INF)
ABOVE_FORCE = math.nextafter(MAX_FORCE, INF)
G = (0.0, 0.0, 9.81)

#: (omega, specific force or None, require_specific_force, expected reason)
CASES = [
    ((0.1, 0.2, 0.3), G, False, "ok"),
    ((0.1, 0.2, 0.3), None, False, "ok"),
    ((MAX_RATE, 0.0, 0.0), G, False, "ok"),                   # exactly max_rate
    ((0.0, 0.0, -MAX_RATE), G, True, "ok"),
    ((21.0, 28.0, 0.0), G, False, "ok"),                      # sqrt(21² + 28²) == 35 exactly
    ((ABOVE_RATE, 0.0, 0.0), G, False, "over_rate"),          # the next float above
    ((-ABOVE_RATE, 0.0, 0.0), None, False, "over_rate"),
    ((NAN, 0.0, 0.0), G, False, "non_finite"),
    ((0.0, INF, 0.0), G, False, "non_finite"),
    ((0.0, 0.0, -INF), None, False, "non_finite"),
    ((1e200, 0.0, 0.0), G, False, "over_rate"),               # finite, its norm overflows
    ((1e200, 1e200, 1e200), None, True, "over_rate"),
    ((1e-200, 0.0, 0.0), G, False, "ok"),                     # the square underflows
    ((0.1, 0.2, 0.3), (MAX_FORCE, 0.0, 0.0), False, "ok"),
    ((0.1, 0.2, 0.3), (0.0, -ABOVE_FORCE, 0.0), False, "over_specific_force"),
    ((0.1, 0.2, 0.3), (NAN, 0.0, 0.0), False, "non_finite"),
    ((0.1, 0.2, 0.3), (0.0, 0.0, -INF), True, "non_finite"),
    ((0.1, 0.2, 0.3), (1e200, 0.0, 0.0), False, "over_specific_force"),
    ((0.1, 0.2, 0.3), None, True, "no_specific_force"),       # missing while required
    # several rules broken: the first in the gate's order
    ((ABOVE_RATE, 0.0, 0.0), (NAN, 0.0, 0.0), False, "non_finite"),
    ((1e200, 0.0, 0.0), (ABOVE_FORCE, 0.0, 0.0), False, "over_rate"),
    ((NAN, 0.0, 0.0), None, True, "non_finite"),
    ((ABOVE_RATE, 0.0, 0.0), None, True, "over_rate"),
]
IDS = [f"{i}-{c[3]}" for i, c in enumerate(CASES)]


def config(require: bool) -> GateConfig:
    return GateConfig(max_rate=MAX_RATE, max_specific_force=MAX_FORCE, require_specific_force=require)


def verdict_args(w, f, require) -> tuple:
    return (*w, *(f or (0.0, 0.0, 0.0)), f is not None, MAX_RATE, MAX_FORCE, require)


def started_gate(require: bool) -> TimeGate:
    """A gate whose time base is locked (header stamps) by one accepted sample at T0."""
    g = TimeGate(config(require))
    assert g.offer(Reading((0.0, 0.0, 0.0), G, T0, "base_link")).reason == "start"
    return g


@pytest.mark.parametrize("w, f, require, reason", CASES, ids=IDS)
def test_rule_compiled_and_python_agree(w, f, require, reason):
    args = verdict_args(w, f, require)
    assert ROW_REASONS[row_verdict(*args)] == reason
    assert ROW_REASONS[row_verdict.py_func(*args)] == reason        # the same source, not compiled


@pytest.mark.parametrize("w, f, require, reason", CASES, ids=IDS)
def test_offer_and_offer_plain_give_the_rule_s_reason(w, f, require, reason):
    r = Reading(w, f, T0 + NS // 100, "base_link")
    d = started_gate(require).offer(r)
    assert d.reason == reason
    if reason != "ok":
        assert d.detail and d.sample is None
    g = started_gate(require)
    before = (dict(g.counts), g.last_stamp_ns, g.received)
    p = g.offer_plain(r)
    if reason == "ok":
        assert p is not None and p[1] == w and p[2] == f and g.counts["ok"] == 1
    else:                                       # not plain: nothing changed, offer says why
        assert p is None and (dict(g.counts), g.last_stamp_ns, g.received) == before
        assert g.offer(r).reason == reason


@pytest.mark.parametrize("require", [False, True])
def test_block_pass_gives_the_rule_s_reason(require):
    cases = [c for c in CASES if c[2] == require]
    n = len(cases)
    w = np.array([c[0] for c in cases], float)
    has_force = np.array([c[1] is not None for c in cases])
    f = np.array([c[1] if c[1] is not None else (NAN, INF, NAN) for c in cases], float)   # ignored if absent
    usable = usable_rows(w, f, has_force, np.zeros(n, np.int8), MAX_RATE, MAX_FORCE, require)
    assert usable.tolist() == [c[3] == "ok" for c in cases]
    stamps = T0 + NS // 1000 * np.arange(1, n + 1, dtype=np.int64)
    rb = RateBlock(stamps, np.ones(n, bool), ["base_link"] * n, w, f, has_force, np.zeros(n, np.int8), {},
                   np.zeros(n, bool))
    blk = started_gate(require).offer_block(rb)
    assert [REASONS[k] for k in blk.reason] == [c[3] for c in cases]
    ref = started_gate(require)                 # and one offer per row
    assert [ref.offer(Reading(c[0], c[1], int(s), "base_link")).reason for c, s in zip(cases, stamps)] == \
        [c[3] for c in cases]
