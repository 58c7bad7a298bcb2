"""Tests of the top-level Python API: the whole chain through ``forcecal.NAME`` on the simulated
'paper' rig, the results' short reprs and notebook tables, and their pandas frames."""

from __future__ import annotations

import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest

import forcecal
from forcecal.actuator import predict
from forcecal.campaign import calibrate_campaign
from forcecal.forces import steady as forces
from forcecal.model import spatial

STEPS = ("load_rig", "read_scan", "read_run", "build_spatial_model", "load_model",
         "reconstruct", "calibrate", "write_calibration", "load_calibration", "predict",
         "predict_flux", "stream")
MAX_REPR = 300
"""A repr longer than this is a dump, not a summary."""


@pytest.fixture(scope="module")
def chain(paper_dir, tmp_path_factory):
    """Rig, scan, model (saved and loaded again), run, estimate and calibration, by the API."""
    out = tmp_path_factory.mktemp("api")
    rig = forcecal.load_rig(paper_dir / "rig.toml")
    scan = forcecal.read_scan(paper_dir / "scan.uff", rig=rig)
    built = forcecal.build_spatial_model(rig, scan)
    model = forcecal.load_model(built.save(out / "model.json"))
    run = forcecal.read_run(paper_dir / "runs" / "paper.csv")
    est = forcecal.reconstruct(rig, model, run)
    result = forcecal.calibrate(rig, model, paper_dir / "manifest.csv", workers=1)
    forcecal.write_calibration(result, out)
    cal = forcecal.load_calibration(out / "calibration.json")
    return SimpleNamespace(rig=rig, scan=scan, built=built, model=model, run=run, est=est,
                           result=result, cal=cal, out=out, paper_dir=paper_dir)


def test_every_step_is_a_documented_top_level_name():
    for name in STEPS:
        assert name in forcecal.__all__
        func = getattr(forcecal, name)
        assert callable(func) and func.__doc__ and "Parameters" in func.__doc__, name
    for name in ("read_scan", "calibrate", "load_calibration"):
        doc = getattr(forcecal, name).__doc__
        assert "Examples" in doc and "Returns" in doc, name
    with pytest.raises(AttributeError, match="no attribute 'nonsense'"):
        _ = forcecal.nonsense


