"""The method on a plate on three gauges, and with fewer forces than gauges (synthetic data)."""

from __future__ import annotations

import numpy as np
import pytest

from forcecal.errors import ConditioningError, RigError
from forcecal.forces.solve import SPLIT_CONDITION
from forcecal.forces.steady import reconstruct
from forcecal.model.basis import fit_shape
from forcecal.model.inertia import mass_coupling
from forcecal.model.relaxation import force_matrix, relaxation_shapes
from forcecal.model.spatial import build_spatial_model
from forcecal.records import Run, Scan
from forcecal.rig import parse_rig

A, B = 0.5, 0.4
RHO = 60.0                      # kg/m^2
GAUGES = ((0.05, 0.05), (0.45, 0.05), (0.25, 0.35))


def plate_rig(forces=((0.2, 0.2), (0.3, 0.2)), gauges=GAUGES,
              sensors=((0.1, 0.3), (0.4, 0.3), (0.1, 0.1), (0.4, 0.1))):
    return parse_rig({
        "name": "plate",
        "structure": {"kind": "plate", "mass_per_area": RHO,
                      "outline": [[0, 0], [A, 0], [A, B], [0, B]],
                      "masses": [{"x": 0.25, "y": 0.2, "mass": 0.3}]},
        "gauges": [{"name": f"R{k + 1}", "x": x, "y": y} for k, (x, y) in enumerate(gauges)],
        "forces": [{"name": f"F{k + 1}", "x": x, "y": y, "gap": 1e-3}
                   for k, (x, y) in enumerate(forces)],
        "sensors": [{"name": f"s{k + 1}", "x": x, "y": y} for k, (x, y) in enumerate(sensors)],
        "actuator": {"current": "i"},
        "acquisition": {"frequency": 20.0},
    }, source="plate.toml")


def shape2d(p):
    return np.sin(np.pi * p[:, 0] / A) * np.sin(np.pi * p[:, 1] / B) + 0.03 + 0.02 * p[:, 0]


def plate_scan(rng, coef, shape_fn=shape2d, fs=4000.0, duration=0.5, noise=0.0):
    xx, yy = np.meshgrid(np.linspace(0, A, 11), np.linspace(0, B, 9))
    pts = np.column_stack([xx.ravel(), yy.ravel()])
    t = np.arange(int(duration * fs)) / fs
    w = 2 * np.pi * 20.0
    tau = rng.uniform(0, 0.05, len(pts))
    resp = np.zeros((len(pts), len(t)))
    for n, c in enumerate(coef, start=1):
        ph = np.exp(1j * n * w * (t[None, :] + tau[:, None]))
        resp += (1j * n * w * c * shape_fn(pts)[:, None] * ph).real
    ref = (0.5 * np.exp(1j * w * (t[None, :] + tau[:, None]))).real
    resp += noise * rng.standard_normal(resp.shape)
    return Scan(points=pts, response=resp, reference=ref, fs=fs)


def test_plate_relaxation_shapes_are_barycentric():
    rig = plate_rig()
    np.testing.assert_allclose(relaxation_shapes(rig, rig.gauge_points), np.eye(3), atol=1e-14)
    p = np.array([[0.1, 0.2], [0.4, 0.33]])
    np.testing.assert_allclose(relaxation_shapes(rig, p).sum(axis=0), 1.0, atol=1e-14)


def test_collinear_gauges_are_refused():
    with pytest.raises(ConditioningError, match="statically determinate"):
        force_matrix(plate_rig(gauges=((0.05, 0.1), (0.25, 0.1), (0.45, 0.1))))


def test_plate_rigid_translation_couplings_add_up_to_the_total_mass():
    rig = plate_rig()
    scan = plate_scan(np.random.default_rng(0), [1e-5], shape_fn=lambda p: np.ones(len(p)))
    model = build_spatial_model(rig, scan, n_harmonics=1)
    phi = model.shape_values(1, np.array([[0.2, 0.2]]))[0]
    m = (model.couplings[0] / phi).real
    np.testing.assert_allclose(m.sum(), RHO * A * B + 0.3, rtol=1e-12)
    # each coupling: integral of rho psi_r (barycentric, linear) over the rectangle + lumped
    centroid_psi = relaxation_shapes(rig, np.array([[A / 2, B / 2]]))[:, 0]
    lumped = 0.3 * relaxation_shapes(rig, np.array([[0.25, 0.2]]))[:, 0]
    np.testing.assert_allclose(m, RHO * A * B * centroid_psi + lumped, rtol=1e-12)


