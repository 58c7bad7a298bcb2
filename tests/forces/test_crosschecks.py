"""The forces against their poles' Maxwell force: a synthetic steady estimate whose forces are
exactly c Phi^2 / (2 mu0 A) plus noise, then one lab mistake at a time in its reactions or its
inertia; the note must name the mistake with its size."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

from forcecal.forces.crosschecks import ALIKE, MU0, EstimateTerms, flux_notes, pole_notes
from forcecal.model.relaxation import force_matrix
from forcecal.records import Run
from forcecal.rig import parse_rig

F0, FS, N, H = 20.0, 2000.0, 2000, 3
AREA = 4e-4
RIG = parse_rig({
    "structure": {"length": 0.6, "mass_per_length": 3.768},
    "gauges": [{"name": "R1", "x": 0.0}, {"name": "R2", "x": 0.6}],
    "forces": [{"name": "F1", "x": 0.25}, {"name": "F2", "x": 0.35}],
    "sensors": [{"name": "s1", "x": 0.1}],
    "actuator": {"flux": "phi", "pole_area": AREA},
    "uncertainty": {"gauge_scale": 0.0, "probe_scale": 0.0, "current_scale": 0.0,
                    "position": 0.0, "mass": 0.0, "gap": 0.0},
}, source="rig.toml")
DECLARED = dataclasses.replace(RIG, type_b=dataclasses.replace(RIG.type_b, gauge_scale=0.005))
"""The rig declaring each gauge's scale known to 0.5 %."""


def _phasors(x: np.ndarray) -> np.ndarray:
    t = np.arange(N) / FS
    out = [x.mean()] + [2 * np.mean(x * np.exp(-2j * np.pi * n * F0 * t)) for n in range(1, H + 1)]
    return np.array(out)


def _lab(seed: int, noise: float = 2e-4):
    """(run, terms) of a clean estimate: each pole's force 0.97 x Maxwell's, reactions and
    inertia that give it, and noise of ``noise`` N on every force phasor."""
    rng = np.random.default_rng(seed)
    t = np.arange(N) / FS
    phi = 4e-5 * (1 + 0.4 * np.sin(2 * np.pi * F0 * t) + 0.05 * np.sin(4 * np.pi * F0 * t + 1))
    run = Run(channels={"phi": phi + 1e-9 * rng.standard_normal(N)}, fs=FS, source="run.csv")
    maxwell = _phasors(phi**2 / (2 * MU0 * AREA))
    force = 0.97 * np.vstack([maxwell, maxwell])
    force += noise * (rng.standard_normal(force.shape) + 1j * rng.standard_normal(force.shape))
    force[:, 0] = force[:, 0].real
    psi = force_matrix(RIG)
    n = np.arange(H + 1)
    inertia = 0.1 * (n * 2 * np.pi * F0 / 125.0) ** 2 * (psi @ force) * np.exp(0.3j)
    reactions = inertia - psi @ force                   # F = Psi^+ (J - R)
    terms = EstimateTerms(force=force, std=np.full(force.shape, noise),
                          reactions=reactions, inertia=inertia, pinv=np.linalg.pinv(psi),
                          kept=np.ones(H + 1, dtype=bool), w0=2 * np.pi * F0)
    return run, terms


def _mistaken(terms: EstimateTerms, reactions=None, inertia=None) -> EstimateTerms:
    r = terms.reactions if reactions is None else reactions
    j = terms.inertia if inertia is None else inertia
    return dataclasses.replace(terms, reactions=r, inertia=j, force=terms.pinv @ (j - r))


def _delayed(x: np.ndarray, seconds: float) -> np.ndarray:
    return x * np.exp(-1j * np.arange(H + 1) * 2 * np.pi * F0 * seconds)


def test_a_clean_estimate_draws_no_note_at_the_stated_rate():
    """Over 100 draws the rate stays near FALSE_ALARM (achieved: 0 of 300; 2 in 100 would be
    20x the rate)."""
    alarms = sum(bool(flux_notes(RIG, *_lab(seed), "run")) for seed in range(100))
    assert alarms <= 1, alarms


