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

"""YAML of a bag's ``metadata.yaml`` and QoS profiles through libyaml: the text ruamel writes
for rosbags' ``Writer`` (sorted keys, block style; tested equal), ~50x faster.

:func:`fast_yaml` swaps ``rosbags.rosbag2.writer.YAML`` (a module global, rosbags internal:
its ``Writer`` has no hook for the dumper) for :class:`LibYaml` while the writer's
``add_connection`` and ``close`` run.
"""
from __future__ import annotations

from contextlib import contextmanager
import re
from typing import Any, Iterator

_PLAIN = re.compile(r"[A-Za-z_/][A-Za-z0-9_/.\-]*")
#: words PyYAML would read back as booleans or null (YAML 1.1): quoted, so not on the fast path
_RESERVED = {w for v in ("yes", "no", "true", "false", "on", "off", "null") for w in (v, v.title(), v.upper())}


def _scalar(v: Any) -> str | None:
    """The plain text PyYAML writes for ``v``, or None where it would quote, fold or format it."""
    if v is None:
        return "null"
    if v is True or v is False:
        return "true" if v else "false"
    if type(v) is int:
        return str(v)
    if type(v) is str:
        if v == "":
            return "''"
        if _PLAIN.fullmatch(v) and v not in _RESERVED:
            return v
    return None


def block_yaml(data: dict) -> str | None:
    """``yaml.dump(data, CSafeDumper, default_flow_style=False, sort_keys=True)`` for a bag's
    metadata made of mappings, lists of scalars or mappings, ints, booleans, None and plain
    names (tested equal); None for anything else (the caller dumps with PyYAML). PyYAML's
    representer walks every node in Python (~12 ms for the metadata of 15 topics)."""
    out: list[str] = []

    def mapping(d: dict, ind: int, first: str | None) -> bool:
        for n, k in enumerate(sorted(d)):
            key = _scalar(k) if type(k) is str else None
            if key is None:
                return False
            head = first if n == 0 and first is not None else " " * ind
            if not value(head + key + ":", d[k], ind):
                return False
        return True

    def value(head: str, v: Any, ind: int) -> bool:
        if isinstance(v, dict) and v:
            out.append(head)
            return mapping(v, ind + 2, None)
        if isinstance(v, list) and v:
            out.append(head)
            for item in v:
                if isinstance(item, dict) and item:
                    if not mapping(item, ind + 2, " " * ind + "- "):
                        return False
                else:
                    text = _scalar(item) if not isinstance(item, (dict, list)) else ("{}" if item == {} else None)
                    if text is None:
                        return False
                    out.append(" " * ind + "- " + text)
            return True
        text = "{}" if v == {} and isinstance(v, dict) else "[]" if v == [] and isinstance(v, list) else _scalar(v)
        if text is None:
            return False
        out.append(head + " " + text)
        return True

    if not isinstance(data, dict) or not data or not mapping(data, 0, None):
        return None
    return "\n".join(out) + "\n"


class LibYaml:
    """Stand-in for ruamel's ``YAML(typ='safe')`` inside rosbags' writer: the same text
    (sorted keys, block style; tested equal) from libyaml, ~50x faster (ruamel takes ~0.3 s to
    dump the metadata of a bag with 16 topics). Texts of small values (a connection's QoS
    profiles, the same for every output topic) are kept: each dump walks PyYAML's Python
    representer (~0.5 ms)."""

    _memo: dict[str, str] = {}
    MEMO_KEY_CHARS = 2000       # values whose repr is longer (the bag's metadata) are not kept

    def __init__(self, typ: str = "safe"):
        self.default_flow_style = False

    def dump(self, data: Any, stream: Any) -> None:
        import yaml

        text = block_yaml(data) if isinstance(data, dict) and not self.default_flow_style else None
        if text is None:
            key = repr(data) + repr(self.default_flow_style)
            small = len(key) <= self.MEMO_KEY_CHARS
            text = self._memo.get(key) if small else None
            if text is None:
                dumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
                text = yaml.dump(data, Dumper=dumper, default_flow_style=self.default_flow_style, sort_keys=True)
                if small and len(self._memo) < 256:
                    self._memo[key] = text
        stream.write(text)


@contextmanager
def fast_yaml() -> Iterator[None]:
    """rosbags' writer module dumping YAML with :class:`LibYaml` for the block's duration."""
    import rosbags.rosbag2.writer as mod

    old, mod.YAML = mod.YAML, LibYaml
    try:
        yield
    finally:
        mod.YAML = old
