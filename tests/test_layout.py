"""The package's layout keeps its promises: each stage of the method in the package named after
it, the README's table naming them, one concept per module, short functions, the drive and the
structure kind read in one place each, no import cycle at any level, no import inside a
function to dodge one, the core free of files, streams and figures, and a small public API."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import forcecal

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "forcecal"
MAX_LINES = 900
"""A module above this many lines does more than one job."""
MAX_FUNCTION_CODE = 60
"""Lines of code (not blank, not comment, not docstring) a function may hold."""
MAX_DOCSTRING = 20
"""Lines a module docstring may hold."""
MAX_TOP_LEVEL = 13
"""Modules at the top of the package beside its subpackages."""
MAX_PUBLIC = 30
"""Names of ``forcecal.__all__``."""
MAX_EXPORTED = 428
"""Names of every ``__all__`` in the package together: half of what they were (856) before the
stages became packages."""
DEFERRED_OK = ("cli", "api.py", "report", "__init__.py")
"""Where an import inside a function is allowed: start-up time is the point (the command line,
the API, the report's figures, the package's lazy top)."""
CORE = ("structures", "signals", "model", "forces", "actuator", "rig.py", "records.py",
        "errors.py", "schema", "_atomic.py", "_version.py")
"""The method's own stages and data: they never read files by format, stream or draw."""
OUTSIDE_CORE = ("io", "realtime", "report", "cli", "simulate", "drives", "campaign", "cluster",
                "api")
DRIVE_READERS = ("rig.py", "drives/")
"""The rig parser (and its writer) and the drives' chooser are the only readers of the drive."""


def modules() -> list[Path]:
    return sorted(PACKAGE.rglob("*.py"))


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


NAMES = {module_name(p): p for p in modules()}


def _target(path: Path, node: ast.ImportFrom) -> str:
    """The absolute module an ``from ... import`` names."""
    if not node.level:
        return node.module or ""
    parts = module_name(path).split(".")
    if path.name != "__init__.py":
        parts = parts[:-1]
    parts = parts[:len(parts) - (node.level - 1)]
    return ".".join([*parts, *([node.module] if node.module else [])])


def imports(path: Path) -> list[tuple[str, bool]]:
    """(forcecal module imported, whether inside a function) of every import outside an
    ``if TYPE_CHECKING`` block; ``from pkg import submodule`` names the submodule."""
    out: list[tuple[str, bool]] = []

    def visit(node: ast.AST, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                continue
            inner = in_function or isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef)
            if isinstance(child, ast.ImportFrom):
                base = _target(path, child)
                for alias in child.names:
                    name = f"{base}.{alias.name}"
                    target = name if name in NAMES else base
                    if target.startswith("forcecal"):
                        out.append((target, in_function))
            elif isinstance(child, ast.Import):
                out.extend((a.name, in_function) for a in child.names
                           if a.name.startswith("forcecal"))
            visit(child, inner)

    visit(ast.parse(path.read_text(encoding="utf-8")), False)
    return out


def where(path: Path) -> str:
    return str(path.relative_to(PACKAGE))


def test_readme_layout_table_names_every_package_and_top_module():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    table = text[text.index("## Layout"):text.index("Accuracy and speed figures")]
    rows = [line for line in table.splitlines() if line.startswith("| `")]
    assert len(rows) <= 25, f"the layout table has {len(rows)} rows"
    named = set(re.findall(r"`([\w/.]+)`", table)) - {"src/forcecal/"}
    for path in PACKAGE.iterdir():
        if path.name.startswith(("_", ".")) or path.suffix not in ("", ".py"):
            continue
        if path.name in ("errors.py", "records.py", "provenance.py"):
            continue
        name = path.name + ("/" if path.is_dir() else "")
        assert name in named, f"README's layout table does not name {name}"
    for item in named:
        if item.endswith(("/", ".py")):
            assert (PACKAGE / item).exists() or list(PACKAGE.glob(f"*/{item}")), \
                f"README names {item}, which does not exist"


def test_every_package_says_which_stage_it_holds():
    for path in PACKAGE.rglob("*/__init__.py"):
        doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""
        assert re.search(r"(METHOD|INTERFACES)\.md", doc) or path.parent.name == "figures", \
            f"{where(path)}: its docstring names no stage of METHOD.md or INTERFACES.md"


def test_few_modules_at_the_top():
    top = [p.name for p in PACKAGE.glob("*.py")]
    assert len(top) <= MAX_TOP_LEVEL, sorted(top)


def test_no_module_outgrows_a_concept():
    big = {where(p): n for p in modules()
           if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_LINES}
    assert not big, f"modules above {MAX_LINES} lines: {big}"