@pytest.mark.parametrize(("name", "mistake", "says"), [
    ("R1 scale 2 %", lambda t: _mistaken(t, reactions=t.reactions * [[1.02], [1.0]]),
     ("gauge 'R1' scale", 2.0, "%")),
    ("R2 scale -10 %", lambda t: _mistaken(t, reactions=t.reactions * [[1.0], [0.9]]),
     ("gauge 'R2' scale", -10.0, "%")),
    ("R1 offset 1 N", lambda t: _mistaken(t, reactions=t.reactions + [[1.0], [0.0]]
                                         * (np.arange(H + 1) == 0)),
     ("gauge 'R1' offset", 1.0, "N")),
    ("probes' sign", lambda t: _mistaken(t, inertia=-t.inertia),
     ("the inertia's scale", -200.0, "%")),
    ("mass 30 % low", lambda t: _mistaken(t, inertia=0.7 * t.inertia),
     ("the inertia's scale", -30.0, "%")),
    ("gauges 1 ms late", lambda t: _mistaken(t, reactions=_delayed(t.reactions, 1e-3)),
     ("a delay of the gauges", 1.0, "ms")),
    ("probes 2 ms late", lambda t: _mistaken(t, inertia=_delayed(t.inertia, 2e-3)),
     ("a delay of the probes", 2.0, "ms")),
    ("gauges 2 ms early", lambda t: _mistaken(t, reactions=_delayed(t.reactions, -2e-3)),
     ("a delay of the gauges", -2.0, "ms")),
])
def test_a_mistake_is_named_among_the_best_with_its_size(name, mistake, says):
    """Achieved: each named among the causes the data cannot tell apart from the best (a
    gauge's scale and a force's position can be alike), its size within 3 % of the truth
    (tolerance 10 %)."""
    run, terms = _lab(1)
    notes = flux_notes(RIG, run, mistake(terms), "run 'run.csv'")
    assert len(notes) == 1, (name, notes)
    cause, size, unit = says
    found = re.search(re.escape(cause) + r"[^;]* off by ([-+0-9.e]+) " + unit
                      + r" \(chi-square then ([0-9.e+-]+)\)", notes[0])
    assert found, (name, notes[0])
    assert float(found.group(1)) == pytest.approx(size, rel=0.1), (name, notes[0])
    chi2 = [float(c) for c in re.findall(r"chi-square then ([0-9.e+-]+)\)", notes[0])]
    assert float(found.group(2)) - min(chi2) <= ALIKE, (name, notes[0])


def test_no_flux_or_no_area_no_check_and_an_ac_flux_is_said():
    run, terms = _lab(2)
    bad = _mistaken(terms, reactions=terms.reactions * [[1.1], [1.0]])
    no_area = dataclasses.replace(RIG, actuator=dataclasses.replace(RIG.actuator,
                                                                    pole_area=None))
    assert flux_notes(no_area, run, bad, "run") == []
    ac = Run(channels={"phi": run.channels["phi"] - run.channels["phi"].mean()}, fs=FS)
    assert "holds no DC" in flux_notes(RIG, ac, bad, "run")[0]


def test_a_scale_within_the_declared_uncertainty_is_not_a_mistake():
    """Gauge scales known to 0.5 %: R1 2 % off against R2 is 2.8 standard uncertainties of
    their ratio, short of the one-in-a-thousand gain (no note); 4 % is 5.7 (named, +4.0 %)."""
    run, terms = _lab(1)
    assert flux_notes(DECLARED, run, _mistaken(terms, reactions=terms.reactions
                                               * [[1.02], [1.0]]), "run") == []
    notes = flux_notes(DECLARED, run, _mistaken(terms, reactions=terms.reactions
                                                * [[1.04], [1.0]]), "run")
    assert "gauge 'R1' scale (its 'scale' in the rig) off by +4" in notes[0]


def test_a_pole_flux_missing_from_the_run_or_a_constant_flux_is_said():
    run, terms = _lab(3)
    own = dataclasses.replace(RIG, forces=(RIG.forces[0],
                                           dataclasses.replace(RIG.forces[1], flux="phi2")))
    said = flux_notes(own, run, terms, "run")
    assert said == ["run: force 'F2': its flux channel 'phi2' (forces[1].flux) is not in the "
                    "run; its force is not checked against Maxwell's stress"]
    still = Run(channels={"phi": np.full(N, 4e-5)}, fs=FS)
    assert "the flux is constant" in flux_notes(RIG, still, terms, "run")[0]