def test_import_forcecal_stays_light():
    code = ("import sys, forcecal; heavy = [m for m in ('matplotlib', 'pandas', 'scipy.stats') "
            "if m in sys.modules]; print(','.join(heavy))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True)
    assert done.stdout.strip() == ""


def test_the_chain_gives_what_the_stage_functions_give(chain):
    direct = forces.reconstruct(chain.rig, spatial.build_spatial_model(chain.rig, chain.scan),
                                chain.run)
    np.testing.assert_allclose(chain.est.series, direct.series, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(chain.est.force, direct.force, rtol=1e-9, atol=1e-12)
    assert chain.est.run_name == "paper"
    np.testing.assert_array_equal(chain.model.harmonics, chain.built.harmonics)
    reference = calibrate_campaign(chain.rig, chain.model, chain.paper_dir / "manifest.csv",
                                   workers=1)
    np.testing.assert_allclose(chain.result.calibration.params, reference.calibration.params,
                               rtol=1e-12)
    assert chain.cal.law == chain.result.calibration.law
    np.testing.assert_allclose(chain.cal.params, chain.result.calibration.params, rtol=1e-12)
    np.testing.assert_allclose(chain.cal.covariance, chain.result.calibration.covariance,
                               rtol=1e-12)


def test_calibrate_builds_the_model_from_a_scan(chain):
    from_scan = forcecal.calibrate(chain.rig, chain.scan, chain.paper_dir / "manifest.csv",
                                   workers=1)
    assert from_scan.calibration.law == chain.result.calibration.law
    np.testing.assert_allclose(from_scan.calibration.params, chain.result.calibration.params,
                               rtol=1e-9)


@pytest.mark.parametrize("directed", [False, True])
def test_read_scan_reads_locations_on_a_directed_rig(monkeypatch, directed):
    from forcecal import api

    seen = {}

    def fake(path, reference_label="Ref", locations=False):
        seen.update(path=path, reference_label=reference_label, locations=locations)
        return "scan"

    monkeypatch.setattr(api, "_read_scan", fake)
    rig = SimpleNamespace(structure=SimpleNamespace(directed=directed))
    assert forcecal.read_scan("s.uff", rig=rig, reference_label="R") == "scan"
    assert seen == {"path": "s.uff", "reference_label": "R", "locations": directed}
    forcecal.read_scan("s.uff")
    assert seen["locations"] is False


def _check_short(text: str) -> None:
    assert len(text) < MAX_REPR, text
    assert "array(" not in text and "\n" not in text, text


def test_force_estimate_prints_a_summary(chain):
    est = chain.est
    text = repr(est)
    _check_short(text)
    assert "'paper'" in text and f"f0 = {est.f0:.6g} Hz" in text
    for k, name in enumerate(est.force_names):
        assert f"{name} {abs(est.force[k, 1]):.4g} ± {est.force_std[k, 1]:.2g}" in text
    assert f"total {abs(est.total[1]):.4g} ± {est.total_std[1]:.2g}" in text
    assert f"inertia share {100 * est.inertia_share:.1f} %" in text
    html = est._repr_html_()
    assert html.count("<tr>") == len(est.force_names) + 2 and "paper" in html
    assert f"{abs(est.static[0, 1]):.4g}" in html


def test_force_estimate_to_dataframe(chain, tmp_path):
    from forcecal.io.results import write_estimate

    est = chain.est
    df = est.to_dataframe()
    names = list(est.force_names)
    series, _ = write_estimate(est, tmp_path)                 # what `forcecal reconstruct` writes
    header = series.read_text(encoding="utf-8").split("\n", 1)[0].split(",")
    assert [df.index.name, *df.columns] == header
    assert list(df.columns) == [*names, "total", *(f"{n}_static" for n in names),
                                "total_static", *(f"{n}_std" for n in names), "total_std"]
    for name, values in est.columns().items():
        np.testing.assert_array_equal(df[name].to_numpy(), values, err_msg=name)
    np.testing.assert_array_equal(df.index.to_numpy(), est.time)
    np.testing.assert_array_equal(df[names].to_numpy().T, est.series)
    np.testing.assert_array_equal(df[[f"{n}_static" for n in names]].to_numpy().T,
                                  est.static_series)
    np.testing.assert_allclose(df["total"].to_numpy(), est.series.sum(axis=0), rtol=1e-12)
    np.testing.assert_allclose(df["total_static"].to_numpy(), est.static_series.sum(axis=0),
                               rtol=1e-12)


def test_force_estimate_harmonics_frame(chain):
    est = chain.est
    frame = est.harmonics_frame()
    assert frame.index.names == ["force", "harmonic"]
    assert len(frame) == est.force.size
    kept = est.kept.astype(bool)
    assert kept.any() and not kept.all()           # the paper run drops its upper harmonics
    estimated = ["amplitude", "phase", "std", "static_amplitude"]
    for k, name in enumerate(est.force_names):
        rows = frame.loc[name]
        np.testing.assert_array_equal(rows.index.to_numpy(), est.harmonics)
        for column, values in (("amplitude", np.abs(est.force[k])),
                               ("phase", np.angle(est.force[k])), ("std", est.force_std[k]),
                               ("static_amplitude", np.abs(est.static[k]))):
            np.testing.assert_array_equal(rows[column].to_numpy()[kept], values[kept])
        np.testing.assert_array_equal(rows["with_inertia"].to_numpy(), est.with_inertia)
        np.testing.assert_array_equal(rows["kept"].to_numpy(), kept)
        # a harmonic the data do not support has no estimate: NaN, not amplitude 0 at phase pi
        assert np.isnan(rows[estimated].to_numpy()[~kept]).all(), rows[~kept]


def test_spatial_model_prints_a_summary(chain):
    model = chain.model
    text = repr(model)
    _check_short(text)
    assert f"f0 {model.f0:.6g} Hz" in text
    orders = ", ".join(f"{int(n)} ({s.order})" for n, s in
                       zip(model.harmonics, model.shapes, strict=True))
    assert orders in text
    assert f"records set aside {len(model.set_aside)}" in text
    assert "<table>" in model._repr_html_()


def test_calibration_prints_its_law(chain):
    cal = chain.cal
    text = repr(cal)
    _check_short(text)
    assert f"'{cal.law}'" in text and cal.law_object.formula in text
    for name, value, std in zip(cal.law_object.param_names, cal.params, cal.stderr,
                                strict=True):
        assert f"{name} = {value:.6g} ± {std:.2g}" in text
    html = cal._repr_html_()
    assert html.count("<tr>") == len(cal.params) + 1


def test_a_campaign_prints_its_law_not_its_runs(chain):
    result = chain.result
    text = repr(result)
    _check_short(text)                                  # was the whole dataclass, 13,000 lines
    assert f"'{result.law}'" in text and f"{len(result.runs)} runs" in text
    for (name, value), std in zip(result.params.items(), result.calibration.stderr, strict=True):
        assert f"{name} = {value:.6g} ± {std:.2g}" in text
    assert repr(result) in result._repr_html_() or "&#x27;" in result._repr_html_()


def test_predict_at_the_top_level_is_the_actuator_s(chain):
    current = np.linspace(*chain.cal.current_range, 3)
    gap = float(np.mean(chain.cal.gap_range))
    top = forcecal.predict(chain.cal, current=current, gaps=gap)
    own = predict(chain.cal, current=current, gaps=gap)
    np.testing.assert_array_equal(top.total, own.total)
    assert forcecal.predict is predict


def test_predict_gives_floats_for_scalars_and_arrays_for_arrays():
    from forcecal.actuator import Calibration

    cal = Calibration(law="k_i2_s2", params=np.array([9e-6]), covariance=np.array([[1e-18]]),
                      n_poles=2, current_range=(0.8, 1.2), gap_range=(0.0008, 0.001))
    one = forcecal.predict(cal, 0.9, 0.0009)
    assert isinstance(one.total, float) and isinstance(one.std, float)
    assert one.per_pole.shape == (2,)
    assert one.total == pytest.approx(2 * 9e-6 * 0.9**2 / 0.0009**2, rel=1e-12)
    per_pole = forcecal.predict(cal, np.float64(0.9), [0.0009, 0.00095])   # a gap per pole
    assert isinstance(per_pole.total, float) and per_pole.per_pole.shape == (2,)
    for current, gaps, shape in (([0.9], 0.0009, (1,)), ([0.85, 0.9, 0.95], 0.0009, (3,)),
                                 (0.9, [[0.0009, 0.0009], [0.00095, 0.00095]], (2,))):
        many = forcecal.predict(cal, current, gaps)
        assert isinstance(many.total, np.ndarray) and many.total.shape == shape
        assert many.std.shape == shape and many.per_pole.shape == (*shape, 2)
    assert forcecal.predict(cal, [0.9], 0.0009).total[0] == one.total
    flux_cal = Calibration(law="flux", params=np.array([4e-4]), covariance=np.array([[1e-14]]),
                           n_poles=2, current_range=(0.8, 1.2), gap_range=(0.0008, 0.001),
                           flux_range=(1e-5, 1e-4))
    assert isinstance(forcecal.predict_flux(flux_cal, 5e-5).total, float)
    assert forcecal.predict_flux(flux_cal, [5e-5]).total.shape == (1,)
