"""The virtual plate rig against closed-form truths, its own balance laws and its files.

Every check compares the simulator with something it does not compute itself: Kirchhoff's
simply supported frequencies, the Navier series, the barycentric coordinates of the gauge
triangle (as area ratios), a Gauss quadrature of the inertia term written below, a static solve,
or the files read back by the public readers.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from forcecal.io.manifest import read_manifest
from forcecal.io.run_files import read_run, read_table_csv
from forcecal.io.uff import read_scan_uff
from forcecal.rig import load_rig
from forcecal.simulate.beam import natural_frequencies
from forcecal.simulate.export import write_simulation
from forcecal.simulate.integrate import integrate
from forcecal.simulate.magnet import MU0, Drive
from forcecal.simulate.plate import (
    assemble_plate,
    bfs_row,
    flexural_rigidity,
    simply_supported_frequencies,
    simply_supported_static_deflection,
)
from forcecal.simulate.presets import NoiseSpec, PlateSpec, get_preset
from forcecal.simulate.virtual_rig import (
    build_model,
    public_rig,
    record_run,
    record_scan,
    scan_points,
)

FREQ_RTOL = 5e-3          # the brief's bound; an 8 x 8 mesh gives ~2e-4
STATIC_RTOL = 1e-3        # point load: 16 x 16 elements give ~7e-4 (h^2 under the load)
OFF_LOAD_RTOL = 1e-5      # away from the load, 20 x 16 elements give ~1e-6
NAVIER_ALPHA = 0.01160    # Timoshenko's coefficient, square plate, central point load
BALANCE_RTOL = 1e-6       # rigid-body balance residual relative to the reaction RMS
QUADRATURE_RTOL = 1e-9    # our quadrature of J vs Psi^T M a (both exact: rounding only)
FORCE_RTOL = 1e-12        # magnetic force vs its closed form at the simulated gap
UFF_RTOL = 5e-12          # pyuff ASCII values: %20.11e
SHORT = 0.25              # s, record length of the noise-free checks

SPEC = PlateSpec()
D = flexural_rigidity(SPEC.youngs_modulus, SPEC.thickness, SPEC.poisson)
RHO_H = SPEC.density * SPEC.thickness


def kirchhoff_simply_supported(a: float, b: float, n_modes: int = 4) -> np.ndarray:
    """pi^2 (m^2/a^2 + n^2/b^2) sqrt(D / (rho h)) / (2 pi), the lowest n_modes [Hz]."""
    mn = np.arange(1, 8)
    lam = np.sort((mn[:, None] ** 2 / a**2 + mn[None, :] ** 2 / b**2).ravel())[:n_modes]
    return np.pi**2 * lam * np.sqrt(D / RHO_H) / (2 * np.pi)


def navier_deflection(a, b, load, x0, y0, x, y, n_terms=2000) -> float:
    """Navier's double series for a simply supported plate under a point load at (x0, y0)."""
    m = np.arange(1, n_terms + 1)
    sx = np.sin(m * np.pi * x0 / a) * np.sin(m * np.pi * x / a)
    sy = np.sin(m * np.pi * y0 / b) * np.sin(m * np.pi * y / b)
    den = (m[:, None] ** 2 / a**2 + m[None, :] ** 2 / b**2) ** 2
    return float(4 * load / (np.pi**4 * D * a * b) * np.sum(np.outer(sx, sy) / den))


def barycentric(gauges, points) -> np.ndarray:
    """psi_r at points (n, 2) as area ratios of the gauge triangle: (3, n)."""
    g = np.asarray(gauges, dtype=float)
    p = np.atleast_2d(np.asarray(points, dtype=float))

    def area(p0, p1, p2):
        return 0.5 * ((p1[..., 0] - p0[..., 0]) * (p2[..., 1] - p0[..., 1])
                      - (p2[..., 0] - p0[..., 0]) * (p1[..., 1] - p0[..., 1]))

    total = area(g[0], g[1], g[2])
    return np.stack([area(p, g[1], g[2]), area(g[0], p, g[2]), area(g[0], g[1], p)]) / total


def gauge_xy(preset) -> np.ndarray:
    return np.array([[x, y] for _, x, y in preset.beam.gauges])