# --------------------------------------------------------------------------------------------
# the flux channels of one core against each other

def _paired(area: float | None = AREA):
    """The test rig with each pole on its own flux channel, both of core 'U'."""
    return parse_rig({
        "structure": {"length": 0.6, "mass_per_length": 3.768},
        "gauges": [{"name": "R1", "x": 0.0}, {"name": "R2", "x": 0.6}],
        "forces": [{"name": "F1", "x": 0.25, "flux": "phi1", "core": "U"},
                   {"name": "F2", "x": 0.35, "flux": "phi2", "core": "U"}],
        "sensors": [{"name": "s1", "x": 0.1}],
        "actuator": {} if area is None else {"pole_area": area},
        "uncertainty": {"gauge_scale": 0.0, "probe_scale": 0.0, "current_scale": 0.0,
                        "position": 0.0, "mass": 0.0, "gap": 0.0},
    }, source="rig.toml")


def _two_channels(seed: int, gain: float = 1.0):
    """(run, terms) of :func:`_lab` with the flux read by two channels, the second ``gain``
    times the first and with its own noise."""
    run, terms = _lab(seed)
    rng = np.random.default_rng(1000 + seed)
    phi = run.channel("phi")
    phi2 = gain * (phi + 1e-9 * rng.standard_normal(N))
    return Run(channels={"phi1": phi, "phi2": phi2}, fs=FS, source="run.csv"), terms


def test_one_cores_flux_channels_agree_on_a_clean_run():
    """Achieved: no note in 100 draws (2 would be 20x the rate)."""
    rig = _paired()
    alarms = sum(bool(flux_notes(rig, *_two_channels(seed), "run")) for seed in range(100))
    assert alarms <= 1, alarms


@pytest.mark.parametrize(("gain", "area", "look"), [
    (1.10, AREA, "look at 'phi2' first"), (1e-3, AREA, "look at 'phi2' first"),
    (0.9, None, "look at both: a scale")])
def test_a_flux_channel_off_is_named_with_its_ratio_and_maxwell_stands_aside(gain, area, look):
    """Achieved: the ratio to 4 digits; the gauges are not blamed (the Maxwell check stands
    aside, the poles' forces pull alike). A ratio within the fringing (2 %) is not a mistake
    the data can show: 10 % is 5 of its standard deviations."""
    rig = _paired(area)
    notes = flux_notes(rig, *_two_channels(3, gain), "run 'run.csv'")
    assert len(notes) == (2 if area else 1), notes
    found = re.search(r"'phi2' reads ([-+0-9.e]+) times 'phi1'", notes[0])
    assert found and float(found.group(1)) == pytest.approx(gain, rel=2e-3), notes
    assert "core 'U'" in notes[0] and look in notes[0], notes
    assert not any("gauge" in n for n in notes), notes
    if area:
        assert "not checked against Maxwell's stress" in notes[1]
        run, terms = _two_channels(3, gain)
        assert pole_notes(rig, run, terms, "run") == []


def test_a_flux_channel_within_the_fringing_draws_no_pair_note():
    notes = flux_notes(_paired(), *_two_channels(3, 1.02), "run")
    assert not any("flux channels" in n for n in notes), notes


def test_a_flux_channels_sign_is_named_and_the_maxwell_check_stands():
    """Phi^2 hides a sign: the note names it, and the forces are still checked (no note)."""
    notes = flux_notes(_paired(), *_two_channels(3, -1.0), "run")
    assert len(notes) == 1 and "'phi2' reads -1 times 'phi1'" in notes[0], notes
    assert "look at both: a sign" in notes[0], notes


@pytest.mark.parametrize("dead", ["phi1", "phi2"])
def test_a_dead_flux_channel_is_named_as_one(dead):
    """Either channel of the core reading nothing: it reads 0 times the other, named first as
    carrying next to no flux (before, a dead first channel made the live one read '+0 times'
    it)."""
    run, terms = _two_channels(3)
    channels = {**run.channels, dead: np.zeros(N)}
    notes = flux_notes(_paired(), Run(channels=channels, fs=FS, source="run.csv"), terms, "run")
    live = "phi2" if dead == "phi1" else "phi1"
    assert f"'{dead}' reads +0 times '{live}'" in notes[0], notes
    assert f"look at '{dead}' first: it carries next to no flux" in notes[0], notes
