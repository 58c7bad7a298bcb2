"""The method on a 3-D body: six gauges with measuring directions, located scans, vector shapes.

The virtual block (:mod:`forcecal.simulate.solid`) is the truth; the estimator knows only the
public rig (blocks, density, lumped mass, locations) and the recorded files.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from forcecal.cli.main import main
from forcecal.errors import ConditioningError, RigError
from forcecal.forces.steady import reconstruct
from forcecal.io.scan_files import read_scan, write_scan_npz
from forcecal.io.uff import write_scan_uff
from forcecal.model.basis import fit_shape, orthonormal_basis
from forcecal.model.inertia import mass_weights
from forcecal.model.relaxation import force_matrix, relaxation_shapes
from forcecal.model.spatial import build_spatial_model
from forcecal.rig import parse_rig, rig_to_dict
from forcecal.simulate.physics import relaxation_modes
from forcecal.simulate.presets import get_preset
from forcecal.simulate.virtual_rig import (
    build_model,
    measure_run,
    measure_scan,
    public_rig,
    run_truth,
    scan_response,
    simulate_response,
)

BODY_TOL_PCT = 1.0          # total force, % of the true AC RMS (the benchmark: ~0.5 %)


def rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


def _simulate(preset, seed):
    """The block's FE model, public rig, a noisy scan and run, the run's truth and response."""
    fe = build_model(preset)
    rig = public_rig(preset)
    spec = preset.runs[0]
    r = simulate_response(preset, spec.drives, None, spec.duration, fe)
    rng = np.random.default_rng(seed)
    scan = measure_scan(preset, fe, scan_response(preset, fe), rng)
    run = measure_run(preset, spec, fe, r, rng)
    return preset, fe, rig, scan, run, run_truth(preset, fe, r), r


@pytest.fixture(scope="module")
def body():
    return _simulate(get_preset("body"), 7)


def _doc(rig):
    return rig_to_dict(rig)


# ------------------------------------------------------------------------------ the rig file


def test_rig_round_trip_keeps_locations(body):
    _, _, rig, *_ = body
    again = parse_rig(_doc(rig), source="again.toml")
    np.testing.assert_allclose(again.gauge_points, rig.gauge_points)
    np.testing.assert_allclose(again.force_points, rig.force_points)
    assert again.structure.total_mass == pytest.approx(rig.structure.total_mass)
    assert rig.structure.total_mass == pytest.approx(2700 * 0.5 * 0.3 * 0.04 + 0.3)


@pytest.mark.parametrize("edit, key", [
    (lambda d: d["gauges"][0].pop("direction"), "gauges[0].direction"),
    (lambda d: d["gauges"][1].update(direction=[0, 0, 0]), "gauges[1].direction"),
    (lambda d: d["sensors"][0].update(z=0.5), "sensors[0].x"),
    (lambda d: d["gauges"].pop(), "gauges"),
    (lambda d: d["structure"].update(blocks=[{"min": [0, 0, 0], "max": [0.5, 0.3, -1]}]),
     "structure.blocks[0].max"),
    (lambda d: d["structure"]["blocks"].append({"min": [0.1, 0.1, 0], "max": [0.2, 0.2, 0.01]}),
     "structure.blocks[1]"),
])
def test_bad_body_rig_names_the_key(body, edit, key):
    doc = _doc(body[2])
    edit(doc)
    with pytest.raises(RigError, match=f"key '{key.replace('[', '.').replace(']', '.')}"):
        parse_rig(doc, source="bad.toml")


def test_direction_is_for_bodies_only():
    doc = _doc(public_rig(get_preset("paper")))
    doc["gauges"][0]["direction"] = [0, 0, 1]
    with pytest.raises(RigError, match=r"gauges.0..direction' applies to a 3-D body only"):
        parse_rig(doc)


def test_directions_are_normalised(body):
    doc = _doc(body[2])
    doc["gauges"][3]["direction"] = [5.0, 0, 0]
    assert parse_rig(doc).gauges[3].direction == (1.0, 0.0, 0.0)


# ------------------------------------------------------------------- relaxation shapes (3-D)


def test_relaxation_shapes_are_the_identity_at_the_gauges(body):
    rig = body[2]
    np.testing.assert_allclose(relaxation_shapes(rig, rig.gauge_points), np.eye(6), atol=1e-12)


def test_relaxation_shapes_match_the_simulators_rigid_motions(body):
    """The estimator's psi_r (its own algebra) against the FE model's rigid motion vectors,
    compared along random directions at random points."""
    preset, fe, rig, *_ = body
    rng = np.random.default_rng(3)
    pts = rng.uniform([0, 0, 0], [0.5, 0.3, 0.04], size=(20, 3))
    d = rng.standard_normal((20, 3))
    loc = np.column_stack([pts, d / np.linalg.norm(d, axis=1, keepdims=True)])
    np.testing.assert_allclose(relaxation_shapes(rig, loc),
                               relaxation_modes(fe, preset) @ fe.row(loc).T, atol=1e-10)


def test_gauges_whose_lines_meet_one_line_are_refused(body):
    """Condition IV: all six lines of action meeting the z axis leave the rotation about it
    unresisted."""
    doc = _doc(body[2])
    lines = [((0.2, 0.1, 0.0), (-0.2, -0.1, 0.0)), ((0.4, 0.2, 0.02), (-0.4, -0.2, 0.0)),
             ((0.3, 0.0, 0.0), (-0.3, 0.0, 0.1)), ((0.1, 0.3, 0.04), (-0.1, -0.3, 0.2)),
             ((0.5, 0.1, 0.01), (-0.5, -0.1, -0.3)), ((0.0, 0.0, 0.02), (1.0, 1.0, 1.0))]
    for g, (p, d) in zip(doc["gauges"], lines, strict=True):
        g["x"], g["y"], g["z"] = p
        g["direction"] = list(d)
    rig = parse_rig(doc)
    with pytest.raises(ConditioningError, match="lines of action all meet one line"):
        force_matrix(rig)


def test_block_quadrature_couples_rigid_motions_exactly(body):
    """m_r of a rigid translation along x is the mass the relaxed gauge r carries along x:
    sum over r of m_r[e_x] weighted by each gauge's direction's x gives the total mass."""
    rig = body[2]
    pts, w = mass_weights(rig)
    ex = pts[:, 3]                                     # u = e_x, so d . u = d_x
    coupling = w @ ex                                  # (6,) [kg]
    # a rigid translation u = e_x is sum_r psi_r * (d_r . e_x) at the gauges: sum r m_r d_r,x
    total = coupling @ rig.gauge_points[:, 3]
    assert total == pytest.approx(rig.structure.total_mass, rel=1e-12)


# ------------------------------------------------------------------------- bases and files


def test_face_scans_keep_only_the_functions_they_tell_apart():
    """Points on the top and the four sides of a box cannot see x(x-a) y(y-b) (z-c); the
    basis drops it (and its multiples) instead of failing, and fits a field it contains."""
    rng = np.random.default_rng(5)
    g = np.linspace(0, 1, 7)
    top = np.array([[x, y, 1.0] for x in g for y in g])
    sides = np.array([[x0, y, z] for x0 in (0.0, 1.0) for y in g for z in (0.25, 0.5, 0.75)]
                     + [[x, y0, z] for y0 in (0.0, 1.0) for x in g for z in (0.25, 0.5, 0.75)])
    pts = np.vstack([top, sides])
    ext = ((0, 1), (0, 1), (0, 1))
    basis = orthonormal_basis(pts, ext, 7)
    b = basis.evaluate(pts)
    np.testing.assert_allclose(b.T @ b, np.eye(basis.n_funcs), atol=1e-9)
    assert basis.n_funcs < 84                           # some of the 84 functions are dropped
    field = 1 + pts[:, 0] ** 3 - 2 * pts[:, 0] * pts[:, 1] ** 2 + 0.5 * pts[:, 2]
    fit = fit_shape(pts, field + 1e-9 * rng.standard_normal(len(pts)), ext)
    inside = np.array([[0.3, 0.6, 0.4]])
    assert fit.evaluate(inside)[0] == pytest.approx(1 + 0.027 - 2 * 0.3 * 0.36 + 0.2, abs=1e-6)


@pytest.mark.parametrize("suffix", [".uff", ".npz"])
def test_located_scan_round_trips(body, tmp_path, suffix):
    scan = body[3]
    small = dataclasses.replace(scan, points=scan.points[:9], response=scan.response[:9, :64],
                                reference=scan.reference[:9, :64])
    path = tmp_path / f"scan{suffix}"
    (write_scan_uff if suffix == ".uff" else write_scan_npz)(small, path)
    back = read_scan(path, locations=True)
    np.testing.assert_allclose(back.points, small.points, atol=1e-15)
    np.testing.assert_allclose(back.response, small.response, rtol=1e-11, atol=1e-15)
    np.testing.assert_allclose(back.reference, small.reference, rtol=1e-11)


# --------------------------------------------------------------------------------- the method


def test_balance_of_the_virtual_block_holds_exactly(body):
    """METHOD.md eq. 6 on the FE truth: J_r = R_r + sum_n psi_r(x_n) . d_n f_n."""
    preset, fe, rig, _, _, truth, r = body
    psi = force_matrix(rig)
    gauges = -preset.beam.gauge_stiffness * (fe.row(rig.gauge_points) @ (r.u + fe.beta * r.v))
    resid = truth.inertia - gauges - psi @ truth.pole_force
    assert rms(resid) < 1e-7 * rms(gauges)


def test_body_forces_within_tolerance_and_far_better_than_reactions(body):
    _, _, rig, scan, run, truth, _ = body
    model = build_spatial_model(rig, scan)
    est = reconstruct(rig, model, run)
    true_total = truth.pole_force.sum(axis=0)
    ac = rms(true_total - true_total.mean())
    e = est.total_series - true_total
    es = est.static_series.sum(axis=0) - true_total
    err, static = 100 * rms(e - e.mean()) / ac, 100 * rms(es - es.mean()) / ac
    assert err < BODY_TOL_PCT
    assert static > 20 * err
    # the vector model: three components per harmonic, a resultant and three moments
    assert model.shapes[0].axes == (0, 1, 2)
    names = est.combination_names
    assert {"resultant_z", "moment_x", "moment_y", "moment_z"} <= set(names)


def test_tilted_poles_are_reconstructed_along_their_direction(body):
    """The poles pull at 30 degrees from z in the y-z plane: the x and y gauges now carry load,
    and the estimate still follows the truth."""
    preset = get_preset("body")
    d = (0.0, 0.5, np.sqrt(3) / 2)
    mag = preset.magnets[0]
    tilted = dataclasses.replace(preset, magnets=(dataclasses.replace(mag, poles=tuple(
        dataclasses.replace(p, direction=d) for p in mag.poles)),))
    _, _, rig, scan, run, truth, _ = _simulate(tilted, 11)
    y_gauge = run.channel("Y1")
    assert rms(y_gauge - y_gauge.mean()) > 10.0                    # in-plane load is real
    est = reconstruct(rig, build_spatial_model(rig, scan), run)
    true_total = truth.pole_force.sum(axis=0)
    e = est.total_series - true_total
    assert 100 * rms(e - e.mean()) / rms(true_total - true_total.mean()) < BODY_TOL_PCT


def test_modes_basis_is_refused_for_a_body(body):
    rig, scan = body[2], body[3]
    with pytest.raises(Exception, match="the modes basis does not serve a body"):
        build_spatial_model(rig, scan, basis="modes")


def test_cli_runs_a_body_end_to_end(body, tmp_path, capsys):
    """The module's body written as a lab's files (rig file, UFF scan, CSV run) through
    ``forcecal reconstruct``: its notes printed, its total against the truth."""
    import csv

    import tomli_w

    from forcecal.io.run_files import write_run_csv

    _, _, rig, scan, run, truth, _ = body
    (tmp_path / "rig.toml").write_text(tomli_w.dumps(_doc(rig)), encoding="utf-8")
    write_scan_uff(scan, tmp_path / "scan.uff")
    write_run_csv(run, tmp_path / "body.csv")
    rc = main(["reconstruct", str(tmp_path / "rig.toml"), str(tmp_path / "scan.uff"),
               str(tmp_path / "body.csv"), "-o", str(tmp_path / "res")])
    assert rc == 0
    # the estimate's notes are printed where the user looks, not only kept in the JSON
    printed = capsys.readouterr().out
    assert "note: harmonic 3: no shape in the scan model" in printed, printed
    with open(tmp_path / "res" / "body.forces.csv") as fh:
        rows = list(csv.DictReader(fh))
    total = np.array([float(r["total"]) for r in rows])
    true_total = truth.pole_force.sum(axis=0)
    e = total - true_total
    assert 100 * rms(e - e.mean()) / rms(true_total - true_total.mean()) < BODY_TOL_PCT



def test_report_on_a_body_draws_the_vector_model(body, tmp_path):
    """The report's shape figure for a body compares every record with the vector model."""
    from forcecal.report.pipeline import run_report

    _, _, rig, scan, run, *_ = body
    path = run_report(rig, scan, [run], tmp_path / "rep")
    assert path.is_file() and (tmp_path / "rep" / "figures" / "shapes.png").stat().st_size > 5000
    assert "resultant_z" in (tmp_path / "rep" / f"{run.name}.json").read_text()


def test_oblique_scan_record_is_refused_by_name(body):
    from forcecal.errors import InputError

    rig, scan = body[2], body[3]
    pts = scan.points.copy()
    pts[4, 3:] = [0.6, 0.0, 0.8]
    with pytest.raises(InputError, match=r"record 5 measures along .*not along x, y or z"):
        build_spatial_model(rig, dataclasses.replace(scan, points=pts))


def test_instantaneous_gaps_on_a_body(body):
    """Each pole's gap closes by the body's displacement along the pole's direction."""
    from forcecal.campaign import pole_motion

    _, _, rig, scan, run, truth, _ = body
    model = build_spatial_model(rig, scan)
    motion = pole_motion(rig, model, run, reconstruct(rig, model, run))
    err = motion.gaps(truth.t) - truth.gap
    dc = err.mean(axis=1)
    amplitude = 0.5 * (truth.gap.max(axis=1) - truth.gap.min(axis=1))
    assert np.all(np.abs(truth.gap.mean(axis=1) - 1e-3) > 1e-6)   # a DC deflection to find
    assert np.all(np.abs(dc) < 0.2e-6)
    assert np.all(np.max(np.abs(err - dc[:, None]), axis=1) < 0.02 * amplitude)
