"""The tare against the rig's weight (``forces.weight``): the weight the gauges carry at rest,
the check's silence on a clean lab tare and the mistakes it names (the false-alarm rate over
1000 seeds and what it catches are in ``benchmarks/weight.py``)."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pandas as pd
import pytest

from forcecal.api import reconstruct
from forcecal.forces.steady import reconstruct as steady_reconstruct
from forcecal.forces.weight import current_rms, weight_chi_square, weight_notes, weight_parts
from forcecal.records import Run
from forcecal.rig import Weight
from forcecal.simulate.lab import gravity_preload
from forcecal.simulate.presets import get_preset, with_realism
from forcecal.simulate.virtual_rig import build_model, public_rig


@pytest.mark.parametrize("name", ["paper", "plate", "body"])
def test_the_rigs_weight_on_each_gauge_is_the_finite_element_models_preload(name):
    # the simulator's preload: its consistent mass matrix on the gauges' relaxation modes;
    # forcecal's: its own quadrature of the rig file's masses (achieved: 1e-15 relative)
    preset = with_realism(get_preset(name), "lab")
    rig = public_rig(preset)
    assert rig.weight == Weight(gravity=9.81, gauge_zero=0.5)
    expected = gravity_preload(preset, build_model(preset), 9.81)
    got = sum(e for _, e in weight_parts(rig))
    assert np.allclose(got, expected, rtol=0.0, atol=1e-9 * np.abs(expected).sum())
    # the vertical gauges carry the whole weight (the body's last three lie horizontal)
    vertical = got if name != "body" else got[:3]
    assert vertical.sum() == pytest.approx(rig.structure.total_mass * 9.81, rel=1e-9)


def _note(rig, tare, run) -> str:
    notes = weight_notes(rig, tare, current_rms(rig, run), "run")
    assert len(notes) == 1, notes
    return notes[0]


def _size(note: str, cause: str) -> float:
    found = re.search(re.escape(cause) + r" off by ([-+][\d.e+]+) (%|N)", note)
    assert found, (cause, note)
    return float(found.group(1))


def test_a_clean_tare_is_silent_and_a_mistaken_mass_or_zero_is_named(random_lab):
    rig, _, run, tare, _ = random_lab
    chi2, dof = weight_chi_square(rig, tare)
    assert dof == 2 and chi2 < 13.8                    # the 1e-3 quantile (achieved 1.74)
    assert weight_notes(rig, tare, current_rms(rig, run), "run") == []
    # the distributed mass 30 % high in the rig (achieved +25.3 %: the zeros' 0.7 N on a 22 N
    # weight); a lumped mass of 17 times its value explains as well and is not named
    heavy = dataclasses.replace(rig, structure=rig.structure.with_masses(distributed=1.3))
    note = _note(heavy, tare, run)
    assert 20.0 < _size(note, "structure.mass_per_length") < 40.0
    assert "0.593 kg less than the rig's masses" in note and "masses[0]" not in note
    # 3 N on the first gauge's zero (achieved +3.18 N, beside its scale +25.8 %: alike)
    channels = dict(tare.channels)
    channels["R1"] = channels["R1"] + 3.0 / rig.gauges[0].scale
    note = _note(rig, dataclasses.replace(tare, channels=channels), run)
    assert 2.0 < _size(note, "gauge 'R1' zero (its reading without the structure)") < 4.0
    assert "cannot tell the first 2 apart" in note
    # a record with current is no weight: the run given as its own tare is not weighed
    assert weight_notes(heavy, run, current_rms(rig, run), "run") == []
    assert weight_notes(heavy, tare, None, "run") == []                # nothing to compare with
    # a rig that does not say its gauges read the weight is not checked
    assert weight_notes(dataclasses.replace(heavy, weight=None), tare, 1.0, "run") == []


def test_the_estimate_under_any_drive_carries_the_note(random_lab):
    # a tare whose first gauge read 3 N more: the forces, zeroed by it, carry its note
    rig, model, run, tare, _ = random_lab
    channels = dict(tare.channels)
    channels["R1"] = channels["R1"] + 3.0 / rig.gauges[0].scale
    shifted = dataclasses.replace(tare, channels=channels)
    said = [n for n in reconstruct(rig, model, run, tare=shifted).notes
            if "the rig's masses weigh" in n]
    assert len(said) == 1 and "gauge 'R1' zero" in said[0]


def test_a_steady_estimate_weighs_its_tare_unless_the_gauges_are_ac_coupled(paper):
    # the ideal 'paper' rig said to read its weight with a tare of zeros (it has no gravity):
    # 24.6 N missing, noted; AC-coupled gauges (piezoelectric) read no weight: not checked
    rig, _, model, run = paper
    weighed = dataclasses.replace(rig, weight=Weight(gravity=9.81, gauge_zero=0.05))
    rng = np.random.default_rng(4)
    tare = dataclasses.replace(run, name="tare", source="tare.csv", channels={
        c: 1e-3 * rng.standard_normal(run.n_samples) for c in run.channels})

    def said(**options):
        return [n for n in steady_reconstruct(weighed, model, run, tare=tare, **options).notes
                if "the rig's masses weigh" in n]

    assert len(said()) == 1 and "2.51 kg less than the rig's masses" in said()[0]
    assert said(ac_coupled=True) == []


def test_the_stream_weighs_its_tare_against_the_scans_drive(random_lab, tmp_path, capsys):
    # as reconstruct: a tare 3 N off on its first gauge is noted before the stream writes; a
    # clean one is silent (a record with current as the tare: the unit test above)
    from forcecal.cli.main import main

    rig, _, _, _, out = random_lab
    frame = pd.read_csv(out / "runs" / "tare.csv")
    frame["R1"] = frame["R1"] + 3.0 / rig.gauges[0].scale
    frame.to_csv(tmp_path / "tare3.csv", index=False)
    said = {}
    for name, tare in (("shifted", tmp_path / "tare3.csv"), ("clean", out / "runs" / "tare.csv")):
        assert main(["stream", str(out / "rig.toml"), str(out / "model.json"),
                     str(out / "runs" / "random.csv"), "--tare", str(tare), "-o",
                     str(tmp_path / f"{name}.csv")]) == 0
        said[name] = [line for line in capsys.readouterr().err.splitlines()
                      if "the rig's masses weigh" in line]
    assert len(said["shifted"]) == 1 and "gauge 'R1' zero" in said["shifted"][0]
    assert said["clean"] == []


def test_the_chi_square_has_its_degrees_of_freedom_when_every_stated_error_is_drawn():
    # 600 tares of the lab beam, each drawing what the covariance states: the gauges' zeros
    # (0.5 N), their gains (0.5 %), the distributed and the lumped mass (5 % each, so that
    # they count) and white noise on the record; the chi-square's mean is its 2 degrees of
    # freedom (achieved 1.94; test 1.7-2.3, 4 standard errors). Without the masses' term it
    # reads 4.28, with the zeros' variance halved 3.06
    preset = with_realism(get_preset("paper"), "lab")
    base = public_rig(preset)
    rig = dataclasses.replace(base, type_b=dataclasses.replace(base.type_b, mass=0.05))
    parts = np.array([e for _, e in weight_parts(rig)])                  # (n_parts, n_g)
    rng = np.random.default_rng(12)
    names = [g.name for g in rig.gauges]
    chi2 = []
    for _ in range(600):
        weight = (1 + 0.05 * rng.standard_normal(len(parts))) @ parts
        read = (1 + 0.005 * rng.standard_normal(2)) * weight + 0.5 * rng.standard_normal(2)
        tare = Run(channels={**{n: r + 0.01 * rng.standard_normal(200)
                                for n, r in zip(names, read, strict=True)},
                             rig.actuator.current: np.zeros(200)}, fs=1000.0)
        chi2.append(weight_chi_square(rig, tare)[0])
    assert 1.7 < np.mean(chi2) < 2.3, np.mean(chi2)
