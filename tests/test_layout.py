"""The package's layout keeps its promises: the README's table names every stage module, no
module outgrows a reader, only the rig parser reads a structure's kind, and the core never
imports the file formats, the figures or the command line."""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "forcecal"
MAX_LINES = 600
"""A module above this many lines does more than one job (largest today: about 500)."""
INFRASTRUCTURE = {"__init__.py", "__main__.py", "errors.py", "records.py", "demo.py",
                  "_toml.py", "_version.py", "_atomic.py", "_schema.py"}
"""Top-level modules that are not a stage of the method (exceptions, data containers, the demo
driver, private helpers)."""
OUTSIDE_CORE = ("io", "report", "cli", "simulate", "demo")
"""Subpackages and modules the core must not import."""


def modules() -> list[Path]:
    return sorted(PACKAGE.rglob("*.py"))


def test_readme_layout_table_names_every_stage_module():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    table = text[text.index("## Layout"):text.index("Accuracy and speed figures")]
    named = set(re.findall(r"`([\w/.]+)`", table)) - {"src/forcecal/"}
    files = {p.name for p in modules()}
    for item in sorted(named):
        if item.endswith(("/", ".py")):
            assert (PACKAGE / item).exists() or item in files, \
                f"README names {item}, which does not exist"
    for path in PACKAGE.iterdir():
        name = path.name + ("/" if path.is_dir() else "")
        if path.name in INFRASTRUCTURE or path.name.startswith((".", "__")) \
                or path.suffix not in ("", ".py"):
            continue
        assert name in named, f"README's layout table does not name {name}"


def test_no_module_outgrows_a_reader():
    sizes = {p.relative_to(PACKAGE): len(p.read_text(encoding="utf-8").splitlines())
             for p in modules()}
    big = {str(p): n for p, n in sizes.items() if n > MAX_LINES}
    assert not big, f"modules above {MAX_LINES} lines: {big}"


def test_only_the_rig_parser_reads_a_structure_kind():
    offenders = []
    for p in modules():
        for k, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1):
            if re.search(r"\bkind\s*(==|!=)|\.kind\s+in\b", line) and p.name != "rig.py":
                offenders.append(f"{p.relative_to(PACKAGE)}:{k}: {line.strip()}")
    assert not offenders, offenders


def imported_modules(path: Path) -> set[str]:
    """Top-level forcecal names a module imports (relative imports resolved)."""
    rel = path.relative_to(PACKAGE).with_suffix("").parts
    depth = len(rel) - 1
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = list(rel[:depth - node.level + 1]) if node.level <= depth + 1 else []
                target = base + (node.module.split(".") if node.module else [])
                if not target and node.names:
                    target = [node.names[0].name]
                if target:
                    out.add(target[0])
            elif node.module and node.module.startswith("forcecal."):
                out.add(node.module.split(".")[1])
        elif isinstance(node, ast.Import):
            out |= {a.name.split(".")[1] for a in node.names if a.name.startswith("forcecal.")}
    return out


def test_the_core_imports_no_file_format_figure_or_command_line():
    offenders = []
    for p in modules():
        top = p.relative_to(PACKAGE).parts[0].removesuffix(".py")
        if top in OUTSIDE_CORE or top in ("campaign", "__main__", "stream", "api") or \
                (p.name == "__init__.py" and p.parent == PACKAGE):
            continue
        bad = imported_modules(p) & set(OUTSIDE_CORE)
        if bad:
            offenders.append(f"{p.relative_to(PACKAGE)} imports {sorted(bad)}")
    # the stream's kernel and estimator are core; its replay driver may write files
    for name in ("rls.py", "estimator.py"):
        bad = imported_modules(PACKAGE / "stream" / name) & set(OUTSIDE_CORE)
        if bad:
            offenders.append(f"stream/{name} imports {sorted(bad)}")
    assert not offenders, offenders