def test_plate_mass_coupling_of_a_bending_shape():
    rig = plate_rig()
    m = mass_coupling(rig, lambda p: p[:, 0] ** 2 * p[:, 1])
    # psi_r = c0 + c1 x + c2 y; integrals of x^2 y, x^3 y, x^2 y^2 over the rectangle
    coef = np.linalg.inv(np.array([[1, x, y] for x, y in GAUGES]).T)
    i = np.array([A**3 / 3 * B**2 / 2, A**4 / 4 * B**2 / 2, A**3 / 3 * B**3 / 3])
    lumped = 0.3 * relaxation_shapes(rig, np.array([[0.25, 0.2]]))[:, 0] * 0.25**2 * 0.2
    np.testing.assert_allclose(m, RHO * coef @ i + lumped, rtol=1e-12)


def _static_plate_run(rig, f, fs, t, model_sensors=4):
    reactions = -force_matrix(rig) @ f
    ch = {f"R{k + 1}": reactions[k] for k in range(3)}
    ch.update({f"s{k + 1}": np.zeros_like(t) for k in range(model_sensors)})
    ch["i"] = 0.5 * np.sin(2 * np.pi * 20.0 * t)
    return Run(channels=ch, fs=fs, name="static")


def test_fewer_forces_than_gauges_in_least_squares():
    rig = plate_rig()
    model = build_spatial_model(rig, plate_scan(np.random.default_rng(1), [1e-5], noise=1e-7),
                                n_harmonics=1)
    fs = 4000.0
    t = np.arange(1700) / fs
    w = 2 * np.pi * 20.0
    f = np.stack([5 + 2 * np.sin(w * t), 4 + 1.5 * np.sin(w * t + 0.2)])
    est = reconstruct(rig, model, _static_plate_run(rig, f, fs, t), n_harmonics=1)
    np.testing.assert_allclose(est.series, f, atol=1e-9)
    assert np.all(est.consistency < 1e-9)                         # consistent loads
    assert "moment_y" in est.combination_names
    # an inconsistent third reaction shows in the residual
    bad = _static_plate_run(rig, f, fs, t)
    ch = dict(bad.channels)
    ch["R3"] = ch["R3"] + 0.3
    est_bad = reconstruct(rig, model, Run(ch, fs, name="bad"), n_harmonics=1)
    assert est_bad.consistency[0] > 0.1


def test_close_forces_report_an_uncertain_split_and_a_sure_resultant():
    rng = np.random.default_rng(2)
    rig = plate_rig(forces=((0.245, 0.2), (0.255, 0.2)))
    model = build_spatial_model(rig, plate_scan(rng, [1e-5], noise=1e-7), n_harmonics=1)
    fs = 4000.0
    t = np.arange(2000) / fs
    f = np.stack([5 + 2 * np.sin(2 * np.pi * 20 * t)] * 2)
    run = _static_plate_run(rig, f, fs, t)
    ch = {k: v + (0.01 * rng.standard_normal(len(t)) if k.startswith("R") else
                  2e-9 * rng.standard_normal(len(t))) for k, v in run.channels.items()}
    est = reconstruct(rig, model, Run(ch, fs, name="close"), n_harmonics=1)
    assert est.psi_condition > SPLIT_CONDITION
    assert any("poorly determined" in note for note in est.notes)
    split, total = est.force_std[0, 1], est.total_std[1]
    assert split > 10 * total
    # the stated uncertainties are honest: the total is right within a few of its sigmas
    assert abs(est.total[1] - (-4j)) < 5 * total * np.sqrt(2)


def test_sensors_on_a_plate_node_line_are_refused():
    rig = plate_rig(sensors=((0.0, 0.1), (0.0, 0.3)))          # the x = 0 edge: no motion
    model = build_spatial_model(rig, plate_scan(
        np.random.default_rng(3), [1e-5],
        shape_fn=lambda p: np.sin(np.pi * p[:, 0] / A) * np.sin(np.pi * p[:, 1] / B)),
        n_harmonics=1)
    fs = 4000.0
    t = np.arange(2000) / fs
    run = _static_plate_run(rig, np.ones((2, len(t))), fs, t, model_sensors=2)
    with pytest.raises(ConditioningError, match="node"):
        reconstruct(rig, model, run, n_harmonics=1)


