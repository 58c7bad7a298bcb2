"""What the commands print besides their files: the summary of ``calibrate``, the steps of
``demo`` whether or not stderr is a terminal, and ``-q``, silent on success but for the data a
command is asked to print."""

from __future__ import annotations

import importlib
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from forcecal.actuator import Calibration
from forcecal.campaign import CampaignResult
from forcecal.cli.main import main

cli_main = importlib.import_module("forcecal.cli.main")     # the module (forcecal.cli.main is
                                                            # also the name of its function)


def calibration(law: str = "k_i2_sfe2") -> Calibration:
    """A calibration of ``law`` with u(K) = 2.2e-09 N m^2/A^2."""
    params = {"k_i2_sfe2": [1.00491e-5, 5e-5], "k_i2_s2": [9.06016e-6]}[law]
    covariance = np.diag([2.2e-9, 1e-7][: len(params)]) ** 2
    return Calibration(law=law, params=np.array(params), covariance=covariance, n_poles=2,
                       current_range=(0.2, 1.0), gap_range=(0.0007, 0.0013))


def campaign(law: str = "k_i2_sfe2", held_out: float = 0.00109, uncertainty=None):
    """What the summary reads of a campaign's result (:class:`CampaignResult`)."""
    best = SimpleNamespace(held_out=SimpleNamespace(rms=held_out))
    result = SimpleNamespace(calibration=calibration(law), uncertainty=uncertainty,
                             selection=SimpleNamespace(best=best, candidates=(best,) * 4),
                             runs=())
    result.note_kinds = lambda: CampaignResult.note_kinds(result)
    return result


def test_the_calibration_summary_says_law_k_u_held_out_and_certificate():
    lines = cli_main._calibration_summary(campaign(), Path("cal"), certificate=True)
    assert lines == [
        "cal: law k_i2_sfe2, f = K i^2 / (s + s_fe)^2 (chosen of 4 candidate laws)",
        "  K = 1.00491e-05 ± 4.4e-09 N m^2/A^2 (expanded uncertainty U, k = 2; standard "
        "u = 2.2e-09)",
        "  held-out error 0.109 % (RMS relative error of the force predicted for runs left out "
        "of the fit)",
        f"  certificate: {Path('cal') / 'report.html'}",
    ]
    coverage = SimpleNamespace(coverage_factor=3.0)
    lines = cli_main._calibration_summary(campaign("k_i2_s2", uncertainty=coverage),
                                          Path("b") / "unit01", certificate=False)
    assert lines[1] == ("  K = 9.0602e-06 ± 6.6e-09 N m^2/A^2 (expanded uncertainty U, k = 3; "
                        "standard u = 2.2e-09)")                  # digits set by U
    assert lines[-1] == "  no certificate (--no-report)"


def _runs(*notes_per_run):
    return [SimpleNamespace(name=f"r{k}", estimate=SimpleNamespace(notes=tuple(notes)))
            for k, notes in enumerate(notes_per_run)]


def test_the_summary_says_the_runs_notes_once_per_kind_the_commonest_first():
    # the same note but for its numbers and its run is one kind; a check failing on every
    # run reads "3 of 3 runs"; beyond four kinds a count; none: no line
    weigh = "run 'a/r{}.csv': the tare 'a/tare.csv' reads {} N on the gauges"
    result = campaign()
    result.runs = _runs(*([weigh.format(k, 25.46 + k / 10), f"harmonic {5 + k}: no shape"]
                          for k in range(3)))
    lines = cli_main._notes_summary(result)
    assert lines[0] == ("  note (3 of 3 runs; 'r0'): the tare 'a/tare.csv' reads 25.46 N on the "
                        "gauges")
    assert lines[1] == "  note (3 of 3 runs; 'r0'): harmonic 5: no shape"
    assert lines[-1] == "  every run's notes: 'runs' in calibration.json"
    result.runs = _runs(*([f"kind {chr(97 + j)}" for j in range(k + 1)] for k in range(6)))
    lines = cli_main._notes_summary(result)
    assert lines[:2] == ["  note (6 of 6 runs; 'r0'): kind a", "  note (5 of 6 runs; 'r1'): kind b"]
    assert lines[4] == "  ... 2 more kinds of note"
    result.runs = _runs((), ())
    assert cli_main._notes_summary(result) == []
    full = cli_main._calibration_summary(result, Path("cal"), certificate=False)
    assert full[-1] == "  no certificate (--no-report)"


def test_demo_says_every_step_even_without_a_terminal(tmp_path, capsys, monkeypatch):
    def fake_demo(out, progress):
        for step in ("simulating", "  [1/2] run a", "  [2/2] run b"):
            progress(step)
        return out / "report" / "report.html"

    monkeypatch.setattr("forcecal.cli.demo.run_demo", fake_demo)
    monkeypatch.setattr(cli_main, "_interactive", lambda: False)
    assert main(["demo", str(tmp_path)]) == 0
    out, err = capsys.readouterr()
    assert err.splitlines()[:3] == ["simulating", "  [1/2] run a", "  [2/2] run b"]
    assert err.splitlines()[3].startswith("  done in ") and "\r" not in err
    assert out == f"report: {tmp_path / 'report' / 'report.html'}\n"
    assert main(["demo", str(tmp_path), "-q"]) == 0
    assert capsys.readouterr() == ("", "")


def test_quiet_keeps_only_the_data_asked_for(tmp_path, capsys):
    path = calibration().save(tmp_path / "calibration.json")
    argv = ["predict", str(path), "--current", "0.6", "--gap", "0.001"]
    assert main(argv) == 0
    shown = capsys.readouterr()
    assert main([*argv, "-q"]) == 0
    assert capsys.readouterr() == shown and shown.err == ""
    assert float(shown.out) == pytest.approx(2 * 1.00491e-5 * 0.36 / 0.00105**2, rel=1e-6)
    assert main(["schema", str(tmp_path / "rig.schema.json"), "-q"]) == 0   # a file: silent
    assert capsys.readouterr() == ("", "") and (tmp_path / "rig.schema.json").is_file()
    assert main(["schema", "--keys", "-q"]) == 0                  # asked for on stdout: kept
    assert "acquisition.frequency" in capsys.readouterr().out
