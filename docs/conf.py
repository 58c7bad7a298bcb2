"""Sphinx configuration: the Markdown pages (MyST), the tutorial notebook and the API reference.

Build with ``make docs`` (HTML into ``docs/_build/html``). Everything builds offline: no
intersphinx, no notebook execution. The tutorial notebook is shown as a page by a small parser
below: its Markdown cells as text, its code cells as code, each followed by the outputs the
notebook stores (``make tutorial`` executes it): myst-nb is not needed.
"""

from __future__ import annotations

import json
import re
from typing import Any

from myst_parser.parsers.sphinx_ import MystParser

import forcecal

project = "forcecal"
author = "the forcecal authors"
copyright = "the forcecal authors, MIT licence"
version = release = forcecal.__version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
]

root_doc = "index"
source_suffix = {".rst": "restructuredtext", ".md": "markdown", ".ipynb": "notebook"}
exclude_patterns = ["_build", ".ipynb_checkpoints"]
templates_path = ["_templates"]   # autosummary: a package page without its re-exports

# MyST: GitHub-style anchors for the pages' links to sections (guide.md#21-the-rig-file-toml)
myst_heading_anchors = 4
myst_enable_extensions = ["dollarmath"]

# the API reference: numpydoc-style docstrings read by napoleon; module pages by autosummary
autosummary_generate = True
autosummary_imported_members = False
autodoc_default_options = {"members": True, "show-inheritance": True}
autodoc_member_order = "bysource"
autodoc_typehints = "signature"
autodoc_typehints_format = "fully-qualified"   # "short" leaves a literal ~ in dataclass signatures
autodoc_preserve_defaults = False
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
napoleon_use_ivar = True      # attributes as a field list: their types link to classes only

html_theme = "alabaster"
html_title = f"forcecal {release}"
html_static_path: list[str] = []
html_theme_options = {"description": "forces on a vibrating structure; actuator calibration",
                      "fixed_sidebar": True}


def notebook_markdown(text: str) -> str:
    """A notebook (nbformat 4 JSON) as MyST Markdown: Markdown cells as they are, code cells as
    ``python`` code blocks, each followed by its stored outputs (:func:`output_markdown`)."""
    notebook = json.loads(text)
    parts = []
    for cell in notebook.get("cells", []):
        source = _text(cell.get("source", ""))
        if cell.get("cell_type") == "markdown":
            parts.append(source)
        elif cell.get("cell_type") == "code":
            parts.append(_fenced("python", source))
            shown = (output_markdown(output) for output in cell.get("outputs", []))
            parts.extend(_fenced("{container} nboutput", s) for s in shown if s)
    return "\n\n".join([*parts, _fenced("{raw} html", _OUTPUT_STYLE)]) + "\n"


_OUTPUT_STYLE = ("<style>div.nboutput div.highlight {background: none; "
                 "border-left: 3px solid #ccc}</style>")
"""An output's text set apart from the code above it (the theme draws both alike)."""


_RICHEST = ("image/png", "text/html", "text/plain")
"""The MIME types of a displayed value shown, the first one the output holds."""
_ANSI = re.compile(r"\x1b\[[0-9;]*[A-Za-z]")


def output_markdown(output: dict) -> str:
    """One stored output as MyST Markdown: printed text (stdout, stderr) and a value's
    ``text/plain`` as literal blocks, an ``image/png`` as an image (a data URI: the page carries
    it), a ``text/html`` (a DataFrame, a result's table) as raw HTML, an error as its traceback;
    of a value's several MIME types the richest (:data:`_RICHEST`). Nothing for other types."""
    kind = output.get("output_type")
    if kind == "stream":
        return _fenced("text", _text(output.get("text", "")))
    if kind == "error":
        return _fenced("text", _ANSI.sub("", "\n".join(output.get("traceback", []))))
    data = output.get("data", {})
    mime = next((m for m in _RICHEST if m in data), None)
    if mime == "image/png":
        png = "".join(_text(data[mime]).split())
        return f"```{{image}} data:image/png;base64,{png}\n:alt: figure\n```"
    if mime == "text/html":
        return _fenced("{raw} html", _text(data[mime]))
    if mime == "text/plain":
        return _fenced("text", _text(data[mime]))
    return ""


def _text(value: str | list[str]) -> str:
    """A notebook's multi-line string: stored whole or as a list of lines."""
    return "".join(value) if isinstance(value, list) else value


def _fenced(info: str, body: str) -> str:
    """``body`` in a backtick fence longer than any run of backticks in it."""
    longest = max((len(run) for run in re.findall(r"`+", body)), default=0)
    fence = "`" * max(3, longest + 1)
    body = body.rstrip("\n")
    return f"{fence}{info}\n{body}\n{fence}"


class NotebookParser(MystParser):
    """Parses ``.ipynb`` files as the Markdown :func:`notebook_markdown` makes of them."""

    supported = ("notebook",)

    def parse(self, inputstring: str, document: Any) -> None:
        super().parse(notebook_markdown(inputstring), document)


# a type field as napoleon writes it, and a shape in it: "(n_params,) array" is code, not names
_TYPE_FIELD = re.compile(r"^(\s*:(?:type|vartype)\s+[^:]+:\s*|\s*:rtype:\s*)(.*)$")
_SHAPE = re.compile(r"(?<![\w`])\([^()`]*\)")
# spans of a docstring line in which "|" is literal or a role's text: ``x``, `x`, :role:`x`
_QUOTED = re.compile(r"(``.+?``|(?::[\w:+-]+:)?`[^`]+`)")


_module_documented = [""]
"""The module whose page autodoc is writing (set by its docstring, before its members)."""


def prepare_docstring(app: Any, what: str, name: str, obj: Any, options: Any,
                      lines: list[str]) -> None:
    """Note the module being documented; show the shapes in types as code, ``(n_poles,)``, so
    that Sphinx does not link their dimension names to attributes of that name; and escape the
    plain-text absolute values (``|F_1|``): every ``|`` outside literals, so that reST reads
    neither a substitution nor a line block."""
    if what == "module":
        _module_documented[0] = name
    for k, line in enumerate(lines):
        field = _TYPE_FIELD.match(line)
        if field and "(" in field.group(2):
            line = lines[k] = field.group(1) + _SHAPE.sub(r"``\g<0>``", field.group(2))
        if "|" in line:
            parts = _QUOTED.split(line)
            lines[k] = "".join(p if j % 2 else p.replace("|", "\\|") for j, p in enumerate(parts))


def skip_reexport(app: Any, what: str, name: str, obj: Any, skip: bool,
                  options: Any) -> bool | None:
    """Document an object once, on the page of the public module that defines it: a module that
    re-exports it (``forcecal.io.uff`` the ``read_scan_uff`` of ``forcecal.io._uff_read``)
    skips it.
    What a module re-exports from a private one (``_uff_read``) is documented with it."""
    home = getattr(obj, "__module__", None)
    if skip or what != "module" or not isinstance(home, str) or not home.startswith("forcecal"):
        return None
    if home == _module_documented[0] or any(p.startswith("_") for p in home.split(".")):
        return None
    return True


def setup(app: Any) -> dict[str, Any]:
    app.add_source_parser(NotebookParser)
    app.connect("autodoc-process-docstring", prepare_docstring)
    app.connect("autodoc-skip-member", skip_reexport)
    return {"parallel_read_safe": False}   # skip_reexport follows autodoc's order
