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

"""Every file, command, launch argument and parameter the README and ``docs/`` name exists.

Read from ``README.md`` and the pages of ``docs/`` (not the generated API pages): the inline code
spans, link targets and fenced code blocks. Checked against the repository and the code:

* paths: a link target (relative to its page); a path whose first part is a folder of the
  repository (``config/``, ``gyro_platform/``, ``test/`` …) or a room of the package
  (``engine/batch.py``, ``io/gate.TimeGate`` — module, then the names it must define); a bare
  ``*.py`` / ``*.txt`` / ``*.xml`` file name (at the root or in ``gyro_platform``, ``test``,
  ``launch``, ``config``); ``install/gyro_platform/share/gyro_platform/…`` (the installed copy of
  a repository file); ``../shared/…`` (checked where ``../shared`` exists, else skipped with the
  reason); globs must match a file;
* ``gyro_platform.x.y.Name``: the module exists and defines every name after it;
* ``gyro-platform <subcommand> [--flags]`` (and ``python -m gyro_platform …``): the subcommand is
  one of the CLI's parser, every flag one of that subcommand's parser, ``bench``'s benchmark one
  of its choices;
* ``ros2 launch gyro_platform <file> [name:=value]``: the launch file exists and declares every
  argument; ``ros2 run gyro_platform <exe>``: an entry point of setup.py, its ``-p name:=…`` a
  node parameter; ``ros2 param get|set|describe /gyro_platform_node <name>``: a node parameter.

Output paths (``results/…``, ``OUT.summary.json``), ROS names (``/imu``, ``gimbal/joint_states``)
and placeholders (``<share>``, ``~/…``, ``$VAR``) are not repository files and are not checked.
:func:`test_the_checker_finds_wrong_names` keeps the checker honest. The Sphinx build itself runs
only where Sphinx is installed (the ``docs`` extra).
"""
from __future__ import annotations

import ast
from dataclasses import dataclass, field
from functools import lru_cache
import importlib
import importlib.util
from pathlib import Path
import re
import subprocess
import sys

import pytest

REPO = Path(__file__).resolve().parents[1]
PKG = REPO / "gyro_platform"
SHARED = REPO.parent / "shared"
SHARED_PREFIX = "../shared/"
#: first parts of repository paths (the folders a reader can find in a clone)
REPO_DIRS = ("config", "docs", "gyro_platform", "launch", "resource", "test", ".ci")
#: generated, not in the repository: the Sphinx output and the autosummary stubs
GENERATED = ("docs/_build", "docs/api")
INSTALLED = "install/gyro_platform/share/gyro_platform/"
#: bare file names with these endings name repository files (``outputs.csv``, ``metadata.yaml``
#: and the like are outputs and are not checked)
BARE_EXTENSIONS = (".py", ".txt", ".xml", ".cfg", ".toml", ".rviz", ".sh")
BARE_DIRS = ("", "gyro_platform", "test", "launch", "config")

TOKEN = re.compile(r"[^\s\"'`()\[\],;|]+")
CODE_SPAN = re.compile(r"``(.+?)``|`([^`]+)`", re.S)
LINK = re.compile(r"\]\(([^)\s]+)\)")
EXTENSION = re.compile(r"\.(py|ya?ml|xml|md|rst|png|rviz|txt|sh|cfg|toml|json|csv)$")
DOTTED = re.compile(r"\bgyro_platform(?:\.[A-Za-z_]\w*)+")


def doc_files() -> list[Path]:
    docs = REPO / "docs"
    return [REPO / "README.md", *sorted(p for p in docs.glob("*") if p.suffix in (".md", ".rst"))]


@dataclass
class Snippets:
    """What a page names: code (spans and fenced lines, with the page's line numbers) and links."""

    code: list[tuple[int, str]] = field(default_factory=list)
    links: list[tuple[int, str]] = field(default_factory=list)


def snippets(text: str) -> Snippets:
    s = Snippets()
    fence = None
    prose = []                                   # the page with its fenced blocks blanked
    for n, line in enumerate(text.split("\n"), 1):
        stripped = line.strip()
        if stripped.startswith("```"):
            fence = None if fence is not None else stripped[3:]
            prose.append("")
            continue
        if fence is not None:
            prose.append("")
            if not fence.startswith(("{include}", "{literalinclude}")):   # directive options: no commands
                s.code.append((n, line))
            continue
        prose.append(line)
    prose_text = "\n".join(prose)
    for m in CODE_SPAN.finditer(prose_text):     # a span may run over a line break
        n = prose_text.count("\n", 0, m.start()) + 1
        s.code.append((n, (m.group(1) or m.group(2)).replace("\n", " ")))
    for m in LINK.finditer(prose_text):
        s.links.append((prose_text.count("\n", 0, m.start()) + 1, m.group(1)))
    s.code.sort(key=lambda c: c[0])
    return s


