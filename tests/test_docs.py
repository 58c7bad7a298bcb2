"""Every command the documentation shows works as shown.

Each ```console block of docs/*.md is scanned for lines ``$ forcecal ...`` (a trailing ``\\``
continues a command on the next line). The commands of one document run in order, through
:func:`forcecal.cli.main`, in one scratch folder, so a later command may use what an earlier one
wrote. A command must exit with status 0, unless the document marks it with a trailing
``# exits 2``: then it must exit with status 2 and say why in one line on stderr.
"""

from __future__ import annotations

import json
import re
import shlex
from dataclasses import dataclass
from pathlib import Path

import pytest

from forcecal.cli.main import main

DOCS = Path(__file__).resolve().parents[1] / "docs"
FAILS = re.compile(r"#\s*exits\s+(\d+)\s*$")


@dataclass(frozen=True)
class Command:
    doc: str
    line: int
    argv: tuple[str, ...]
    status: int

    @property
    def id(self) -> str:
        return f"{self.doc}:{self.line}:{' '.join(self.argv[:2])}"


def console_commands(text: str, doc: str) -> list[Command]:
    """The ``$ forcecal`` commands of the ```console blocks of one Markdown text."""
    commands = []
    in_console = False
    pending: tuple[int, str] | None = None
    for number, line in enumerate(text.splitlines(), start=1):
        fence = line.strip()
        if fence.startswith("```"):
            in_console = not in_console and fence[3:].strip() == "console"
            pending = None
            continue
        if not in_console:
            continue
        if pending is not None:
            start, joined = pending
            line = joined + " " + line.strip()
            number = start
        elif not line.startswith("$ forcecal"):
            continue
        if line.rstrip().endswith("\\"):
            pending = (number, line.rstrip()[:-1].rstrip())
            continue
        pending = None
        command = line[2:].strip()
        marked = FAILS.search(command)
        argv = shlex.split(command, comments=True)
        commands.append(Command(doc, number, tuple(argv[1:]),
                                int(marked.group(1)) if marked else 0))
    return commands


def all_commands() -> list[Command]:
    return [c for path in sorted(DOCS.glob("*.md"))
            for c in console_commands(path.read_text(encoding="utf-8"), path.name)]


COMMANDS = all_commands()


def test_the_parser_reads_console_blocks():
    text = "\n".join([
        "```console",
        "$ forcecal scan rig.toml 'a b.uff' -o m.json",
        "m.json: fundamental 20 Hz",
        "$ forcecal reconstruct rig.toml m.json \\",
        "    r.csv -o out",
        "$ forcecal predict cal.json --current 1  # exits 2",
        "$ ls out",
        "```",
        "```",
        "$ forcecal demo",
        "```",
    ])
    found = console_commands(text, "x.md")
    assert [(c.line, c.argv, c.status) for c in found] == [
        (2, ("scan", "rig.toml", "a b.uff", "-o", "m.json"), 0),
        (4, ("reconstruct", "rig.toml", "m.json", "r.csv", "-o", "out"), 0),
        (6, ("predict", "cal.json", "--current", "1"), 2),
    ]


def test_the_guide_shows_commands():
    guide = [c for c in COMMANDS if c.doc == "guide.md"]
    shown = {c.argv[0] for c in guide}
    assert {"simulate", "scan", "reconstruct", "calibrate", "predict"} <= shown
    assert any(c.status == 2 for c in guide)


@pytest.fixture(scope="module")
def workspaces(tmp_path_factory):
    """doc name -> [scratch folder, reason the later commands cannot run or None]."""
    spaces: dict[str, list] = {}

    def get(doc: str) -> list:
        if doc not in spaces:
            spaces[doc] = [tmp_path_factory.mktemp(doc.replace(".", "_")), None]
        return spaces[doc]

    return get


@pytest.mark.parametrize("command", COMMANDS, ids=[c.id for c in COMMANDS])
def test_documented_command(command, workspaces, monkeypatch, capsys):
    space = workspaces(command.doc)
    if space[1]:
        pytest.skip(space[1])
    monkeypatch.chdir(space[0])
    space[1] = f"{command.id} failed"
    status = main(list(command.argv))
    err = capsys.readouterr().err
    assert status == command.status, err
    if command.status == 2:
        assert len(err.splitlines()) == 1, err
    if command.doc == "guide.md" and command.argv[:1] == ("calibrate",) and "-o" in command.argv:
        out = Path(command.argv[command.argv.index("-o") + 1])
        if (out / "calibration.json").is_file():
            check_shown_candidates(out / "calibration.json")
    space[1] = None


ROW = re.compile(r"^(\w+)\s+(\d+)\s+([\d.]+)\s+([\d.]+)\s+(-?[\d.]+)\s+(-?[\d.]+)(\s+<- chosen)?$")


def check_shown_candidates(calibration: Path) -> None:
    """The guide's table of candidate laws (section 1.4) is what its `calibrate` computes, to
    the digits shown."""
    shown = [ROW.match(line) for line in (DOCS / "guide.md").read_text().splitlines()]
    rows = {m[1]: m for m in shown if m}
    computed = json.loads(calibration.read_text())
    computed["candidates"] = [c for c in computed["candidates"] if "skipped" not in c]
    table = []
    for c in computed["candidates"]:
        table.append(f"{c['law']:<10}{len(c['params']):>3}  {100 * c['rms_residual']:9.4f}  "
                     f"{100 * c['held_out']:10.4f}  {c['aic']:10.1f}  {c['bic']:10.1f}")
    assert set(rows) == {c["law"] for c in computed["candidates"]}, "\n".join(table)
    for c in computed["candidates"]:
        m = rows[c["law"]]
        got = (float(m[3]), float(m[4]), float(m[5]), float(m[6]))
        want = (100 * c["rms_residual"], 100 * c["held_out"], c["aic"], c["bic"])
        assert all(abs(g - w) <= tol for g, w, tol in zip(got, want, (6e-5, 6e-5, 0.06, 0.06),
                                                        strict=True)), "\n".join(table)
        assert bool(m[7]) == (c["law"] == computed["law"]), c["law"]
