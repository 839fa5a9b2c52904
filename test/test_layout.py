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

Rooms import only downwards (``cli`` → ``ros`` → … → ``physics``), the modules of a room import
each other without a circle, no module reaches a private name of another module (by import or
by attribute), every room says in its docstring what it holds and may import, and no module
grows much past ~700 lines. Read from the source with ``ast``: nothing is imported.

Private names (one leading underscore, not a dunder) are private to the module that defines
them. ``test_no_private_names_across_modules`` flags ``from .x import _y``;
``test_no_private_attributes_across_modules`` flags, in a module ``M`` of the package:

* ``alias._y`` (or ``alias.sub._y``) where ``alias`` is bound in ``M`` by an import from
  ``gyro_platform``: a module or a class of another module (``msgs._flatten``,
  ``Pipeline._error``);
* ``obj._y`` on any other object (``scratch._emit(…)``, ``self.pipeline._error(…)``) when
  ``_y`` is defined (``def``, ``class``, assigned, ``self._y = …``, an argument) in another
  module of the package, unless ``obj`` is a plain name and ``M`` defines ``_y`` too (a local
  object of ``M``'s own making); an attribute chain (``self.primary._advance``) is flagged even
  then: what it holds may come from anywhere.

``self._y``, ``cls._y`` and ``C._y`` for a class ``C`` of ``M`` are the module's own. A separate,
explicit rule for third-party internals: they are not counted here (they are judged where the
package wraps its dependencies, e.g. rosbags), i.e. ``alias._y`` where ``alias`` is bound by an
import of a module outside the package (stdlib or third party: ``argparse._SubParsersAction``,
numba's ``caching._CacheLocator``, ``sys._getframe``), and ``obj._y`` where no module of the
package defines ``_y`` (the object's class is not ours: argparse's ``parser._actions``, scipy's
``solver._estimate_error_norm``, numba's ``out._getvalue``, a namedtuple's ``_replace``). Tests
are not the package: they may look inside (``TimeGate._s``).
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
    "quaternions": set(),
    "heap": set(),
    "physics": {"errors", "signals"},
    "engine": {"physics", "errors", "signals"},
    "messages": {"physics", "engine.inputs", "engine.outputs", "errors"},
    "bags": {"messages", "physics", "errors", "signals", "filesystem"},
    "reports": {"messages", "engine.outputs", "errors", "signals", "filesystem", "quaternions"},
    "pipeline": {"bags", "messages", "engine", "physics", "errors", "signals"},
    "scenes": {"pipeline", "bags", "messages", "reports", "engine", "physics", "errors", "signals", "filesystem",
               "quaternions"},
    "replay": {"pipeline", "scenes", "bags", "messages", "reports", "engine", "physics", "errors", "signals",
               "filesystem"},
    "sweep": {"replay", "pipeline", "scenes", "bags", "messages", "reports", "engine", "physics", "errors", "signals",
              "filesystem"},
    "bench": {"sweep", "replay", "pipeline", "scenes", "bags", "messages", "reports", "engine", "physics", "errors",
              "signals", "filesystem", "ros.core"},
    "ros": {"replay", "pipeline", "scenes", "bags", "messages", "reports", "engine", "physics", "errors", "signals",
            "filesystem", "quaternions"},
    "cli": {"prefill", "sweep", "bench", "ros", "replay", "pipeline", "scenes", "bags", "messages", "reports", "engine",
            "physics", "errors", "signals", "filesystem", "heap"},
    "prefill": {"ros", "replay", "scenes", "bench.bags", "messages", "engine", "physics", "errors", "signals",
                "filesystem"},
    "__init__": {"engine", "physics", "errors", "scenes", "replay", "pipeline", "messages", "bags", "reports"},
    "__main__": {"cli"},
}
MAX_LINES = 700


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


def _reexports(pkg: list[str]) -> dict[str, list[str]]:
    """Name -> module a package's ``__init__`` re-exports it from (inside the package)."""
    init = PKG.joinpath(*pkg, "__init__.py")
    out: dict[str, list[str]] = {}
    if init.exists():
        for node, target, names in _imports(init, pkg):
            for n in names:
                out[n] = target
    return out


def _room_edges() -> dict[tuple[str, ...], set[tuple[str, ...]]]:
    """Module -> modules of its own room it imports (at any level, a function's imports too); an
    import through a package's ``__init__`` is followed to the module that defines the name."""
    edges: dict[tuple[str, ...], set[tuple[str, ...]]] = {}
    for path, parts in _modules():
        if path.name == "__init__.py":
            continue                                # re-exports only (test_inits_only_reexport)
        mine = edges.setdefault(tuple(parts), set())
        for node, target, names in _imports(path, parts):
            for t in _targets(target, names):
                if not t or t[0] != parts[0]:
                    continue
                if PKG.joinpath(*t).is_dir():       # ``from .pkg import Name``: the module behind Name
                    again = _reexports(t)
                    reached = [again[n] for n in names if n in again] or [t]
                else:
                    reached = [t]
                mine.update(tuple(r) for r in reached if tuple(r) != tuple(parts))
    return edges


def test_no_import_circle_inside_a_room():
    """The modules of a room import each other in one direction: no circle, lazy imports included
    (``ros.command`` runs the transports, the transports take the warm-up from ``ros.warmup``)."""
    edges = _room_edges()
    circles, state = [], {}

    def visit(mod: tuple[str, ...], stack: list[tuple[str, ...]]) -> None:
        state[mod] = "open"
        for nxt in sorted(edges.get(mod, ())):
            if state.get(nxt) == "open":
                circle = stack[stack.index(nxt):] + [mod, nxt] if nxt in stack else [mod, nxt]
                circles.append(" -> ".join(".".join(m) for m in circle))
            elif nxt not in state:
                visit(nxt, stack + [mod])
        state[mod] = "done"

    for mod in sorted(edges):
        if mod not in state:
            visit(mod, [])
    assert not circles, "import circles inside a room:\n" + "\n".join(circles)


def test_no_private_names_across_modules():
    bad = []
    for path, parts in _modules():
        for node, target, names in _imports(path, parts):
            for n in names:
                if n.startswith("_") and not n.startswith("__"):
                    bad.append(f"{path.relative_to(PKG)}:{node.lineno} imports private {n} from {'.'.join(target)}")
    assert not bad, "\n".join(bad)


def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def _defined_privates(tree: ast.AST) -> set[str]:
    """Private names a module defines: functions, classes, assigned names and attributes."""
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            out.add(node.name)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            out.add(node.id)
        elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
            out.add(node.attr)
        elif isinstance(node, ast.arg):
            out.add(node.arg)
        elif isinstance(node, ast.keyword) and node.arg:     # ``set_defaults(_module=…)``, ``_replace(_x=…)``
            out.add(node.arg)
    return {n for n in out if _private(n)}


def _import_bindings(tree: ast.AST) -> dict[str, bool]:
    """Names bound by imports in a module -> True if they come from the package, False if not."""
    out: dict[str, bool] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            ours = node.level > 0 or (node.module or "").split(".")[0] == "gyro_platform"
            for a in node.names:
                out[a.asname or a.name] = ours
        elif isinstance(node, ast.Import):
            for a in node.names:
                out[a.asname or a.name.split(".")[0]] = a.name.split(".")[0] == "gyro_platform"
    return out


def _root_name(node: ast.expr) -> str | None:
    """``a`` of ``a.b.c`` (None for a call, a subscript … at the root)."""
    while isinstance(node, ast.Attribute):
        node = node.value
    return node.id if isinstance(node, ast.Name) else None


def test_no_private_attributes_across_modules():
    """``X._y`` reaches into another module of the package (the rules: the module docstring)."""
    trees = {path: ast.parse(path.read_text(), str(path)) for path, _ in _modules()}
    defined = {path: _defined_privates(tree) for path, tree in trees.items()}
    bad = []
    for path, tree in trees.items():
        own_classes = {n.name for n in ast.walk(tree) if isinstance(n, ast.ClassDef)}
        bound = _import_bindings(tree)
        elsewhere = set().union(*(d for p, d in defined.items() if p != path))
        for node in ast.walk(tree):
            if not (isinstance(node, ast.Attribute) and _private(node.attr)):
                continue
            where = f"{path.relative_to(PKG)}:{node.lineno} {ast.unparse(node)}"
            value, root = node.value, _root_name(node.value)
            if isinstance(value, ast.Name) and (value.id in ("self", "cls") or value.id in own_classes):
                continue                                    # the module's own
            if root in bound:
                if bound[root]:
                    bad.append(f"{where}: private name of the package module bound to {root!r}")
                continue                                    # stdlib / third party: not counted here
            if node.attr not in elsewhere:
                continue                                    # ours alone, or a third-party object's
            if isinstance(value, ast.Name) and node.attr in defined[path]:
                continue                                    # a local object of this module's making
            bad.append(f"{where}: {node.attr} is defined in another module of the package")
    assert not bad, "private attributes reached across modules:\n" + "\n".join(bad)


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