# ---- the code the docs are checked against -------------------------------------------------
@lru_cache(maxsize=None)
def subcommand_parsers() -> dict:
    from gyro_platform import cli

    parser = cli.build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    return {"": parser, **sub.choices}


def options_of(parser) -> set[str]:
    return {o for a in parser._actions for o in a.option_strings}


def positional_choices(parser) -> list:
    return [a.choices for a in parser._actions if not a.option_strings and a.choices and a.dest != "command"]


@lru_cache(maxsize=None)
def launch_arguments(launch_file: str) -> set[str] | None:
    """The arguments a launch file declares: the names of the table it imports (``ARGUMENTS``) or
    literal ``DeclareLaunchArgument("name", …)`` calls. None if the file does not exist."""
    path = REPO / "launch" / launch_file
    if not path.is_file():
        return None
    tree = ast.parse(path.read_text())
    names = {c.args[0].value for c in ast.walk(tree) if isinstance(c, ast.Call)
             and getattr(c.func, "id", "") == "DeclareLaunchArgument" and c.args
             and isinstance(c.args[0], ast.Constant)}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and any(a.name == "ARGUMENTS" for a in node.names):
            names |= {a[0] for a in importlib.import_module(node.module).ARGUMENTS}
    return names


@lru_cache(maxsize=None)
def entry_points() -> set[str]:
    return set(re.findall(r"[\"']([\w.-]+)\s*=\s*gyro_platform[\w.]*:\w+", (REPO / "setup.py").read_text()))


@lru_cache(maxsize=None)
def node_parameters() -> set[str]:
    from gyro_platform.ros.parameters import SPECS

    return set(SPECS) | {"use_sim_time"}


@lru_cache(maxsize=None)
def defined_names(path: Path) -> set[str]:
    """Every name a module defines at any depth (functions, classes, assignments, attributes
    assigned on ``self``), read with ``ast``."""
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            names.add(node.id)
        elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
            names.add(node.attr)
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            names |= {(a.asname or a.name).split(".")[0] for a in node.names}
    return names


def module_file(parts: list[str]) -> Path | None:
    base = REPO.joinpath(*parts)
    for p in (base.with_suffix(".py"), base / "__init__.py"):
        if p.is_file():
            return p
    return None


def check_dotted(parts: list[str]) -> str | None:
    """``parts`` = a module path under the repository, then names it must define. None if fine."""
    for i in range(len(parts), 0, -1):
        path = module_file(parts[:i])
        if path is not None:
            missing = [n for n in parts[i:] if n not in defined_names(path)]
            if missing and parts[0] == "gyro_platform":      # a lazy re-export (the package root's)
                try:
                    obj = importlib.import_module(".".join(parts[:i]))
                    for n in parts[i:]:
                        obj = getattr(obj, n)
                    return None
                except (ImportError, AttributeError):
                    pass
            return f"{path.relative_to(REPO)} defines no {'.'.join(missing)}" if missing else None
    return "no such module"


@lru_cache(maxsize=None)
def rooms() -> tuple[str, ...]:
    return tuple(p.parent.name for p in PKG.glob("*/__init__.py"))


# ---- checks ----------------------------------------------------------------------------------
def check_path(token: str, page_dir: Path, link: bool) -> str | None:
    """Why ``token`` names no repository file, or None (fine, or not a repository path)."""
    token = token.split("#")[0].rstrip(".:")
    if not token or "://" in token or token.startswith(("/", "~", "$", "<", "-", "mailto:")) \
            or any(c in token for c in "<>{}$…="):
        return None
    if token.startswith(SHARED_PREFIX):
        return None                          # test_shared_paths_exist
    if link:
        target = (page_dir / token).resolve()
        return None if target.exists() else "link target not found"
    if token.startswith(INSTALLED):
        token = token[len(INSTALLED):]       # the installed copy of config/… or launch/…
        return None if (REPO / token).exists() else "not installed from the repository"
    if token.startswith(GENERATED):
        return None
    first, _, rest = token.partition("/")
    if first in REPO_DIRS or (first in rooms() and rest):
        base = REPO if first in REPO_DIRS else PKG
        if any(c in token for c in "*?"):
            return None if list(base.glob(token)) else "glob matches nothing"
        if (base / token).exists():
            return None
        head, _, names = token.rpartition("/")[2].partition(".")
        if names and not EXTENSION.search(token):          # engine/batch.block_kernel
            mod = (base / token).parent.relative_to(REPO).parts + (head,)
            return check_dotted([*mod, *names.split(".")])
        if not EXTENSION.search(token) and module_file(list((base / token).relative_to(REPO).parts)):
            return None                                       # physics/system (a module)
        return "no such file"
    if "/" not in token and token.endswith(BARE_EXTENSIONS):
        return None if any((REPO / d / token).is_file() for d in BARE_DIRS) else "no such file"
    return None


