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

"""Reading a scene file's YAML: PyYAML's safe loader, refusing duplicate keys, errors in one line.

* :func:`load_yaml` — the parsed text; :class:`SceneYAMLError` (one line: ``line L:C: problem``)
  for a syntax error or a key given twice in one mapping (YAML forbids it; PyYAML would keep
  the last silently).
* :func:`as_float` — a value read as a number: PyYAML follows YAML 1.1, which reads ``1e-7`` or
  ``2e6`` (no dot) as strings; scene and sweep files take them as the numbers they are.
"""
from __future__ import annotations

from typing import Any

import numpy as np
import yaml

__all__ = ["SceneYAMLError", "UniqueKeyLoader", "as_float", "load_yaml", "yaml_error_line"]

MERGE_TAG = "tag:yaml.org,2002:merge"


class SceneYAMLError(ValueError):
    """A scene's text is not valid YAML; the message is one line naming line and column."""


class UniqueKeyLoader(yaml.SafeLoader):
    """SafeLoader that refuses a key given twice in one mapping (merge keys ``<<`` may be
    overridden, as YAML allows)."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict:
        first: dict[Any, yaml.Mark] = {}
        for key_node, _ in node.value:
            if key_node.tag == MERGE_TAG:
                continue
            key = self.construct_object(key_node, deep=True)
            try:
                seen = first.setdefault(key, key_node.start_mark)
            except TypeError:            # unhashable: the base constructor says so
                continue
            if seen is not key_node.start_mark:
                raise yaml.constructor.ConstructorError(
                    None, None, f"duplicate key {key!r} (first at {_at(seen)})", key_node.start_mark)
        return super().construct_mapping(node, deep=deep)


def _at(mark: yaml.Mark) -> str:
    """``line L:C`` of a PyYAML mark (1-based)."""
    return f"line {mark.line + 1}:{mark.column + 1}"


def yaml_error_line(e: yaml.YAMLError) -> str:
    """PyYAML's (multi-line) error as one line: ``line L:C: problem (context at line L:C)``."""
    mark = getattr(e, "problem_mark", None)
    if mark is None:
        return " ".join(str(e).split())
    text = f"{_at(mark)}: {getattr(e, 'problem', None) or type(e).__name__}"
    context, cmark = getattr(e, "context", None), getattr(e, "context_mark", None)
    if context:
        text += f" ({context}" + (f" at {_at(cmark)})" if cmark is not None else ")")
    return " ".join(text.split())


def load_yaml(text: str) -> Any:
    """The parsed YAML ``text`` of a scene; SceneYAMLError (one line) if it is not valid YAML
    or repeats a key in one mapping."""
    try:
        return yaml.load(text, Loader=UniqueKeyLoader)   # noqa: S506 - a SafeLoader
    except yaml.YAMLError as e:
        raise SceneYAMLError(yaml_error_line(e)) from None


def as_float(v: Any) -> float | None:
    """``v`` as a float: numbers and numeric strings (YAML 1.1 reads ``1e-7`` as a string); None
    for anything else, booleans included (not checked for finiteness)."""
    if isinstance(v, bool) or v is None:
        return None
    if isinstance(v, (int, float, np.integer, np.floating)):
        return float(v)
    if isinstance(v, str):
        try:
            return float(v.strip())
        except ValueError:
            return None
    return None
