"""Bad arguments point to the help of the command they were given to.

Every argument error exits with status 2 and one line on stderr, ``forcecal CMD: ... (see
'forcecal CMD --help')``, whether argparse finds it (an unknown argument, a missing one, a
value of the wrong type) or the command does (a range, a path); nothing is written. Only an
error before any command (none, an unknown one) points to ``forcecal --help``.
"""

from __future__ import annotations

import pytest

from forcecal.cli.main import main

ENOUGH = {  # arguments each command parses (the files need not exist: nothing gets that far)
    "demo": ["out"],
    "simulate": ["out"],
    "scan": ["rig.toml", "scan.uff", "-o", "model.json"],
    "reconstruct": ["rig.toml", "model.json", "run.csv", "-o", "out"],
    "calibrate": ["rig.toml", "scan.uff", "--manifest", "manifest.csv", "-o", "out"],
    "predict": ["calibration.json", "--current", "1", "--gap", "0.001"],
    "stream": ["rig.toml", "model.json", "run.csv", "-o", "out.csv"],
    "report": ["rig.toml", "scan.uff", "run.csv", "-o", "out"],
}


def refused(argv: list[str], capsys, folder) -> str:
    """Exit 2, nothing on stdout, one line on stderr, nothing written; that line."""
    code = main(argv)
    out, err = capsys.readouterr()
    assert code == 2, err
    assert out == ""
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert list(folder.iterdir()) == []
    return lines[0]


def points_to_its_help(line: str, command: str) -> None:
    assert line.startswith(f"forcecal {command}: "), line
    assert line.endswith(f"(see 'forcecal {command} --help')"), line


@pytest.fixture(autouse=True)
def in_empty_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


def test_two_gaps_point_to_predicts_help(tmp_path, capsys):
    line = refused(["predict", "calibration.json", "--current", "1", "--gap", "0.001",
                    "0.0011"], capsys, tmp_path)
    assert line == ("forcecal predict: unrecognized arguments: 0.0011 "
                    "(see 'forcecal predict --help')")


@pytest.mark.parametrize("command", list(ENOUGH))
def test_an_unknown_argument_points_to_the_commands_help(command, tmp_path, capsys):
    line = refused([command, *ENOUGH[command], "--frobnicate", "3"], capsys, tmp_path)
    points_to_its_help(line, command)
    assert "unrecognized arguments: --frobnicate 3" in line


@pytest.mark.parametrize("command", [c for c in ENOUGH if c != "demo"])
def test_a_missing_argument_points_to_the_commands_help(command, tmp_path, capsys):
    line = refused([command], capsys, tmp_path)
    points_to_its_help(line, command)
    assert "the following arguments are required" in line


@pytest.mark.parametrize(("argv", "named"), [
    (["predict", "calibration.json", "--current", "lots", "--gap", "0.001"], "--current"),
    (["simulate", "out", "--seed", "one"], "--seed"),
    (["scan", "rig.toml", "scan.uff", "-o", "model.json", "--criterion", "aic"], "--criterion"),
    (["reconstruct", *ENOUGH["reconstruct"], "--harmonics", "0"], "--harmonics"),
    (["simulate", "out", "--seed", "-1"], "--seed"),
    (["scan", "rig.toml", "scan.uff", "-o", ""], "-o/--output"),
    (["stream", *ENOUGH["stream"], "--block", "0"], "--block"),
    (["reconstruct", *ENOUGH["reconstruct"], "--monte-carlo", "5"], "--monte-carlo"),
    (["stream", "rig.toml", "model.json", "run.csv", "-o", "out.mat"], "-o/--output"),
    (["report", *ENOUGH["report"], "--truth", "nowhere"], "--truth"),
], ids=["not-a-number", "not-an-integer", "not-a-choice", "harmonics", "seed", "empty-output",
        "block", "monte-carlo", "stream-output", "truth"])
def test_a_bad_value_points_to_the_commands_help(argv, named, tmp_path, capsys):
    line = refused(argv, capsys, tmp_path)
    points_to_its_help(line, argv[0])
    assert f"argument {named}" in line, line


@pytest.mark.parametrize("argv", [[], ["frobnicate"],
                                  ["--frobnicate", "predict", *ENOUGH["predict"]]],
                         ids=["no-command", "unknown-command", "option-before-the-command"])
def test_errors_before_any_command_point_to_the_top_help(argv, tmp_path, capsys):
    line = refused(argv, capsys, tmp_path)
    assert line.startswith("forcecal: ") and line.endswith("(see 'forcecal --help')"), line


@pytest.mark.parametrize("command", list(ENOUGH))
def test_the_help_pointed_to_is_the_commands_usage(command, capsys):
    assert main([command, "--help"]) == 0
    assert capsys.readouterr().out.startswith(f"usage: forcecal {command} ")
