"""Self-checks (forcecal.forces.diagnostics): each fires when the mistake is made on purpose on the
virtual rig, and none fires on the clean presets."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from forcecal.errors import DataError, RigError
from forcecal.forces.diagnostics import mains_notes
from forcecal.forces.estimate import waveform_std_series
from forcecal.forces.steady import implied_phasors, reconstruct, solve_inputs
from forcecal.model.spatial import build_spatial_model
from forcecal.records import Run
from forcecal.rig import parse_rig, rig_to_dict
from forcecal.signals.mains import hum_variance, on_mains
from forcecal.simulate.magnet import Drive, Magnet, Pole
from forcecal.simulate.presets import RunSpec, ScanSpec, get_preset
from forcecal.simulate.virtual_rig import (
    build_model,
    measure_run,
    measure_scan,
    public_rig,
    scan_response,
    simulate_response,
)

CHECKS = ("disagree with the scan model's shape", "pushes", "far from the",
          "drifts within the record")
"""The phrases of the self-checks' notes."""


def self_check_notes(estimate) -> list[str]:
    return [n for n in estimate.notes if any(c in n for c in CHECKS)]


def edited(rig, edit):
    doc = rig_to_dict(rig)
    edit(doc)
    return parse_rig(doc, source="edited.toml")


@pytest.mark.parametrize("preset", ["paper", "resonance", "plate"])
def test_no_self_check_fires_on_a_clean_preset(preset, paper):
    if preset == "paper":
        rig, _, model, run = paper
    else:
        p = get_preset(preset)
        fe = build_model(p)
        rng = np.random.default_rng(5)
        rig = public_rig(p)
        model = build_spatial_model(rig, measure_scan(p, fe, scan_response(p, fe), rng))
        spec = p.runs[0]
        r = simulate_response(p, spec.drives, spec.gap, spec.duration, fe)
        run = measure_run(p, spec, fe, r, rng)
    assert self_check_notes(reconstruct(rig, model, run)) == []


def test_a_gauge_with_the_wrong_sign_is_noticed(paper):
    """R1's scale flipped: the magnet seems to push, and its DC contradicts the current."""
    rig, _, model, run = paper

    def flip(doc):
        doc["gauges"][0]["scale"] = -1.0

    notes = self_check_notes(reconstruct(edited(rig, flip), model, run))
    assert any("pushes" in n for n in notes) or any("far from the" in n for n in notes), notes


def test_a_probe_with_the_wrong_sign_is_noticed(paper):
    rig, _, model, run = paper

    def flip(doc):
        doc["sensors"][1]["scale"] = -1.0

    notes = self_check_notes(reconstruct(edited(rig, flip), model, run))
    assert any("s1, s2 disagree" in n and "harmonic 1" in n for n in notes), notes


@pytest.mark.parametrize(("drift", "refused"), [(0.005, False), (0.15, True)])
def test_a_drifting_drive_is_noticed(paper, drift, refused):
    """The paper run's phasors replayed with a frequency that drifts over the record: a note
    at 0.5 %; at 15 % no single fundamental fits, and the refusal blames the drift, not the
    rig's nominal frequency."""
    rig, _, model, run = paper
    est = reconstruct(rig, model, run)
    phasors = implied_phasors(rig, model, run, est)
    t = run.time - run.t0
    duration = t[-1]
    f0 = est.f0
    cycles = f0 * t + drift * f0 * t**2 / (2 * duration)
    h = len(est.harmonics) - 1
    rot = np.exp(2j * np.pi * np.outer(np.arange(h + 1), cycles))
    rng = np.random.default_rng(2)
    channels = {name: (x @ rot).real + 1e-3 * np.std((x @ rot).real)
                * rng.standard_normal(t.size) for name, x in phasors.items()}
    drifting = Run(channels=channels, fs=run.fs, name="drift", source="drift.csv")
    if refused:
        with pytest.raises(DataError, match="drifts within the record"):
            reconstruct(rig, model, drifting)
        return
    notes = self_check_notes(reconstruct(rig, model, drifting))
    assert any("drifts within the record" in n for n in notes), notes


@pytest.fixture(scope="module")
def two_coils():
    """The paper beam with two magnets on their own coils; scanned with coil B at 40 % of
    coil A's drive, then run with coil B at 120 % and shifted in phase (a coil changed)."""
    p = get_preset("paper")
    f = p.runs[0].drives[0].frequency
    left = Magnet(poles=(Pole("FA", 0.2, 1.0e-3),), current_channel="ia",
                  flux_channel="phia", voltage_channel="va")
    right = Magnet(poles=(Pole("FB", 0.42, 1.0e-3),), current_channel="ib",
                   flux_channel="phib", voltage_channel="vb")
    scan_drives = (Drive("current", 0.5, 0.25, f), Drive("current", 0.2, 0.1, f))
    run_drives = (Drive("current", 0.5, 0.25, f), Drive("current", 0.6, 0.3, f, phase=1.5))
    preset = dataclasses.replace(p, magnets=(left, right), scan=ScanSpec(drives=scan_drives),
                                 runs=(RunSpec("changed", drives=run_drives, duration=1.0),))
    fe = build_model(preset)
    rng = np.random.default_rng(4)
    rig = public_rig(preset)
    model = build_spatial_model(rig, measure_scan(preset, fe, scan_response(preset, fe), rng))
    spec = preset.runs[0]
    run = measure_run(preset, spec, fe, simulate_response(preset, spec.drives, None,
                                                          spec.duration, fe), rng)
    return rig, model, run