def pole_xy(preset) -> np.ndarray:
    return np.array([[p.x, p.y] for m in preset.magnets for p in m.poles])


def gauge_reactions(model, preset, u, v) -> np.ndarray:
    """Noise-free force each gauge exerts on the plate: spring plus its internal dashpot."""
    rows = bfs_row(model.xs, model.ys, gauge_xy(preset))
    return -preset.beam.gauge_stiffness * (rows @ u + model.beta * (rows @ v))


@pytest.fixture(scope="module")
def plate():
    preset = get_preset("plate")
    return preset, build_model(preset)


# --------------------------------------------------------------------------------------------
# the plate against Kirchhoff


@pytest.mark.parametrize("a, b", [(SPEC.a, SPEC.b), (0.4, 0.4)])
def test_simply_supported_frequencies_match_kirchhoff(a, b):
    f = simply_supported_frequencies(a, b, D, RHO_H, SPEC.poisson, mesh=(8, 8))
    np.testing.assert_allclose(f, kirchhoff_simply_supported(a, b), rtol=FREQ_RTOL)


def test_simply_supported_error_falls_with_mesh_refinement():
    exact = kirchhoff_simply_supported(SPEC.a, SPEC.b)
    errors = np.array([
        np.abs(simply_supported_frequencies(SPEC.a, SPEC.b, D, RHO_H, SPEC.poisson, (n, n))
               / exact - 1)
        for n in (2, 4, 8)
    ])
    assert np.all(errors[1:] < errors[:-1])
    # bicubic conforming elements: frequency error ~ h^4, halving h gains a factor near 16
    assert np.all(errors[:-1] / errors[1:] > 10)


def test_navier_series_gives_timoshenko_coefficient():
    a = 0.4
    w = navier_deflection(a, a, 1.0, a / 2, a / 2, a / 2, a / 2)
    assert w * D / a**2 == pytest.approx(NAVIER_ALPHA, abs=5e-6)


def test_central_point_load_deflection_matches_navier():
    a, load = 0.4, 200.0
    centre = (a / 2, a / 2)
    exact = navier_deflection(a, a, load, *centre, *centre)
    errors = []
    for n in (4, 8, 16):
        w = simply_supported_static_deflection(a, a, D, load, centre, centre, SPEC.poisson, (n, n))
        errors.append(abs(w / exact - 1))
    assert errors[-1] < STATIC_RTOL
    assert errors[0] > errors[1] > errors[2]           # converging (about h^2 under the load)


def test_off_centre_point_load_deflection_matches_navier():
    a, b, load = SPEC.a, SPEC.b, 100.0
    load_at, eval_at = (0.20, 0.20), (0.35, 0.10)      # away from the load: faster convergence
    exact = navier_deflection(a, b, load, *load_at, *eval_at)
    w = simply_supported_static_deflection(a, b, D, load, load_at, eval_at, SPEC.poisson, (20, 16))
    assert w == pytest.approx(exact, rel=OFF_LOAD_RTOL)


# --------------------------------------------------------------------------------------------
# rigid motion, mass and damping


def test_rigid_modes_are_exact_and_stress_free(plate):
    _, model = plate
    rng = np.random.default_rng(3)
    kb = model.bending_stiffness
    for c in rng.normal(size=(3, 3)) * (1e-3, 1e-2, 1e-2):
        rigid = model.rigid_mode(*c)
        pts = rng.uniform((0, 0), (SPEC.a, SPEC.b), size=(40, 2))
        np.testing.assert_allclose(model.row(pts) @ rigid, c[0] + pts @ c[1:], rtol=1e-13,
                                   atol=1e-17)
        scale = np.max(np.abs(kb)) * np.max(np.abs(rigid))
        assert np.max(np.abs(kb @ rigid)) < 1e-12 * scale
        plate_damping = model.damping - model.beta * (model.stiffness - kb)
        assert np.max(np.abs(plate_damping @ rigid)) < 1e-12 * model.beta * scale


def test_free_plate_has_three_rigid_modes():
    free = assemble_plate(SPEC.a, SPEC.b, D, RHO_H, SPEC.poisson, (6, 5))
    f = natural_frequencies(free, 4)
    assert np.all(f[:3] < 1e-4 * f[3])