def test_modal_basis_represents_its_own_modes_exactly():
    x = np.linspace(0, 0.6, 41)
    values = 0.3 + 0.1 * x + np.sin(np.pi * x / 0.6) - 0.2 * np.sin(2 * np.pi * x / 0.6)
    fit = fit_shape(x, values, (0, 0.6), family="modes")
    assert fit.order == 4
    np.testing.assert_allclose(fit.evaluate(x), values, atol=1e-12)
    poly = fit_shape(x, values, (0, 0.6))
    assert poly.order > fit.order                              # polynomials need more terms


def test_plate_rig_without_y_is_refused(tmp_path):
    doc = {"structure": {"kind": "plate", "mass_per_area": 1.0,
                         "outline": [[0, 0], [1, 0], [0, 1]]},
           "gauges": [{"name": "R1", "x": 0.1}], "forces": [{"name": "F1", "x": 0.2, "y": 0.1}],
           "sensors": [{"name": "s1", "x": 0.3, "y": 0.1}]}
    with pytest.raises(RigError, match=r"gauges\[0\]\.y' is missing"):
        parse_rig(doc, source="p.toml")


@pytest.fixture(scope="module")
def plate_lab(tmp_path_factory):
    from forcecal.simulate.export import write_simulation

    return write_simulation(tmp_path_factory.mktemp("plate"), "plate", seed=0)


def test_plate_forces_against_the_virtual_rig(plate_lab):
    """Three gauges, two poles, four probes: the total force within 0.2 % of its AC RMS."""
    from forcecal.io.run_files import read_run, read_table_csv
    from forcecal.io.uff import read_scan_uff
    from forcecal.rig import load_rig

    rig = load_rig(plate_lab / "rig.toml")
    assert rig.structure.kind == "plate" and len(rig.gauges) == 3 and len(rig.forces) == 2
    model = build_spatial_model(rig, read_scan_uff(plate_lab / "scan.uff"))
    est = reconstruct(rig, model, read_run(plate_lab / "runs" / "plate.csv"))
    _, truth = read_table_csv(plate_lab / "truth" / "plate.forces.csv")

    def ac_error(x, true):
        e = x - true
        return np.sqrt(np.mean((e - e.mean()) ** 2)) / np.std(true)

    full = ac_error(est.total_series, truth["total"])
    static = ac_error(est.static_series.sum(axis=0), truth["total"])
    assert full < 0.002
    assert static > 5 * full
    # the stated waveform uncertainty is of the size of the error (not 10x off either way)
    assert 0.2 < full * np.std(truth["total"]) / est.waveform_std < 5


def test_inside_polygon_on_a_concave_outline():
    from forcecal.structures.plate import inside_polygon

    outline = np.array([[0, 0], [0.5, 0], [0.5, 0.4], [0.2, 0.4], [0.2, 0.2], [0, 0.2]])
    points = np.array([[0.1, 0.1], [0.1, 0.3], [0.3, 0.3], [0.5, 0.2], [0.2, 0.3], [0.6, 0.1]])
    np.testing.assert_array_equal(inside_polygon(outline, points),
                                  [True, False, True, True, True, False])


def test_instantaneous_gaps_on_a_plate(plate_lab):
    """The poles' gaps from the plate's shapes, coordinates and probes' DC follow the truth
    (the pole positions are (x, y) points: a beam's x alone would not evaluate the shape)."""
    from forcecal.campaign import pole_motion
    from forcecal.io.run_files import read_run
    from forcecal.io.uff import read_scan_uff
    from forcecal.rig import load_rig

    rig = load_rig(plate_lab / "rig.toml")
    model = build_spatial_model(rig, read_scan_uff(plate_lab / "scan.uff"))
    run = read_run(plate_lab / "runs" / "plate.csv")
    motion = pole_motion(rig, model, run, reconstruct(rig, model, run))
    truth = np.load(plate_lab / "truth" / "plate.npz")
    err = motion.gaps(truth["time"]) - truth["gap"]
    dc = err.mean(axis=1)
    amplitude = 0.5 * (truth["gap"].max(axis=1) - truth["gap"].min(axis=1))
    assert np.all(np.abs(dc) < 0.2e-6)                      # the mean deflection is 4 um
    assert np.all(np.max(np.abs(err - dc[:, None]), axis=1) < 0.02 * amplitude)
