"""The method's stages against closed-form truths on synthetic data."""

from __future__ import annotations

import numpy as np
import pytest

from forcecal.errors import ConditioningError
from forcecal.forces.coordinates import generalized_coordinates
from forcecal.forces.steady import reconstruct
from forcecal.model.basis import fit_shape, shape_similarity
from forcecal.model.inertia import mass_coupling
from forcecal.model.relaxation import force_matrix, relaxation_shapes
from forcecal.model.scan import harmonic_shapes
from forcecal.model.spatial import build_spatial_model
from forcecal.records import Run, Scan
from forcecal.rig import parse_rig
from forcecal.signals.harmonics import fit_harmonics

L = 0.6
RHO = 3.0
LUMPED = ((0.3, 0.25), (0.12, 0.05))


def make_rig(gauges=(0.0, L), forces=(0.25, 0.35), sensors=(0.1, 0.5)):
    return parse_rig({
        "name": "synthetic",
        "structure": {"kind": "beam", "length": L, "mass_per_length": RHO,
                      "masses": [{"x": x, "mass": m} for x, m in LUMPED]},
        "gauges": [{"name": f"R{k + 1}", "x": x} for k, x in enumerate(gauges)],
        "forces": [{"name": f"F{k + 1}", "x": x, "gap": 1e-3} for k, x in enumerate(forces)],
        "sensors": [{"name": f"s{k + 1}", "x": x} for k, x in enumerate(sensors)],
        "actuator": {"current": "i"},
        "acquisition": {"frequency": 20.0},
    }, source="synthetic.toml")


def shape(x):
    """A bending-like real shape with rigid motion (gauge compliance) in it [m per unit]."""
    return np.sin(np.pi * x / L) + 0.05 + 0.02 * x / L


def synthetic_scan(rng, coefficients, f0=20.0, fs=5000.0, n_points=41, duration=0.5,
                   current=(0.5, 0.1, 0.03, 0.02), noise=0.0, shape_fn=shape):
    """Velocity records sum_n Re(j n w c_n phi(x) e^{j n w (t + tau_k)}), random tau_k."""
    x = np.linspace(0, L, n_points)
    t = np.arange(int(duration * fs)) / fs
    w = 2 * np.pi * f0
    tau = rng.uniform(0, 1 / f0, n_points)
    resp = np.zeros((n_points, len(t)))
    ref = np.zeros_like(resp)
    for n, c in enumerate(coefficients, start=1):
        ph = np.exp(1j * n * w * (t[None, :] + tau[:, None]))
        resp += (1j * n * w * c * shape_fn(x)[:, None] * ph).real
    for n, a in enumerate(current, start=1):
        ref += (a * np.exp(1j * n * w * (t[None, :] + tau[:, None]))).real
    resp += noise * rng.standard_normal(resp.shape)
    return Scan(points=x, response=resp, reference=ref, fs=fs, quantity="velocity")


def test_random_start_phases_give_one_coherent_shape_per_harmonic():
    """Regression test for eq. 13 as printed: harmonic n must be aligned by exp(-j n theta_k)."""
    rng = np.random.default_rng(1)
    coef = [1e-5, 3e-6 * np.exp(0.7j), 1e-6 * np.exp(-2.0j), 5e-7 * np.exp(1.1j)]
    scan = synthetic_scan(rng, coef)
    hs = harmonic_shapes(scan, 20.0, n_harmonics=4)
    truth = shape(scan.x)
    for k in range(1, 4):                                       # harmonics 2..4
        assert shape_similarity(hs.values[k], truth) > 0.999999
    # the printed eq. 13 (divide every harmonic by the fundamental's phasor) scrambles them
    theta = hs.drive_phase
    printed = hs.values * np.exp(1j * (hs.harmonics[:, None] - 1) * theta[None, :])
    for k in range(1, 4):
        assert shape_similarity(printed[k], truth) < 0.9


def test_drive_drift_is_normalised():
    rng = np.random.default_rng(2)
    scan = synthetic_scan(rng, [1e-5, 2e-6])
    drift = np.linspace(0.8, 1.2, scan.n_points)[:, None]     # drive amplitude drifts
    drifted = Scan(scan.points, scan.response * drift, scan.reference * drift, scan.fs)
    hs = harmonic_shapes(drifted, 20.0, n_harmonics=2)
    assert shape_similarity(hs.values[0], shape(scan.x)) > 0.999999
    np.testing.assert_allclose(np.abs(hs.values[0]) / np.abs(hs.values[0]).max(),
                               shape(scan.x) / shape(scan.x).max(), rtol=1e-6)