def _code_lines(lines: list[str], fn: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    skip: set[int] = set()
    first = fn.body[0]
    if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) \
            and isinstance(first.value.value, str):
        skip = set(range(first.lineno, (first.end_lineno or first.lineno) + 1))
    return sum(1 for k in range(fn.lineno, (fn.end_lineno or fn.lineno) + 1)
               if k not in skip and lines[k - 1].strip()
               and not lines[k - 1].strip().startswith("#"))


def test_functions_are_short():
    long = []
    for p in modules():
        text = p.read_text(encoding="utf-8")
        lines = text.splitlines()
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and \
                    (n := _code_lines(lines, node)) > MAX_FUNCTION_CODE:
                long.append(f"{where(p)}:{node.lineno} {node.name} ({n} lines)")
    assert not long, long


FIGURE = re.compile(r"\d\s*%|\b(achieved|measured at|took)\s+[\d.]+|\d+(\.\d+)?\s*(ms|s)\b"
                    r" (on|per|for) ")
"""A measured figure: a percentage, an achieved value, a timing."""


def test_module_docstrings_are_short_and_quote_no_figures():
    bad = []
    for p in modules():
        doc = ast.get_docstring(ast.parse(p.read_text(encoding="utf-8"))) or ""
        if len(doc.splitlines()) > MAX_DOCSTRING:
            bad.append(f"{where(p)}: {len(doc.splitlines())} lines")
        if FIGURE.search(doc):
            bad.append(f"{where(p)}: quotes {FIGURE.search(doc).group(0)!r}")
    assert not bad, bad


def test_only_the_rig_parser_reads_a_structure_kind():
    offenders = []
    for p in modules():
        for k, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1):
            if re.search(r"\bkind\s*(==|!=)|\.kind\s+in\b", line) and p.name != "rig.py":
                offenders.append(f"{where(p)}:{k}: {line.strip()}")
    assert not offenders, offenders


DRIVE = re.compile(r"\brig\.drive\b|\bdrive\s*(==|!=)\s*[\"']|\.band\s+is\s+(not\s+)?None|"
                   r"\[[\"']drive[\"']\]")


def test_only_the_drives_read_the_drive():
    """The drive is read once (``forcecal.drives.drive_of``, from the rig the parser wrote);
    every command asks the drive. The broadband model reads the band's value it is built on."""
    offenders = []
    for p in modules():
        rel = where(p)
        if rel.startswith(DRIVE_READERS) or rel.startswith("simulate/"):
            continue
        for k, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1):
            code = line.split("#")[0]
            if DRIVE.search(code) and not code.strip().startswith(('"', "'")) \
                    and not (rel == "model/broadband.py" and "rig.band is None" in code):
                offenders.append(f"{rel}:{k}: {line.strip()}")
    assert not offenders, offenders


def _cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in edges.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            part = []
            while True:
                w = stack.pop()
                on.discard(w)
                part.append(w)
                if w == v:
                    break
            if len(part) > 1:
                found.append(sorted(part))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return found


def test_no_import_cycle_at_any_level():
    """Function-level imports included; a package's ``__init__`` re-exports are not edges."""
    edges = {module_name(p): {t for t, _ in imports(p) if t in NAMES
                              and NAMES[t].name != "__init__.py"}
             for p in modules() if p.name != "__init__.py"}
    assert not _cycles(edges), _cycles(edges)


def test_no_import_inside_a_function_outside_the_entry_points():
    offenders = [f"{where(p)} imports {t} in a function" for p in modules()
                 if not where(p).startswith(DEFERRED_OK) for t, inner in imports(p) if inner]
    assert not offenders, offenders


def test_the_core_imports_no_file_format_stream_or_figure_at_any_level():
    offenders = []
    for p in modules():
        if not where(p).startswith(CORE):
            continue
        for t, _ in imports(p):
            top = t.split(".")[1] if "." in t else ""
            if top in OUTSIDE_CORE:
                offenders.append(f"{where(p)} imports {t}")
    assert not offenders, offenders


def _all(path: Path) -> list[str]:
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        target = node.targets[0] if isinstance(node, ast.Assign) else \
            node.target if isinstance(node, ast.AnnAssign) else None
        if isinstance(target, ast.Name) and target.id == "__all__" and node.value is not None:
            return list(ast.literal_eval(node.value))
    return []


def test_the_public_api_is_small():
    assert len(forcecal.__all__) <= MAX_PUBLIC, len(forcecal.__all__)
    for name in forcecal.__all__:
        assert getattr(forcecal, name) is not None
    exported = sum(len(_all(p)) for p in modules())
    assert exported <= MAX_EXPORTED, f"{exported} names exported package-wide"


def test_the_command_line_entry_point_is_callable():
    """``[project.scripts] forcecal = "forcecal.cli:main"`` and ``python -m forcecal``."""
    from forcecal.cli import main

    assert callable(main)
    assert "forcecal.cli:main" in (ROOT / "pyproject.toml").read_text(encoding="utf-8")