def test_a_load_changed_since_the_scan_is_noticed(two_coils):
    rig, model, run = two_coils
    notes = self_check_notes(reconstruct(rig, model, run))
    assert any("disagree with the scan model's shape" in n for n in notes), notes


# --------------------------------------------------------------------------------------------
# a drive harmonic on a mains harmonic


def test_a_harmonic_on_a_mains_harmonic_is_noted():
    kept = np.array([True, True, True, True])
    notes = mains_notes(50.0, 149.94, kept, 1.0, "run 'body'")
    assert len(notes) == 3                  # 149.94, 299.88, 449.82 Hz: 150, 300, 450 Hz
    assert "harmonic 1 (149.94 Hz) lies 0.06 Hz from the mains' harmonic 3 (150 Hz)" in notes[0]
    assert "not in its uncertainty" in notes[0]
    assert mains_notes(50.0, 149.0, kept, 0.1, "run 'x'") == []     # 1 Hz away, 3 lines 0.3 Hz
    assert mains_notes(None, 150.0, kept, 1.0, "run 'x'") == []
    assert mains_notes(50.0, 150.0, np.array([True, False]), 1.0, "run 'x'") == []  # not kept


def test_reconstruct_notes_the_mains_the_rig_declares(paper, tmp_path):
    rig, _, model, run = paper
    doc = rig_to_dict(rig)
    doc.setdefault("acquisition", {})["mains"] = 60.0
    sixty = parse_rig(doc, source="sixty.toml")
    assert sixty.mains == 60.0 and rig_to_dict(sixty)["acquisition"]["mains"] == 60.0
    notes = reconstruct(sixty, model, run).notes
    assert [n for n in notes if "mains' harmonic 1 (60 Hz)" in n and "harmonic 3 " in n]
    assert not [n for n in reconstruct(rig, model, run).notes if "mains" in n]
    doc["acquisition"]["mains"] = 0.05
    with pytest.raises(RigError, match=r"acquisition\.mains' = 0.05 Hz is not a mains"):
        parse_rig(doc, source="bad.toml")


def test_the_lab_rig_declares_its_mains():
    assert public_rig(get_preset("paper", "lab")).mains == 50.0
    assert public_rig(get_preset("paper")).mains is None


def test_the_hum_on_a_drive_harmonic_is_read_from_the_tare():
    """The tare holds the hum alone: its power at the mains harmonic, the noise's share taken
    out, becomes the variance of Re and Im of the run's phasor on it (a tone of unknown phase);
    a channel without hum (its tare phasor within the noise) gains nothing, nor do harmonics
    off the mains."""
    fs, mains, f0 = 2048.0, 50.0, 149.94
    rng = np.random.default_rng(3)
    t = np.arange(2048) / fs
    sigma, a = 0.01, 0.2
    tare = sigma * rng.standard_normal((2, t.size))
    tare[0] += a * np.sin(2 * np.pi * 150.0 * t + 0.7)          # channel 0 hums, 1 does not
    pairs = on_mains(mains, f0, range(1, 5), fs / t.size)
    assert set(pairs) == {1, 2, 3}                               # 150, 300, 450 Hz
    var, read = hum_variance(tare, fs, mains, pairs, 4, t.size, fs)
    assert read == {1, 2, 3}
    # achieved: 0.01984 (a^2 / 2 = 0.02; the 0.06 Hz gap leaks 99.4 % in amplitude over 1 s)
    assert var[0, 1] == pytest.approx(a**2 / 2, rel=0.03)
    assert var[1, 1] == 0 and np.all(var[:, [0, 4]] == 0)      # noise alone is not hum
    assert var[0, 2] == 0                                          # no hum at 300 Hz
    counted = mains_notes(mains, f0, np.ones(5, bool), fs / t.size, "run 'x'", frozenset(pairs))
    assert "read from the tare record" in counted[0]