def command_problems(line: str) -> list[str]:
    """Problems of the gyro-platform / ros2 commands on one line of code."""
    out = []
    for m in re.finditer(r"(?:^|[\s/])(?:gyro-platform|python3? -m gyro_platform)(?=\s|$)(.*)", line):
        words = re.split(r"\s+(?:&&|\|\|?|;|#)\s*|\s+#", m.group(1))[0].split()
        parsers = subcommand_parsers()
        positional = [w.strip("[]:") for w in words if not w.startswith(("-", "[-"))]
        name = positional[0] if positional and re.fullmatch(r"[a-z]+", positional[0]) else ""
        if name and name not in parsers:
            out.append(f"gyro-platform {name}: no such subcommand ({', '.join(p for p in parsers if p)})")
            continue
        parser = parsers[name]
        known = options_of(parser) | {"-h", "--help"}
        for w in words:
            flag = w.strip("[]").split("=")[0]
            if re.fullmatch(r"--?[A-Za-z][\w-]*", flag) and flag not in known:
                out.append(f"gyro-platform {name or ''}: no option {flag}".replace("  ", " "))
        choices = positional_choices(parser)
        if name and choices and len(positional) > 1 and re.fullmatch(r"[a-z]+", positional[1]):
            if positional[1] not in choices[0]:
                out.append(f"gyro-platform {name} {positional[1]}: not one of {', '.join(choices[0])}")
    m = re.search(r"\bros2 launch gyro_platform (\S+)(.*)", line)
    if m:
        declared = launch_arguments(m.group(1))
        if declared is None:
            out.append(f"ros2 launch gyro_platform {m.group(1)}: no such file in launch/")
        else:
            for arg in re.findall(r"(?:^|\s)\[?([A-Za-z_]\w*):=", m.group(2).split("#")[0]):
                if arg not in declared:
                    out.append(f"ros2 launch gyro_platform {m.group(1)}: no launch argument {arg}")
    m = re.search(r"\bros2 run gyro_platform (\S+)(.*)", line)
    if m:
        if m.group(1) not in entry_points():
            out.append(f"ros2 run gyro_platform {m.group(1)}: no such executable in setup.py")
        out += [f"ros2 run … -p {p}: no such node parameter" for p in re.findall(r"-p\s+([\w.]+):=", m.group(2))
                if p not in node_parameters()]
    for p in re.findall(r"\bros2 param (?:get|set|describe) /\S*gyro_platform_node\s+([\w.]+)", line):
        if p not in node_parameters():
            out.append(f"ros2 param …: no node parameter {p}")
    return out


def problems(text: str, page: Path) -> list[str]:
    """Every name on a page that does not exist, as 'page:line: token: why'."""
    name = page.relative_to(REPO) if page.is_relative_to(REPO) else page.name
    s = snippets(text)
    found = []
    for n, target in s.links:
        why = check_path(target, page.parent, link=True)
        if why:
            found.append(f"{name}:{n}: {target}: {why}")
    for n, code in s.code:
        for token in TOKEN.findall(code):
            why = check_path(token, page.parent, link=False)
            if why:
                found.append(f"{name}:{n}: {token}: {why}")
        for dotted in DOTTED.findall(code):
            why = check_dotted(dotted.split("."))
            if why:
                found.append(f"{name}:{n}: {dotted}: {why}")
        found += [f"{name}:{n}: {why}" for why in command_problems(code)]
    return found


# ---- tests -----------------------------------------------------------------------------------
def test_every_file_command_and_parameter_the_docs_name_exists():
    pages = doc_files()
    assert len(pages) > 5 and (REPO / "docs" / "conf.py").is_file()
    found = [p for page in pages for p in problems(page.read_text(), page)]
    assert not found, "the docs name what does not exist:\n" + "\n".join(found)


def test_the_docs_name_commands_and_paths_at_all():
    """The checker reads what it should: the README's commands and paths are seen."""
    s = snippets((REPO / "README.md").read_text())
    code = "\n".join(c for _, c in s.code)
    for need in ("gyro-platform run", "gyro-platform replay", "gyro-platform sweep", "gyro-platform bench",
                 "gyro-platform node", "ros2 launch gyro_platform platform.launch.py", "config/platform.yaml"):
        assert need in code, need
    assert any(t.startswith("docs/") for _, t in s.links)


