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

"""The package layout stays as the README's architecture section draws it.

Rooms import only downwards (``cli`` → ``ros`` → … → ``physics``), no module imports a private
name of another module, every room says in its docstring what it holds and may import, and no
module grows much past ~700 lines. Read from the source with ``ast``: nothing is imported.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / "gyro_platform"

#: room -> rooms it may import (besides itself). ``errors`` is the shared leaf.
ALLOWED: dict[str, set[str]] = {
    "errors": set(),
    "signals": {"errors"},
    "filesystem": {"errors"},
    "physics": {"errors", "signals"},
    "engine": {"physics", "errors"},
    "messages": {"physics", "engine.inputs", "engine.outputs", "errors"},
    "bags": {"messages", "physics", "errors", "signals", "filesystem"},
    "reports": {"messages", "engine.outputs", "errors", "filesystem"},
    "pipeline": {"bags", "messages", "engine", "physics", "errors", "signals"},
    "scenes": {"pipeline", "bags", "messages", "reports", "engine", "physics", "errors", "signals", "filesystem"},
    "replay": {"pipeline", "scenes", "bags", "messages", "reports", "engine", "physics", "errors", "signals",
               "filesystem"},
    "sweep": {"replay", "pipeline", "scenes", "bags", "messages", "reports", "engine", "physics", "errors", "signals",
              "filesystem"},
    "bench": {"sweep", "replay", "pipeline", "scenes", "bags", "messages", "reports", "engine", "physics", "errors",
              "signals", "filesystem", "ros.core"},
    "ros": {"replay", "pipeline", "scenes", "bags", "messages", "reports", "engine", "physics", "errors", "signals",
            "filesystem"},
    "cli": {"sweep", "bench", "ros", "replay", "pipeline", "scenes", "bags", "messages", "reports", "engine",
            "physics", "errors", "signals", "filesystem"},
    "__init__": {"engine", "physics", "errors", "scenes", "replay", "pipeline", "messages", "bags", "reports"},
    "__main__": {"cli"},
}
MAX_LINES = 750


def _modules():
    for path in sorted(PKG.rglob("*.py")):
        rel = path.relative_to(PKG).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__" and len(parts) > 1:
            parts = parts[:-1]
        yield path, parts


def _room(parts: list[str]) -> str:
    return parts[0]


def _resolve(parts: list[str], is_pkg: bool, node: ast.ImportFrom) -> list[str]:
    """Absolute module path (inside the package, as parts) of an import, or [] if outside."""
    if node.level == 0:
        if not (node.module or "").startswith("gyro_platform"):
            return []
        return (node.module or "").split(".")[1:]
    base = parts if is_pkg else parts[:-1]
    base = base[: len(base) - (node.level - 1)] if node.level > 1 else base
    return base + (node.module.split(".") if node.module else [])


def _imports(path: Path, parts: list[str]):
    tree = ast.parse(path.read_text(), str(path))
    is_pkg = path.name == "__init__.py"
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            target = _resolve(parts, is_pkg, node)
            if node.level == 0 and not (node.module or "").startswith("gyro_platform"):
                continue
            yield node, target, [a.name for a in node.names]
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("gyro_platform."):
                    yield node, a.name.split(".")[1:], []


def _allowed(src_room: str, target: list[str]) -> bool:
    if not target:  # ``from gyro_platform import x`` / ``from . import x``: judged by the name
        return True
    dst = target[0]
    if dst == src_room:
        return True
    allowed = ALLOWED.get(src_room, set())
    return dst in allowed or ".".join(target[:2]) in allowed


def test_every_room_is_known_and_documented():
    for path, parts in _modules():
        room = _room(parts)
        assert room in ALLOWED, f"{path.relative_to(PKG)}: room {room!r} is not in the layout table"
        if path.name == "__init__.py":
            doc = ast.get_docstring(ast.parse(path.read_text()))
            why = f"{path.relative_to(PKG)} needs a docstring: what the room holds, what it may import"
            assert doc and len(doc) > 60, why


def _targets(target: list[str], names: list[str]) -> list[list[str]]:
    """Modules an import reaches: ``from pkg import mod`` reaches ``pkg.mod``."""
    if (PKG.joinpath(*target)).is_dir() or not target:
        out = [target + [n] for n in names if (PKG.joinpath(*target, n + ".py")).exists()
               or (PKG.joinpath(*target, n)).is_dir()]
        return out or ([target] if target else [])
    return [target]


def test_imports_point_down():
    bad = []
    for path, parts in _modules():
        room = _room(parts)
        for node, target, names in _imports(path, parts):
            for t in _targets(target, names):
                if not _allowed(room, t):
                    bad.append(f"{path.relative_to(PKG)}:{node.lineno} imports {'.'.join(t)}")
    assert not bad, "imports against the layout:\n" + "\n".join(bad)


def test_no_private_names_across_modules():
    bad = []
    for path, parts in _modules():
        for node, target, names in _imports(path, parts):
            for n in names:
                if n.startswith("_") and not n.startswith("__"):
                    bad.append(f"{path.relative_to(PKG)}:{node.lineno} imports private {n} from {'.'.join(target)}")
    assert not bad, "\n".join(bad)


def test_inits_only_reexport():
    for path, parts in _modules():
        if path.name != "__init__.py":
            continue
        tree = ast.parse(path.read_text())
        for node in tree.body:
            ok = isinstance(node, (ast.Import, ast.ImportFrom)) or (
                isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant)) or (
                isinstance(node, (ast.Assign, ast.AnnAssign))) or (
                # PEP 562 lazy re-export at the package root (keeps ``--help`` fast)
                isinstance(node, ast.FunctionDef) and node.name in ("__getattr__", "__dir__") and len(parts) == 1)
            assert ok, f"{path.relative_to(PKG)}:{node.lineno}: __init__ only re-exports"


@pytest.mark.parametrize("path", sorted(PKG.rglob("*.py")), ids=lambda p: str(p.relative_to(PKG)))
def test_modules_stay_small(path):
    lines = path.read_text().splitlines()
    header = next((i for i, line in enumerate(lines) if line and not line.startswith("#")), 0)   # licence notice
    n = len(lines) - header
    assert n <= MAX_LINES, f"{path.relative_to(PKG)} has {n} lines: split it by job"