def test_reconstruct_counts_the_tare_hum_on_a_drive_harmonic():
    """The paper rig's n = 3 (60.04 Hz) on 60 Hz mains: hum on the probes, in the run and in a
    zero-current tare (each channel its own phase), widens the stated std at n = 3 by the hum
    the tare shows, and there only, and covers the error the hum causes; without the tare it
    is only noted (and only the probes' misfit inflation, if any, widens the std)."""
    p = get_preset("paper")
    fe = build_model(p)
    rng = np.random.default_rng(5)
    rig = dataclasses.replace(public_rig(p), mains=60.0)
    model = build_spatial_model(rig, measure_scan(p, fe, scan_response(p, fe), rng))
    spec = p.runs[0]
    run = measure_run(p, spec, fe, simulate_response(p, spec.drives, spec.gap, spec.duration,
                                                     fe), rng)
    t = np.arange(run.channels[rig.sensor_names[0]].size) / run.fs
    hum = 10 * p.noise.probe                              # per sample; its phasor stands out

    def hummed(channels, quiet=False):
        level = {**{g: p.noise.gauge for g in rig.gauge_names},
                 **{s: p.noise.probe for s in rig.sensor_names}}
        out = {k: (level.get(k, 1e-4) * rng.standard_normal(v.size) if quiet else v)
               for k, v in channels.items()}
        for s in rig.sensor_names:
            out[s] = out[s] + hum * np.sin(2 * np.pi * 60.0 * t + rng.uniform(0, 2 * np.pi))
        return out

    run_h = dataclasses.replace(run, channels=hummed(run.channels))
    tare = dataclasses.replace(run, channels=hummed(run.channels, quiet=True))
    clean = reconstruct(rig, model, run)
    without = reconstruct(rig, model, run_h)
    with_tare = reconstruct(rig, model, run_h, tare=tare)
    assert without.kept[3] and with_tare.kept[3]
    assert any("not in its uncertainty" in n for n in without.notes)
    assert any("read from the tare record" in n for n in with_tare.notes)
    grown = with_tare.combination_std[:, 3] / clean.combination_std[:, 3]
    assert np.all(grown > 90), grown                      # achieved 267-447: the hum counted
    np.testing.assert_allclose(with_tare.combination_std[:, 1:3], without.combination_std[:, 1:3],
                               rtol=1e-9)
    # the hum's error (against the hum-free run's estimate) within the widened std: achieved
    # |error| = 0.48 std in this draw
    err = np.abs(with_tare.combination[:, 3] - clean.combination[:, 3])
    assert np.all(err < 3 * np.sqrt(2) * with_tare.combination_std[:, 3]), err
    # the Monte Carlo (--monte-carlo) draws the probes' phasors with the same widened std
    drawn = solve_inputs(rig, model, run_h, with_tare, tare).sensor_std[:, 3]
    plain = solve_inputs(rig, model, run_h, without).sensor_std[:, 3]
    assert np.all(drawn > 10 * plain), (drawn, plain)


def test_harmonics_left_out_are_said_and_counted_in_the_waveform(paper):
    """Estimated to harmonic 1 where the reactions show 2 and 3: a note, and their RMS by the
    reactions alone in the waveform's uncertainty (achieved: 1.56 times the full estimate's
    own harmonics 2 and 3, whose inertia the reactions alone lack; bounds 1 to 2.5)."""
    rig, _, model, run = paper
    full = reconstruct(rig, model, run)
    cut = reconstruct(rig, model, run, n_harmonics=1)
    said = [n for n in cut.notes if "leave them out" in n]
    assert len(said) == 1 and "harmonics 2, 3 of the reactions" in said[0], cut.notes
    assert cut.force.shape[1] == 2 and full.dropped_rms is None
    assert not any("leave them out" in n for n in full.notes)
    shown = np.sqrt(np.sum(np.abs(full.total[2:4]) ** 2) / 2)
    assert 1.0 < cut.dropped_rms[-1] / shown < 2.5
    assert cut.waveform_std == pytest.approx(
        np.hypot(cut.dropped_rms[-1], np.sqrt(np.sum(cut.total_std[1:] ** 2))), rel=0.01)
    per_sample = waveform_std_series(cut)      # each force's and the total's, at mid-record
    floor = np.sqrt(np.sum(np.vstack([cut.force_std, cut.total_std]) ** 2, axis=1)
                    + cut.dropped_rms**2)
    np.testing.assert_allclose(per_sample.min(axis=1), floor, rtol=1e-3)


def test_a_wrong_nominal_frequency_on_a_short_run_is_taken_from_the_scan(paper):
    """The rig's acquisition.frequency 10 % off and a run of ten periods: the fundamental
    locks onto a side lobe from the nominal one (3.6 % off), and fits the record worse than
    the scan model's; it is taken there, with a note naming the key (achieved: the scan's
    fundamental to 2e-5, the forces as from the right nominal frequency to 1e-6 N)."""
    rig, _, model, run = paper
    half = Run(channels={k: v[: run.n_samples // 2] for k, v in run.channels.items()},
               fs=run.fs, t0=run.t0, name=run.name, source="half.csv")
    wrong = dataclasses.replace(rig, frequency=1.1 * rig.drive_frequency)
    est = reconstruct(wrong, model, half)
    said = [n for n in est.notes if "the rig's key is likely wrong" in n]
    assert len(said) == 1 and "'acquisition.frequency' = 22" in said[0], est.notes
    assert est.f0 == pytest.approx(model.f0, rel=2e-5)
    right = reconstruct(rig, model, half)
    np.testing.assert_allclose(est.force, right.force, atol=1e-6)