def test_rigid_translation_couplings_add_up_to_the_total_mass():
    rig = make_rig(gauges=(0.05, 0.55))
    rng = np.random.default_rng(3)
    scan = synthetic_scan(rng, [1e-5], current=(0.5,), shape_fn=lambda x: np.ones_like(x))
    model = build_spatial_model(rig, scan, n_harmonics=1)
    assert model.shapes[0].order == 1
    phi = model.shape_values(1, np.array([0.3]))[0]
    m = model.couplings[0] / phi                                 # per unit translation [kg]
    np.testing.assert_allclose(m.sum().real, rig.structure.total_mass, rtol=1e-12)
    xq = np.linspace(0, L, 20001)
    psi = relaxation_shapes(rig, xq)
    for r in range(2):
        distributed = np.trapezoid(RHO * psi[r], xq)
        lumped = sum(mk * relaxation_shapes(rig, np.array([xk]))[r, 0] for xk, mk in LUMPED)
        np.testing.assert_allclose(m[r].real, distributed + lumped, rtol=1e-8)
        assert abs(m[r].imag) < 1e-12 * abs(m[r])


def test_fitting_a_fitted_shape_returns_it_unchanged():
    rng = np.random.default_rng(4)
    x = np.linspace(0, L, 61)
    values = shape(x) * (1 + 0.3j) + 1e-3 * rng.standard_normal(61)
    first = fit_shape(x, values, (0, L))
    again = fit_shape(x, first.evaluate(x), (0, L), order=first.order)
    np.testing.assert_allclose(again.evaluate(x), first.evaluate(x), rtol=0, atol=1e-13)


def test_relaxation_shapes_for_gauges_anywhere():
    rig = make_rig(gauges=(0.07, 0.48))
    psi = relaxation_shapes(rig, rig.gauge_points)
    np.testing.assert_allclose(psi, np.eye(2), atol=1e-14)
    x = np.linspace(0, L, 7)
    np.testing.assert_allclose(relaxation_shapes(rig, x).sum(axis=0), 1.0, atol=1e-14)
    np.testing.assert_allclose(relaxation_shapes(rig, x)[1], (x - 0.07) / 0.41, atol=1e-14)


def test_mass_coupling_quadrature_is_exact_for_polynomials():
    rig = make_rig()
    m = mass_coupling(rig, lambda x: x**3)
    xq = np.linspace(0, L, 200001)
    psi = relaxation_shapes(rig, xq)
    for r in range(2):
        ref = np.trapezoid(RHO * psi[r] * xq**3, xq) + sum(
            mk * relaxation_shapes(rig, np.array([xk]))[r, 0] * xk**3 for xk, mk in LUMPED)
        np.testing.assert_allclose(m[r], ref, rtol=1e-9)


def _static_run(rig, forces_t, fs, t):
    """Gauges carry -Psi f(t); the structure does not move (no inertia)."""
    psi = force_matrix(rig)
    reactions = -psi @ forces_t
    ch = {"R1": reactions[0], "R2": reactions[1], "s1": np.zeros_like(t),
          "s2": np.zeros_like(t), "i": 0.5 * np.sin(2 * np.pi * 20.0 * t)}
    return Run(channels=ch, fs=fs, name="static")


def test_static_load_recovered_exactly_by_both_paths():
    rig = make_rig()
    rng = np.random.default_rng(5)
    model = build_spatial_model(rig, synthetic_scan(rng, [1e-5, 2e-6], noise=1e-7),
                                n_harmonics=2)
    fs = 5000.0
    t = np.arange(2600) / fs                                   # 10.4 periods: fractional
    w = 2 * np.pi * 20.0
    f = np.stack([3.0 + 1.2 * np.sin(w * t + 0.3) + 0.2 * np.cos(2 * w * t),
                  2.0 + 0.8 * np.sin(w * t - 0.4) + 0.1 * np.sin(2 * w * t)])
    est = reconstruct(rig, model, _static_run(rig, f, fs, t), n_harmonics=2)
    np.testing.assert_allclose(est.series, f, atol=1e-9)
    np.testing.assert_allclose(est.static_series, f, atol=1e-12)


def test_whole_and_fractional_records_give_the_same_forces(paper, paper_noise_free):
    rig, _, model, _ = paper
    run, _ = paper_noise_free
    whole = int(round(18 * run.fs / 20.014))                   # about 18 periods
    frac = int(round(17.37 * run.fs / 20.014))
    a = reconstruct(rig, model, _cut(run, whole))
    b = reconstruct(rig, model, _cut(run, frac))
    np.testing.assert_allclose(a.force[:, :3], b.force[:, :3], rtol=0,
                               atol=1e-6 * np.abs(a.force[:, 1]).max())


def _cut(run: Run, n: int) -> Run:
    return Run(channels={k: v[:n] for k, v in run.channels.items()}, fs=run.fs, name=run.name)


def test_sensors_at_a_node_are_refused():
    rig = make_rig(sensors=(0.0, L))                           # shape nearly zero at the ends
    rng = np.random.default_rng(6)
    model = build_spatial_model(rig, synthetic_scan(
        rng, [1e-5], current=(0.5,), shape_fn=lambda x: np.sin(np.pi * x / L)), n_harmonics=1)
    s_fit = fit_harmonics(np.zeros((2, 1000)) + 1e-9 * rng.standard_normal((2, 1000)),
                          5000.0, 20.0, 1)
    with pytest.raises(ConditioningError, match="node of the harmonic-1 shape"):
        generalized_coordinates(model, rig, s_fit, "r.csv")