def test_the_checker_finds_wrong_names(tmp_path):
    page = tmp_path / "page.md"
    good = ("Run `gyro-platform run default --out results/x --duration 2` or see [the model](model.md).\n"
            "```bash\nros2 launch gyro_platform platform.launch.py scene:=coning namespace:=r1\n"
            "ros2 run gyro_platform platform_node --ros-args -p output_rate:=5.0\n"
            "gyro-platform bench accuracy --quick\n```\n"
            "`gyro_platform/engine/simulator.py`, `engine/batch.block_kernel`, `config/scenes/*.yaml`, "
            "`gyro_platform.ros.parameters.parameters_markdown`, `install/gyro_platform/share/gyro_platform/"
            "config/platform.yaml`, `results/nowhere/outputs.csv`, `/imu/data`.\n")
    (tmp_path / "model.md").write_text("# model\n")
    assert problems(good, page) == []
    bad = {
        "`gyro_platform/nodee.py`": "gyro_platform/nodee.py: no such file",
        "`config/scenes/nope.yaml`": "no such file",
        "`engine/batch.no_such_kernel`": "defines no no_such_kernel",
        "`gyro_platform.ros.core.NoSuchCore`": "defines no NoSuchCore",
        "`gyro_platform.nosuchroom.x`": "defines no nosuchroom",
        "[gone](gone.md)": "link target not found",
        "`frobnicate.py`": "no such file",
        "`install/gyro_platform/share/gyro_platform/config/nope.yaml`": "not installed",
        "`config/scenes/*.yml`": "glob matches nothing",
        "`gyro-platform runn default`": "no such subcommand",
        "`gyro-platform run default --bogus`": "no option --bogus",
        "`gyro-platform bench acuracy`": "not one of",
        "`ros2 launch gyro_platform nope.launch.py`": "no such file in launch/",
        "`ros2 launch gyro_platform platform.launch.py bogus:=1`": "no launch argument bogus",
        "`ros2 run gyro_platform node_platform`": "no such executable",
        "`ros2 run gyro_platform platform_node --ros-args -p outptu_rate:=1.0`": "no such node parameter",
        "`ros2 param set /gyro_platform_node outptu_rate 1.0`": "no node parameter outptu_rate",
    }
    for text, why in bad.items():
        found = problems(text + "\n", page)
        assert found and any(why in f for f in found), (text, found)


def test_readme_is_a_ros_2_package_readme():
    """What it is, quick start (the two blocks .ci/run extracts), ROS 2 within the first 60
    lines, topics and parameters, the tools, links into docs/ — in that order, ~250 lines."""
    lines = (REPO / "README.md").read_text().split("\n")
    heads = [(n, line) for n, line in enumerate(lines, 1) if line.startswith("## ")]
    order = ["## Quick start", "## ROS 2", "## Topics and parameters", "## Replay", "## Documentation"]
    at = [next((n for n, h in heads if h.startswith(o)), None) for o in order]
    assert None not in at and at == sorted(at), list(zip(order, at))
    assert at[1] <= 60, f"the ROS 2 section starts at line {at[1]}"
    assert len(lines) <= 300, f"README.md has {len(lines)} lines"
    for marker in ("<!-- ci:setup -->", "<!-- ci:test -->"):
        assert lines.count(marker) == 1, marker
        i = lines.index(marker)
        assert at[0] < i + 1 < at[1] and lines[i + 1] == "```bash", marker    # in the quick start, bash


def test_shared_paths_exist():
    """``../shared/…`` paths (the spec, the recordings, the ROS 2 install script) exist beside
    the repository, on the machines that have them."""
    tokens = {(page, n, t) for page in doc_files() for n, code in snippets(page.read_text()).code
              for t in TOKEN.findall(code) if t.startswith(SHARED_PREFIX)}
    tokens |= {(page, n, t) for page in doc_files() for n, t in snippets(page.read_text()).links
               if t.startswith(SHARED_PREFIX)}
    assert tokens, "the README names ../shared/spec/PHYSICS.md and ../shared/ros2/install.sh"
    if not SHARED.is_dir():
        pytest.skip(f"{SHARED} does not exist here: the ../shared paths the docs name cannot be checked")
    missing = [f"{p.relative_to(REPO)}:{n}: {t}" for p, n, t in sorted(tokens)
               if not (REPO / t.rstrip(".:")).exists()]
    assert not missing, "\n".join(missing)


def test_sphinx_builds_the_docs_without_warnings(tmp_path):
    if importlib.util.find_spec("sphinx") is None or importlib.util.find_spec("myst_parser") is None:
        pytest.skip("Sphinx or myst-parser is not installed (pip install -e '.[docs]'): the -W build is not run")
    res = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "dummy",
                          "-d", str(tmp_path / "doctrees"), str(REPO / "docs"), str(tmp_path / "out")],
                         capture_output=True, text=True, timeout=900, cwd=REPO)
    assert res.returncode == 0, res.stderr[-4000:]