def test_mass_matrix_carries_total_mass_and_first_moments(plate):
    preset, model = plate
    (xm, ym, mm), = preset.beam.masses
    one, x, y = (model.rigid_mode(*c) for c in ((1, 0, 0), (0, 1, 0), (0, 0, 1)))
    a, b = SPEC.a, SPEC.b
    total = RHO_H * a * b + mm
    assert one @ model.mass @ one == pytest.approx(total, rel=1e-12)
    assert one @ model.mass @ x == pytest.approx(RHO_H * a * b * a / 2 + mm * xm, rel=1e-12)
    assert one @ model.mass @ y == pytest.approx(RHO_H * a * b * b / 2 + mm * ym, rel=1e-12)
    assert x @ model.mass @ x == pytest.approx(RHO_H * b * a**3 / 3 + mm * xm**2, rel=1e-12)


def test_shape_functions_interpolate_nodes_and_are_continuous(plate):
    _, model = plate
    rng = np.random.default_rng(4)
    u = rng.standard_normal(model.n_dof)
    nodes = model.nodes
    np.testing.assert_allclose(model.row(nodes) @ u, u[0::4], rtol=1e-13, atol=1e-13)
    # across an element edge (x = xs[3]) w is continuous
    x_edge = model.xs[3]
    y = rng.uniform(0, SPEC.b, 10)
    left = model.row(np.column_stack([np.full(10, x_edge - 1e-12), y])) @ u
    right = model.row(np.column_stack([np.full(10, x_edge + 1e-12), y])) @ u
    np.testing.assert_allclose(left, right, atol=1e-9)


def test_preset_frequencies_and_relaxation_shapes(plate):
    preset, model = plate
    f = natural_frequencies(model, 3)
    assert 60.0 < f[0] < 90.0                            # first bending mode, with the armature
    psi = barycentric(gauge_xy(preset), gauge_xy(preset))
    np.testing.assert_allclose(psi, np.eye(3), atol=1e-15)


# --------------------------------------------------------------------------------------------
# the magnet on the plate: poles act at (x, y)


def test_dc_pole_forces_act_at_their_xy(plate):
    preset, model = plate
    magnet, current = preset.magnets[0], 0.8
    r = integrate(model, preset.magnets, (Drive("current", current, 0.0, 20.0),), preset.fs, 0.05)
    rows = bfs_row(model.xs, model.ys, pole_xy(preset))
    np.testing.assert_allclose(r.gap, magnet.poles[0].gap - rows @ r.u, rtol=1e-13)
    # the DC steady state is the static solution under the recorded pole forces at (x, y)
    u_static = np.linalg.solve(model.stiffness, rows.T @ r.pole_force[:, -1])
    np.testing.assert_allclose(r.u[:, -1], u_static, rtol=1e-9,
                               atol=1e-9 * np.max(np.abs(u_static)))
    flux = magnet.turns * current * MU0 * magnet.pole_area / (
        r.gap.sum(axis=0) + magnet.iron_length / magnet.mu_r)
    np.testing.assert_allclose(r.pole_force, np.broadcast_to(
        flux**2 / (2 * MU0 * magnet.pole_area), r.gap.shape), rtol=FORCE_RTOL)


# --------------------------------------------------------------------------------------------
# rigid-body balance of the truth (METHOD.md eq. 6)


