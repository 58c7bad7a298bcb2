"""The run against the scan (``forces.scan_check``): the scan's drive kept in the model, the
harmonics of i^2, and the notes on a sign, a unit slip and a delay of the probes."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from forcecal.forces.coordinates import Coordinates
from forcecal.forces.scan_check import PHASE_TOLERANCE, scan_notes
from forcecal.model.scan import harmonic_shapes
from forcecal.model.spatial import SpatialModel, build_spatial_model
from forcecal.records import Scan
from forcecal.rig import parse_rig
from forcecal.signals.fourier_sums import square_phasors

L = 0.6
F0 = 20.0
DRIVE = np.array([0.7, 0.5, 0.1, 0.03])
"""[A] the scan's current: a DC bias and three harmonics, in phase with the fundamental."""


@pytest.fixture(scope="module")
def scanned():
    """A beam rig and its model from a scan whose records start at random phases."""
    rng = np.random.default_rng(7)
    x = np.linspace(0, L, 31)
    fs, w = 5000.0, 2 * np.pi * F0
    t = np.arange(int(0.5 * fs)) / fs
    tau = rng.uniform(0, 1 / F0, len(x))
    phase = np.exp(1j * w * (t[None, :] + tau[:, None]))
    shape = np.sin(np.pi * x / L)[:, None]
    resp = sum((1j * n * w * c * shape * phase**n).real
               for n, c in enumerate([1e-5, 3e-6, 1e-6], start=1))
    ref = DRIVE[0] + sum((a * phase**n).real for n, a in enumerate(DRIVE[1:], start=1))
    scan = Scan(points=x, response=resp, reference=ref, fs=fs, quantity="velocity")
    rig = parse_rig({
        "structure": {"kind": "beam", "length": L, "mass_per_length": 3.768},
        "gauges": [{"name": "R1", "x": 0.0}, {"name": "R2", "x": L}],
        "forces": [{"name": "F1", "x": 0.25, "gap": 1e-3}, {"name": "F2", "x": 0.35, "gap": 1e-3}],
        "sensors": [{"name": "s1", "x": 0.1}, {"name": "s2", "x": 0.5}],
        "acquisition": {"frequency": F0}}, source="beam.toml")
    return rig, scan, build_spatial_model(rig, scan, n_harmonics=3)


def test_square_phasors_are_the_harmonics_of_the_square():
    rng = np.random.default_rng(3)
    current = rng.normal(size=5) + 1j * rng.normal(size=5)
    current[0] = current[0].real
    t = np.arange(1000) / 1000
    n = np.arange(5)
    i = (current[None, :] * np.exp(2j * np.pi * np.outer(t, n))).real.sum(axis=1)
    spectrum = np.fft.fft(i**2) / len(t)
    expected = np.concatenate([[spectrum[0].real], 2 * spectrum[1:5]])
    assert np.allclose(square_phasors(current), expected, atol=1e-12)


def test_the_model_keeps_the_scans_drive_aligned(scanned):
    _, scan, model = scanned
    hs = harmonic_shapes(scan, F0, n_harmonics=3)
    assert hs.drive is not None and np.allclose(hs.drive, DRIVE, atol=1e-6)
    again = SpatialModel.from_json(json.loads(json.dumps(model.to_json())))
    assert again.drive is not None and np.allclose(again.drive, DRIVE, atol=1e-6)


def _coordinates(model: SpatialModel, q1: complex, std: float = 1e-4) -> Coordinates:
    q = np.ones(len(model.harmonics), dtype=complex)
    q[model.index(1)] = q1
    return Coordinates(harmonics=model.harmonics, q=q, q_std=np.full(len(q), std),
                       gain=np.ones(len(q)), chi2=np.ones(len(q)))


@pytest.mark.parametrize("turn", [0.0, 0.3, -1.1])
def test_the_scans_own_motion_draws_no_note(scanned, turn):
    """Any bias, level, sign of the current or time origin: rho stays real and positive."""
    _, _, model = scanned
    n = np.arange(4)
    for current in (DRIVE, -0.5 * DRIVE, np.array([1.2, 0.2, 0.0, 0.0])):
        run = current * np.exp(1j * n * turn)                # the run's own time origin
        q1 = square_phasors(run)[1] / square_phasors(DRIVE)[1]
        assert scan_notes(model, _coordinates(model, q1), run, ["s1", "s2"], "run") == []


def test_a_sign_a_unit_slip_and_a_delay_are_named(scanned):
    _, _, model = scanned
    names = ["s1", "s2"]
    [sign] = scan_notes(model, _coordinates(model, -1.0), DRIVE, names, "run")
    assert "against the scan's motion" in sign and "sensors[].scale" in sign
    [unit] = scan_notes(model, _coordinates(model, 1e-3), DRIVE, names, "run")
    assert "0.00100 times" in unit and "unit or scale slip" in unit
    late = 0.4e-3                                            # [s] the probes recorded late
    q1 = np.exp(-2j * np.pi * model.f0 * late)
    [delay] = scan_notes(model, _coordinates(model, q1), DRIVE, names, "run")
    assert "+0.4 ms late" in delay
    # within the tolerance the load leaves, no note
    within = np.exp(0.8j * PHASE_TOLERANCE)
    assert scan_notes(model, _coordinates(model, within), DRIVE, names, "run") == []
    # a drive without a DC bias pulls at 2 w0 only: nothing to compare at the fundamental
    unbiased = np.array([0.0, 0.5, 0.0, 0.0])
    assert scan_notes(model, _coordinates(model, -1.0), unbiased, names, "run") == []
    # a model file whose drive holds the DC only (or none) cannot be checked: no note, no error
    for drive in (model.drive[:1], None):
        short = dataclasses.replace(model, drive=drive)
        assert scan_notes(short, _coordinates(model, -1.0), DRIVE, names, "run") == []
