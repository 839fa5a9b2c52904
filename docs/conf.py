"""Sphinx configuration of the gyro_platform documentation (built as rosdoc2 builds ROS 2 package docs).

    sphinx-build -W -b html docs docs/_build/html

The pages are MyST markdown; the API reference is generated from the docstrings
(autosummary over every module of the package, autodoc, napoleon).
"""
import os
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, ROOT)
# ``python -m gyro_platform`` runs the command line when its module is imported; the API
# reference has nothing to say about it, and autosummary's recursive scan would import it
import types  # noqa: E402
sys.modules.setdefault("gyro_platform.__main__", types.ModuleType("gyro_platform.__main__"))

project = "gyro_platform"
author = "gyro_platform developers"
copyright = "2026, gyro_platform developers"
release = version = "0.1.0"

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", ".venv", "Thumbs.db", ".DS_Store"]
templates_path = ["_templates"]

myst_enable_extensions = ["colon_fence", "dollarmath"]
myst_heading_anchors = 3

# -- API reference --------------------------------------------------------------------------
autosummary_generate = True
autosummary_imported_members = False
# ignore-module-all: the package root and ``engine.integrators`` list re-exported names in
# ``__all__``; they are documented once, in the module that defines them
autodoc_default_options = {"members": True, "show-inheritance": True, "ignore-module-all": True}
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_typehints_format = "short"
# the rclpy node is documented without a ROS install: its ROS imports are mocked (rosdoc2 runs
# with ROS sourced and does not need this)
autodoc_mock_imports = ["rclpy", "rcl_interfaces", "std_srvs", "launch", "launch_ros", "ament_index_python"]
napoleon_google_docstring = True
napoleon_numpy_docstring = True

html_theme = "alabaster"
html_static_path = []
html_title = "gyro_platform"


# -- plain-text docstrings ------------------------------------------------------------------
# The docstrings are reST for markup (``code``, :func:`x`, literal blocks) but write maths as
# plain text: |x| is an absolute value, [A-Za-z_] a character class. In reST those are a
# substitution reference and a hyperlink reference; escape exactly these two characters
# outside literals and interpreted text, so that they read as written. Every other markup
# problem still fails the build (-W).
import re as _re

_LITERAL_SPAN = _re.compile(r"(``.+?``|`[^`]+`_?_?)", _re.S)    # may run over a line break
_PLAIN_BAR = _re.compile(r"(?<!\\)\|")
_PLAIN_REF_END = _re.compile(r"(?<=[\w\]])_(?=[\]\W]|$)", _re.M)


def _escape_plain(text: str) -> str:
    parts = _LITERAL_SPAN.split(text)
    for i in range(0, len(parts), 2):        # even parts: outside ``literal`` / `interpreted`
        parts[i] = _PLAIN_REF_END.sub(r"\\_", _PLAIN_BAR.sub(r"\\|", parts[i]))
    return "".join(parts)


def _indent(line: str) -> int:
    return len(line) - len(line.lstrip())


def _literal_lines(lines: list[str]) -> set[int]:
    """Lines of literal blocks (after ``::``), directives and doctests: left as written."""
    out, block = set(), None         # block: indent of the line that opened a literal block
    for i, line in enumerate(lines):
        stripped = line.strip()
        if block is not None and (not stripped or _indent(line) > block):
            out.add(i)
            continue
        block = None
        if stripped.startswith((".. ", ">>>")):
            out.add(i)
            block = _indent(line)
        elif stripped.endswith("::"):
            block = _indent(line)
    return out


def escape_plain_docstring(app, what, name, obj, options, lines):
    keep = _literal_lines(lines)
    i = 0
    while i < len(lines):            # each run of prose lines as one text: spans cross lines
        if i in keep:
            i += 1
            continue
        j = i
        while j < len(lines) and j not in keep:
            j += 1
        lines[i:j] = _escape_plain("\n".join(lines[i:j])).split("\n")
        i = j


def setup(app):
    app.connect("autodoc-process-docstring", escape_plain_docstring)