@pytest.fixture(scope="module")
def quiet_run(plate):
    preset, model = plate
    p0 = dataclasses.replace(preset, noise=NoiseSpec(0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
    spec = dataclasses.replace(preset.runs[0], duration=SHORT)
    run, truth = record_run(p0, spec, np.random.default_rng(11), model)
    response = integrate(model, preset.magnets, spec.drives, preset.fs, SHORT)
    return p0, model, run, truth, response


def test_truth_balances_reactions_inertia_and_forces(quiet_run):
    preset, model, run, truth, response = quiet_run
    np.testing.assert_array_equal(truth.w, response.u[0::4])
    assert truth.nodes.shape == (len(model.xs) * len(model.ys), 2)
    reactions = gauge_reactions(model, preset, response.u, response.v)
    recorded = np.stack([run.channels[name] for name, _, _ in preset.beam.gauges])
    np.testing.assert_array_equal(recorded, reactions)
    psi = barycentric(gauge_xy(preset), pole_xy(preset))          # (3 gauges, 2 poles)
    rms = np.sqrt(np.mean(reactions**2, axis=1))
    residual = truth.inertia - reactions - psi @ truth.pole_force
    assert np.max(np.abs(residual) / rms[:, None]) < BALANCE_RTOL
    # the reactions alone do not balance the forces: the inertia term is far above rounding
    static = -reactions - psi @ truth.pole_force
    assert np.all(np.max(np.abs(static), axis=1) / rms > 1e3 * BALANCE_RTOL)
    ac_share = np.sqrt(np.mean(truth.inertia**2, axis=1)) / np.std(reactions, axis=1)
    assert np.all(ac_share > 0.01)


def test_inertia_equals_an_independent_quadrature(quiet_run):
    preset, model, _, truth, response = quiet_run
    gx, gw = np.polynomial.legendre.leggauss(4)           # exact for psi (1) * w (3) per axis
    xs, ys = model.xs, model.ys
    px = ((xs[:-1] + xs[1:]) / 2 + np.outer(gx, np.diff(xs)) / 2).ravel()
    wx = (np.outer(gw, np.diff(xs)) / 2).ravel()
    py = ((ys[:-1] + ys[1:]) / 2 + np.outer(gx, np.diff(ys)) / 2).ravel()
    wy = (np.outer(gw, np.diff(ys)) / 2).ravel()
    qx, qy = np.meshgrid(px, py, indexing="ij")
    pts = np.column_stack([qx.ravel(), qy.ravel()])
    weights = np.outer(wx, wy).ravel()
    w_tt = bfs_row(xs, ys, pts) @ response.a
    j = (RHO_H * barycentric(gauge_xy(preset), pts) * weights) @ w_tt
    for xm, ym, mass in preset.beam.masses:
        j += mass * barycentric(gauge_xy(preset), [(xm, ym)]) * (
            bfs_row(xs, ys, (xm, ym)) @ response.a)
    scale = np.sqrt(np.mean(j**2, axis=1))[:, None]
    assert np.max(np.abs(truth.inertia - j) / scale) < QUADRATURE_RTOL


# --------------------------------------------------------------------------------------------
# files written by write_simulation("plate")


@pytest.fixture(scope="module")
def plate_files(tmp_path_factory):
    out = tmp_path_factory.mktemp("plate") / "sim"
    write_simulation(out, "plate", seed=5)
    return out


def test_plate_files_read_back(plate_files, plate):
    out = plate_files
    preset, model = plate
    rig = load_rig(out / "rig.toml")
    assert rig.structure.kind == "plate" and len(rig.gauges) == 3 and len(rig.forces) == 2
    assert rig.structure.mass_per_area == pytest.approx(RHO_H, rel=1e-15)
    assert dataclasses.replace(rig, source="<rig>") == public_rig(preset)
    np.testing.assert_array_equal(rig.force_points, pole_xy(preset))

    rng = np.random.default_rng(5)                  # the same draws, in write_simulation's order
    scan = record_scan(preset, rng, model)
    back = read_scan_uff(out / "scan.uff")
    assert back.points.shape == (13 * 11, 2)
    np.testing.assert_array_equal(back.points, scan_points(preset))
    np.testing.assert_array_equal(back.points, scan.points)
    assert back.fs == preset.fs and back.quantity == "velocity"
    np.testing.assert_allclose(back.response, scan.response, rtol=UFF_RTOL, atol=0)
    np.testing.assert_allclose(back.reference, scan.reference, rtol=UFF_RTOL, atol=0)

    got = read_run(out / "runs" / "plate.csv")
    names = ["R1", "R2", "R3", "s1", "s2", "s3", "s4", "i", "phi", "v"]
    assert list(got.channels) == names
    assert got.n_samples == round(preset.runs[0].duration * preset.fs)
    t, cols = read_table_csv(out / "truth" / "plate.forces.csv")
    assert list(cols) == ["F1", "F2", "total"] and len(t) == got.n_samples
    with np.load(out / "truth" / "plate.npz") as npz:
        assert npz["inertia"].shape == (3, got.n_samples)
        assert npz["nodes"].shape == (len(model.xs) * len(model.ys), 2)
    entries = read_manifest(out / "manifest.csv")
    assert [e.run for e in entries] == [(out / "runs" / "plate.csv").resolve()]
