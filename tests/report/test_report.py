"""Tests of the report: figures draw exactly the stage results they are given, PNGs are written
atomically, and the HTML page is self-contained and escaped.

The data are the simulated 'paper' rig (simulated once per session); every drawn line is read
back from its Line2D and compared with the result it should show.
"""

from __future__ import annotations

import base64
import dataclasses
import html
import re
from itertools import count
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from matplotlib.figure import Figure

from forcecal.actuator import Calibration, predict
from forcecal.campaign import calibrate_campaign
from forcecal.cli.main import main
from forcecal.cli.parser import build_parser
from forcecal.errors import DimensionError, InputError
from forcecal.forces.diagnostics import FALSE_ALARM
from forcecal.forces.steady import channels_si, reconstruct
from forcecal.io.run_files import read_run, read_table_csv
from forcecal.io.uff import read_scan_uff
from forcecal.model.scan import harmonic_shapes
from forcecal.model.spatial import build_spatial_model
from forcecal.report import (
    CalibrationPoints,
    Image,
    Preformatted,
    Section,
    Table,
    build_report,
    estimate_table,
    fig_calibration,
    fig_coordinates,
    fig_forces,
    fig_residuals,
    fig_shapes,
    fig_signals,
    law_harmonics,
    save_png,
    write_report,
)
from forcecal.report.figures.forces import force_sigma
from forcecal.report.pipeline import _run_section, _shapes_caption
from forcecal.rig import load_rig
from forcecal.signals.harmonics import fit_harmonics

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
PERIODS = 3.0
"""Periods drawn by the time-history figures (their default)."""
_FACTOR = {"m": 1.0, "mm": 1e3, "µm": 1e6, "nm": 1e9, "A": 1.0, "N": 1.0, "mN": 1e3, "µN": 1e6}


@pytest.fixture(scope="session")
def case(paper_dir):
    """The simulated 'paper' rig: rig, shapes, model, run, estimate and truth."""
    out = paper_dir                     # the session's 'paper' preset, seed 0 (conftest.py)
    rig = load_rig(out / "rig.toml")
    scan = read_scan_uff(out / "scan.uff")
    shapes = harmonic_shapes(scan, rig.frequency, 6)
    model = build_spatial_model(rig, scan, 6, shapes=shapes)
    run = read_run(out / "runs" / "paper.csv")
    estimate = reconstruct(rig, model, run)
    _, truth = read_table_csv(out / "truth" / "paper.forces.csv")
    return SimpleNamespace(rig=rig, shapes=shapes, model=model, run=run, estimate=estimate,
                           truth=truth)


def unit_factor(label: str) -> float:
    """The factor from SI to the unit in a label's last [...]."""
    return _FACTOR[label[label.rindex("[") + 1:label.rindex("]")]]


def line(ax, label: str):
    """The one Line2D of ``ax`` with this label."""
    hits = [ln for ln in ax.get_lines() if ln.get_label() == label]
    assert len(hits) == 1, f"{len(hits)} lines labelled {label!r}: " + ", ".join(
        ln.get_label() for ln in ax.get_lines())
    return hits[0]


def markers(ax, label: str):
    """The data line of the errorbar container with this label."""
    hits = [c for c in ax.containers if c.get_label() == label]
    assert len(hits) == 1, f"{len(hits)} error bar sets labelled {label!r}"
    return hits[0].lines[0]


def window(t: np.ndarray, f0: float) -> int:
    return int(np.searchsorted(t, t[0] + PERIODS / f0, side="right"))


def series(phasors: np.ndarray, f0: float, t: np.ndarray) -> np.ndarray:
    n = np.arange(phasors.shape[-1])
    return (phasors @ np.exp(2j * np.pi * f0 * np.outer(n, t))).real


# ------------------------------------------------------------------------------------ figures


def test_fig_shapes_draws_the_measured_and_fitted_shapes(case):
    fig = fig_shapes(case.shapes, case.model)
    harmonics = [int(n) for n in case.model.harmonics]
    assert isinstance(fig, Figure)
    assert len(fig.axes) == len(harmonics) + 1
    x = case.shapes.points[:, 0]
    for ax, n in zip(fig.axes[:-1], harmonics, strict=True):
        k = int(np.flatnonzero(case.shapes.harmonics == n)[0])
        f = unit_factor(ax.get_ylabel())
        re_fit, im_fit = line(ax, "Re fitted"), line(ax, "Im fitted")
        xf = re_fit.get_xdata() / 1e3
        assert xf[0] == pytest.approx(x.min()) and xf[-1] == pytest.approx(x.max())
        expected = case.model.shape_values(n, xf)
        np.testing.assert_allclose(re_fit.get_ydata() / f, expected.real, rtol=1e-12, atol=0)
        np.testing.assert_allclose(im_fit.get_ydata() / f, expected.imag, rtol=1e-12, atol=0)
        meas = markers(ax, "Re measured")
        np.testing.assert_allclose(meas.get_xdata() / 1e3, x)
        np.testing.assert_allclose(meas.get_ydata() / f, case.shapes.values[k].real, rtol=1e-12)
        np.testing.assert_allclose(markers(ax, "Im measured").get_ydata() / f,
                                   case.shapes.values[k].imag, rtol=1e-12)
        # the unit keeps the numbers readable (1 to 1000)
        assert 1 <= np.abs(f * case.shapes.values[k]).max() < 1000
        assert ax.get_ylabel().startswith(f"$H_{{{n}}}$")

    right = fig.axes[-1]
    for n in harmonics:
        (norm,) = [ln for ln in right.get_lines() if ln.get_label().startswith(f"n = {n} ")]
        xf = norm.get_xdata() / 1e3
        phi = case.model.shape_values(n, xf)
        expected = (phi / phi[np.argmax(np.abs(phi))]).real
        np.testing.assert_allclose(norm.get_ydata(), expected, rtol=1e-12)
        assert norm.get_ydata().max() == pytest.approx(1.0)
    legend = right.get_legend().get_title().get_text()
    assert f"one shape serves all: {'yes' if case.model.one_shape else 'no'}" in legend
    assert f"{case.model.similarity[0, 1]:.4f}" in legend


def test_fig_shapes_refuses_a_plate_scan(case):
    plate = dataclasses.replace(case.shapes, points=np.column_stack([case.shapes.points] * 2))
    with pytest.raises(DimensionError, match="1-D points"):
        fig_shapes(plate, case.model)


def test_fig_signals_overlays_the_fitted_fourier_series(case):
    rig, run, est = case.rig, case.run, case.estimate
    fig = fig_signals(run, rig, est)
    assert len(fig.axes) == 1 + len(rig.sensor_names)      # every probe in its own panel
    ax_i, *ax_s = fig.axes
    m = window(run.time, est.f0)
    sig = channels_si(rig, run)
    h = len(est.harmonics) - 1
    measured = line(ax_i, "i measured")
    np.testing.assert_allclose(measured.get_xdata(), run.time[:m] * 1e3)
    np.testing.assert_array_equal(measured.get_ydata(), sig["i"][:m])
    fit = fit_harmonics(sig["i"], run.fs, est.f0, h, t0=run.t0)
    np.testing.assert_allclose(line(ax_i, "i Fourier series").get_ydata(),
                               fit.evaluate(run.time[:m]), rtol=1e-12)
    assert "[A]" in ax_i.get_ylabel() and ax_s[-1].get_xlabel() == "time [ms]"
    colours = set()
    for ax, s in zip(ax_s, rig.sensor_names, strict=True):
        f = unit_factor(ax.get_ylabel())
        np.testing.assert_allclose(line(ax, f"{s} measured").get_ydata() / f, sig[s][:m],
                                   rtol=1e-12)
        fit = fit_harmonics(sig[s], run.fs, est.f0, h, t0=run.t0)
        np.testing.assert_allclose(line(ax, f"{s} Fourier series").get_ydata() / f,
                                   fit.evaluate(run.time[:m]), rtol=1e-9)
        colours.add(line(ax, f"{s} measured").get_color())
    assert len(colours) == len(rig.sensor_names)          # the symmetric rig's probes apart


def test_fig_coordinates_draws_each_harmonics_amplitude_and_inertia(case):
    rig, run, est = case.rig, case.run, case.estimate
    c = est.coordinates
    fig = fig_coordinates(run, rig, est, model=case.model)
    assert len(fig.axes) == 3
    ax_q, ax_a, ax_j = fig.axes
    grid = rig.structure.grid()
    peaks = np.array([np.abs(case.model.shape_values(int(n), grid)).max() for n in c.harmonics])
    # the coordinates as the displacement they stand for: no longer all of unit amplitude
    disp = markers(ax_q, "displacement")
    f = unit_factor(ax_q.get_ylabel())
    np.testing.assert_allclose(disp.get_ydata() / f, np.abs(c.q) * peaks, rtol=1e-12)
    assert np.ptp(np.log10(disp.get_ydata())) > 1              # 30 µm down to 50 nm
    w0 = 2 * np.pi * est.f0
    acc = markers(ax_a, "acceleration").get_ydata() / {"m/s²": 1.0, "mm/s²": 1e3}[
        ax_a.get_ylabel()[ax_a.get_ylabel().rindex("[") + 1:-1]]
    np.testing.assert_allclose(acc, (c.harmonics * w0) ** 2 * np.abs(c.q) * peaks, rtol=1e-12)
    # each value written with the digits its uncertainty warrants: u with two significant
    # digits, the value to the same decimal
    for text in ax_q.texts:
        amp, u = text.get_text().split()[0], text.get_text().split()[2]
        assert len(u.lstrip("0.")) == 2, text.get_text()
        assert len(amp.split(".")[1]) == len(u.split(".")[1]), text.get_text()
    # the inertia each harmonic gives, summed over the gauges, and their sum
    t = run.time[:window(run.time, est.f0)]
    total = est.inertia.sum(axis=0)
    for n in c.harmonics:
        only = np.zeros_like(total)
        only[n] = total[n]
        np.testing.assert_allclose(line(ax_j, f"n = {n}").get_ydata(), series(only, est.f0, t),
                                   rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(line(ax_j, "sum").get_ydata(), series(total, est.f0, t),
                               rtol=1e-9, atol=1e-12)
    plain = fig_coordinates(run, rig, est)                     # without a model: |Q_n| [1]
    np.testing.assert_allclose(markers(plain.axes[0], "displacement").get_ydata(), np.abs(c.q))


def _band(ax, label: str) -> tuple[float, float]:
    """(bottom, top) of the horizontal band with this label."""
    (band,) = [p for p in ax.patches if p.get_label() == label]
    return band.get_y(), band.get_y() + band.get_height()


def test_fig_forces_draws_forces_apart_and_their_errors_with_a_visible_band(case):
    est = case.estimate
    fig = fig_forces(est, case.truth)
    names = (*est.force_names, "total")
    assert len(fig.axes) == 2 + 2 * len(names)
    ax_j, ax_r, *columns = fig.axes
    m = window(est.time, est.f0)
    t = est.time[:m]
    # (1) the inertia terms and (2) the reactions, each on its own axis
    for r, g in enumerate(est.gauge_names):
        np.testing.assert_allclose(line(ax_j, g).get_ydata(), series(est.inertia[r], est.f0, t),
                                   rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(line(ax_r, g).get_ydata(),
                                   series(est.reactions[r], est.f0, t), rtol=1e-9, atol=1e-9)
    assert np.ptp(ax_j.get_ylim()) < 0.5 * np.ptp(ax_r.get_ylim())  # J not flattened by R
    sigma = force_sigma(est)
    np.testing.assert_allclose(sigma, np.sqrt(np.sum(np.vstack([est.force_std, est.total_std])
                                                     ** 2, axis=1)), rtol=1e-12)
    for k, name in enumerate(names):
        ax_f, ax_e = columns[2 * k], columns[2 * k + 1]       # every force in its own panel
        y = est.total_series[:m] if name == "total" else est.series[k, :m]
        np.testing.assert_array_equal(line(ax_f, name).get_ydata(), y)
        static = est.static_series.sum(axis=0) if name == "total" else est.static_series[k]
        assert line(ax_f, f"{name} reactions only").get_linestyle() == "--"
        np.testing.assert_array_equal(line(ax_f, f"{name} reactions only").get_ydata(),
                                      static[:m])
        truth = line(ax_f, f"{name} truth")
        assert truth.get_linestyle() == ":" and truth.get_color() == "k"
        assert truth.get_zorder() > line(ax_f, name).get_zorder()
        # (4) the error on its own scale, the +-2 sigma band visible on it
        f = unit_factor(columns[1].get_ylabel())
        np.testing.assert_allclose(line(ax_e, f"{name} error").get_ydata() / f,
                                   y - case.truth[name][:m], rtol=1e-9, atol=1e-15)
        lo, hi = _band(ax_e, f"{name} ±2σ")
        assert (lo / f, hi / f) == pytest.approx((-2 * sigma[k], 2 * sigma[k]), rel=1e-9)
        assert (hi - lo) / np.ptp(ax_e.get_ylim()) > 0.3, name
    # the reconstruction is much closer to the truth than the reactions-only estimate
    err = np.std(est.total_series - case.truth["total"])
    assert err < 0.1 * np.std(est.static_series.sum(axis=0) - case.truth["total"])

    plain = fig_forces(est)                 # without a truth: the residual and the band
    assert not [ln for ax in plain.axes for ln in ax.get_lines() if "truth" in ln.get_label()]
    ax_e = plain.axes[3]
    residual = line(ax_e, "F1 residual").get_ydata() / unit_factor(ax_e.get_ylabel())
    lo, hi = _band(ax_e, "F1 ±2σ")
    assert (hi - lo) / np.ptp(ax_e.get_ylim()) > 0.2
    assert np.std(residual) < 2 * sigma[0]          # at the estimate's resolution
    with pytest.raises(DimensionError, match="truth column 'F1'"):
        fig_forces(est, {"F1": case.truth["F1"][:-1]})


def test_fig_residuals_amplitudes_chi2_and_its_acceptance(case):
    est = case.estimate
    fig = fig_residuals(est, case.run, case.rig)
    assert len(fig.axes) == 3
    assert len(fig_residuals(est).axes) == 2
    ax_res, ax_c, ax_a = fig.axes
    n_channels = len(case.rig.gauge_names) + len(case.rig.sensor_names) + 2  # i, phi
    assert len(ax_res.get_lines()) == n_channels
    # each residual trace is the channel's fit residual / its sigma, offset
    sig = channels_si(case.rig, case.run)
    fit = fit_harmonics(sig["R1"], case.run.fs, est.f0, len(est.harmonics) - 1, t0=case.run.t0)
    y = line(ax_res, "R1").get_ydata()
    np.testing.assert_allclose(y - y.mean(), (fit.residuals - fit.residuals.mean())
                               / fit.residual_std, rtol=1e-9, atol=1e-9)
    chi2 = line(ax_c, "chi2")
    np.testing.assert_array_equal(chi2.get_ydata(), est.coordinates.chi2)
    # the probe check's acceptance: 2 probes, 1 shape, 2 degrees of freedom, whose reduced
    # chi-square quantile is -ln(rate) at the false-alarm rate shared by the harmonics
    (limit,) = [ln for ln in ax_c.get_lines() if ln.get_label().startswith("the check's limit")]
    rate = FALSE_ALARM / len(est.coordinates.harmonics)
    assert limit.get_ydata()[0] == pytest.approx(-np.log(rate), rel=1e-9)
    assert ax_c.get_ylim()[1] > -np.log(rate)
    assert ax_a.get_yscale() == "log"
    kept = est.kept & (np.abs(est.force[0]) > 0)
    for k, name in enumerate(est.force_names):
        amp = markers(ax_a, name)
        np.testing.assert_allclose(amp.get_ydata(), np.abs(est.force[k])[kept])
        np.testing.assert_allclose(np.round(amp.get_xdata()), est.harmonics[kept])
        np.testing.assert_allclose(line(ax_a, f"{name} reactions only").get_ydata(),
                                   np.abs(est.static[k])[est.kept])


# ------------------------------------------------------------------------ calibration figure

K = 1.0e-5  # N m^2 / A^2, one pole
GAPS = (0.8e-3, 1.0e-3, 1.2e-3)


def _law() -> Calibration:
    return Calibration(law="k_i2_s2", params=np.array([K]), covariance=np.array([[1e-18]]),
                       n_poles=2, current_range=(0.0, 1.2), gap_range=(0.7e-3, 1.3e-3))


def _points() -> CalibrationPoints:
    """Two poles of f = K i^2 / s^2 at i = I0 + I1 cos: F_0 = 2K(I0^2 + I1^2/2)/s^2,
    |F_1| = 4 K I0 I1 / s^2, plus a repeated run."""
    rows = [(g, dc, ac) for g in GAPS for dc in (0.4, 0.6, 0.8) for ac in (0.1, 0.2)]
    rows += [(1.0e-3, 0.6, 0.2)] * 2
    g, dc, ac = (np.array(c) for c in zip(*rows, strict=True))
    return CalibrationPoints(gap=g, dc=dc, ac=ac, force_dc=2 * K * (dc**2 + ac**2 / 2) / g**2,
                             force_ac=4 * K * dc * ac / g**2)


def test_fig_calibration_draws_points_law_and_collapse():
    pts = _points()
    fig = fig_calibration(pts, _law())
    assert len(fig.axes) == 4
    ax0, ax1, cx, dx = fig.axes
    tag = "gap 1.00 mm, AC 0.2 A"
    sel = (pts.gap == 1.0e-3) & (pts.ac == 0.2)
    np.testing.assert_array_equal(markers(ax0, tag).get_ydata(), pts.force_dc[sel])
    np.testing.assert_array_equal(markers(ax1, tag).get_ydata(), pts.force_ac[sel])
    # the repeated runs are counted
    assert "×3" in [t.get_text() for t in ax0.texts]
    # without the law at each run's own conditions: the cycle mean and fundamental of
    # predict() at the static gap, which the legend says
    law0, law1 = line(ax0, f"law {tag}"), line(ax1, f"law {tag}")
    i0 = law0.get_xdata()
    np.testing.assert_allclose(law0.get_ydata(), 2 * K * (i0**2 + 0.02) / 1e-6, rtol=1e-9)
    np.testing.assert_allclose(law1.get_ydata(), 4 * K * i0 * 0.2 / 1e-6, rtol=1e-9)
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert "law at the static gap (the structure's motion neglected)" in legend
    assert {"AC 0.1 A (law's dash)", "AC 0.2 A (law's dash)"} <= set(legend)
    # the collapse: every run's F_0 against the law's F_0, on measured = law
    runs = [ln for ln in cx.get_lines() if ln.get_label().startswith("measured, run")]
    assert len(runs) == pts.n_runs
    x = np.concatenate([ln.get_xdata() for ln in runs])
    np.testing.assert_allclose(x, 2 * K * (pts.dc**2 + pts.ac**2 / 2) / pts.gap**2, rtol=1e-9)
    np.testing.assert_allclose(np.concatenate([ln.get_ydata() for ln in runs]), pts.force_dc)
    # the relative difference, zero here, beside the law's +-2 sigma band: a law linear in
    # K has the relative standard uncertainty std(K) / K = 1e-4, so the band is +-0.02 %
    for ln in dx.get_lines():
        if ln.get_label().startswith("run"):
            assert np.all(np.abs(ln.get_ydata()) < 1e-9), ln.get_label()
    (band,) = [c for c in dx.collections if c.get_label() == "law ±2σ"]
    assert band.get_paths()[0].vertices[:, 1].max() == pytest.approx(0.02, rel=1e-6)
    assert 0.02 / dx.get_ylim()[1] > 0.2                          # visible on its scale
    assert dx.get_ylabel().endswith("[%]") and ax0.get_xlabel() == "DC current $I_0$ [A]"
    # the units in math text, the parameter with the digits its uncertainty warrants
    assert "K = 1.00000e-05 ± 1.0e-09 N m$^{2}$/A$^{2}$" in fig.get_suptitle()


def test_fig_calibration_draws_the_law_at_each_runs_own_conditions():
    pts = _points()
    law_dc = pts.force_dc * 1.02
    fig = fig_calibration(dataclasses.replace(pts, law_dc=law_dc, law_ac=pts.force_ac),
                          _law())
    ax0, _, cx, dx = fig.axes
    sel = (pts.gap == 0.8e-3) & (pts.ac == 0.1)
    np.testing.assert_allclose(line(ax0, "law at gap 0.80 mm, AC 0.1 A").get_ydata(),
                               np.sort(law_dc[sel]))
    # no curve at the static gap beside it, and the legend names the law at own conditions
    assert not [ln for ln in ax0.get_lines() if ln.get_label().startswith("law gap")]
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert "law at each run's own current and gaps" in legend
    np.testing.assert_allclose(line(cx, "measured, run 0").get_xdata(), law_dc[:1])
    np.testing.assert_allclose(line(dx, "run 0").get_ydata(), 100 * (1 / 1.02 - 1))


def test_fig_calibration_without_law_and_from_a_mapping():
    pts = _points()
    fig = fig_calibration({f.name: getattr(pts, f.name) for f in dataclasses.fields(pts)})
    assert len(fig.axes) == 2
    assert not [ln for ln in fig.axes[0].get_lines() if ln.get_label().startswith("law")]
    with pytest.raises(DimensionError, match="'dc' has shape"):
        CalibrationPoints(gap=pts.gap, dc=pts.dc[:-1], ac=pts.ac, force_dc=pts.force_dc,
                          force_ac=pts.force_ac)


def test_law_harmonics_of_a_known_law():
    fs, f0, n = 1000.0, 10.0, 1000
    t = np.arange(n) / fs
    current = 0.6 + 0.2 * np.cos(2 * np.pi * f0 * t)
    mean, fund = law_harmonics(_law(), current, np.full(n, 1.0e-3), fs, f0)
    assert mean == pytest.approx(2 * K * (0.36 + 0.02) / 1e-6, rel=1e-9)
    assert fund == pytest.approx(4 * K * 0.6 * 0.2 / 1e-6, rel=1e-9)


def test_calibration_points_from_a_campaign_collapse(paper_dir):
    rig = load_rig(paper_dir / "rig.toml")
    model = build_spatial_model(rig, read_scan_uff(paper_dir / "scan.uff"))
    result = calibrate_campaign(rig, model, paper_dir / "manifest.csv", workers=1)
    pts = CalibrationPoints.from_campaign(result)
    smp = result.runs[0].samples
    assert pts.names == ("paper",) and pts.samples is not None
    np.testing.assert_array_equal(pts.samples.force, smp.force)
    fig = fig_calibration(pts, result.calibration)
    ax0, ax1, cx, dx = fig.axes
    cal = result.calibration
    k = cal.params[0]
    u = smp.gaps + cal.law_object.gap_offset(cal.params)
    law = k * np.sum(smp.current[:, None] ** 2 / u**2, axis=1)   # at each sample's own gaps
    measured = line(cx, "measured, run paper")
    np.testing.assert_allclose(measured.get_xdata(), law, rtol=1e-9)
    np.testing.assert_array_equal(measured.get_ydata(), smp.force)
    static = [ln for ln in cx.get_lines() if ln.get_label().startswith("reactions only")]
    assert len(static) == 1
    np.testing.assert_array_equal(static[0].get_ydata(), smp.static_force)
    # every sample collapses onto the law, the reactions-only ones do not
    assert np.std(smp.force - law) < 0.2 * np.std(smp.static_force - law)
    # the law drawn at the run's own current and gaps agrees with its measured F_0, |F_1|
    # (the law at the static gap missed them by up to 40 %)
    for ax, measured_value in ((ax0, pts.force_dc), (ax1, pts.force_ac)):
        (drawn,) = [ln for ln in ax.get_lines() if ln.get_label().startswith("law at gap")]
        np.testing.assert_allclose(drawn.get_ydata(), measured_value, rtol=0.02)
    # the law's +-2 sigma band on the difference panel, at the samples' own conditions
    (band,) = [c for c in dx.collections if c.get_label() == "law ±2σ"]
    top = band.get_paths()[0].vertices[:, 1].max()
    rel_std = predict(cal, smp.current, smp.gaps).std / law
    assert top == pytest.approx(200 * rel_std.max(), rel=1e-9)
    assert top / dx.get_ylim()[1] > 0.01


def test_calibration_points_from_estimates(case):
    pts = CalibrationPoints.from_estimates(case.rig, [case.run], [case.estimate])
    est = case.estimate
    current = channels_si(case.rig, case.run)["i"]
    fit = fit_harmonics(current, case.run.fs, est.f0, 1, t0=case.run.t0)
    assert pts.gap[0] == case.rig.forces[0].gap
    assert pts.dc[0] == pytest.approx(fit.phasors[0].real)
    assert pts.ac[0] == pytest.approx(abs(fit.phasors[1]))
    assert pts.force_dc[0] == est.total[0].real
    assert pts.force_ac[0] == abs(est.total[1])
    assert pts.names == (est.run_name,)


# ------------------------------------------------------------------------------------ output


def _small_figure() -> Figure:
    fig = Figure(figsize=(3, 2))
    fig.add_subplot().plot([0, 1], [1, 0], label="line")
    return fig


def test_save_png_writes_a_png(tmp_path):
    path = save_png(_small_figure(), tmp_path / "sub" / "forces.png")
    assert path.read_bytes()[:8] == PNG_SIGNATURE
    assert [p.name for p in path.parent.iterdir()] == ["forces.png"]


def test_save_png_leaves_no_file_on_failure(tmp_path):
    fig = Figure()
    fig.add_subplot().plot([0, 1], [0, 1])

    def broken(fname, **kwargs):
        with open(fname, "wb") as fh:
            fh.write(PNG_SIGNATURE + b"half")
        raise RuntimeError("disk full")

    fig.savefig = broken
    with pytest.raises(RuntimeError, match="disk full"):
        save_png(fig, tmp_path / "f.png")
    assert list(tmp_path.iterdir()) == []
    # an existing file is left untouched
    (tmp_path / "f.png").write_bytes(b"old")
    with pytest.raises(RuntimeError):
        save_png(fig, tmp_path / "f.png")
    assert (tmp_path / "f.png").read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["f.png"]


def test_estimate_table(case):
    est = case.estimate
    rows = estimate_table(est)
    assert rows[0][:4] == ["force", "harmonic", "frequency [Hz]", "amplitude [N]"]
    kept = [int(n) for n in est.harmonics if est.kept[n]]
    assert len(rows) == 1 + (len(est.force_names) + 1) * len(kept)
    by_key = {(r[0], int(r[1])): r for r in rows[1:]}
    r = by_key[("F1", 1)]
    u = est.force_std[0, 1]
    assert float(r[3]) == pytest.approx(abs(est.force[0, 1]), abs=0.06 * u)
    assert float(r[4]) == pytest.approx(np.angle(est.force[0, 1]),
                                        abs=0.06 * u / abs(est.force[0, 1]))
    assert float(r[5]) == pytest.approx(u, rel=0.05)
    assert float(r[6]) == pytest.approx(abs(est.static[0, 1]), abs=0.06 * u)
    assert float(by_key[("total", 0)][3]) == pytest.approx(est.total[0].real,
                                                           abs=0.06 * est.total_std[0])
    assert float(by_key[("total", 2)][3]) == pytest.approx(abs(est.total[2]),
                                                           abs=0.06 * est.total_std[2])
    # the digits follow the uncertainty: an amplitude (and the reactions-only one) to the
    # decimal of its uncertainty's second significant digit, whatever its size
    for row in rows[1:]:
        decimals = len(row[5].split(".")[1])
        assert len(row[5].lstrip("0.")) == 2, row
        assert len(row[3].split(".")[1]) == decimals, row
        assert len(row[6].split(".")[1]) == decimals, row
    small = by_key[("F1", 3)]                 # |F_3| = 0.0012494 N with u = 0.00083 N
    assert float(small[3]) < 10 * float(small[5]) and len(small[3].split(".")[1]) == 5


def test_build_report_is_self_contained_and_escaped(tmp_path, case):
    rows = estimate_table(case.estimate)
    evil = "run <script>alert('x')</script> & co"
    fig = _small_figure()
    sections = [
        Section("Forces", [evil, rows, Image(_small_figure(), caption="fig. 8 <b>", dpi=40),
                           Table([["a<b", 1.5]], header=["name", "value"], caption="small")]),
        Section("Selection", [Preformatted("law  <chosen>\nK = 1"), fig,
                              Section("Nested", ["inner"])]),
    ]
    page = build_report("Report <1>", sections)
    assert page.startswith("<!DOCTYPE html>")
    assert "<script>" not in page
    assert html.escape(evil) in page
    assert "<title>Report &lt;1&gt;</title>" in page
    assert "fig. 8 &lt;b&gt;" in page and "&lt;chosen&gt;" in page
    uris = re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', page)
    assert len(uris) == 2
    assert all(base64.b64decode(u)[:8] == PNG_SIGNATURE for u in uris)
    assert not re.search(r'(src|href)="(?!data:)', page)  # no external asset
    for row in rows:
        for cell in row:
            assert f">{html.escape(cell)}<" in page
    assert "<h3>Nested</h3>" in page
    path = write_report(tmp_path / "report.html", "Report <1>", sections)
    assert path.read_text(encoding="utf-8").count("data:image/png;base64,") == 2


def test_build_report_refuses_unknown_blocks():
    with pytest.raises(InputError, match="cannot show a block of type dict"):
        build_report("t", [Section("s", [{"a": 1}])])


def test_the_report_numbers_its_figures_and_says_what_each_draws(case, tmp_path, monkeypatch):
    # the figures' pixels are tested above: a stand-in for their files keeps this quick
    monkeypatch.setattr("forcecal.report.pipeline.figure_bytes",
                        lambda fig, fmt="png", dpi=120: PNG_SIGNATURE + fmt.encode())
    numbers = count(1)
    caption = _shapes_caption(next(numbers), case.model, 1)
    assert caption.startswith("Fig. 1 (after the paper's fig. 3): ")
    assert len(case.model.scans) <= 1 and "other scans" not in caption   # one scan drawn
    assert ("set aside" in caption) == bool(case.model.set_aside)
    section = _run_section(case.rig, case.model, case.estimate, case.run, None, tmp_path,
                           "svg", numbers)
    images = [b for b in section.content if isinstance(b, Image)]
    assert [i.caption.split(" ")[1].rstrip(":") for i in images] == ["2", "3", "4", "5"]
    forces = images[2].caption
    assert "truth" not in forces and "residual about its Fourier series" in forces
    assert sorted(p.name for p in (tmp_path / "figures").iterdir()) == [
        f"paper.{name}.svg" for name in ("coordinates", "forces", "residuals", "signals")]
    assert all(i.width == 12 * 96 for i in images)      # shown at their drawn size


def test_the_figure_format_option_reaches_the_report(paper_dir, tmp_path, monkeypatch):
    parser = build_parser()
    for command in (["report", "rig.toml", "scan.uff", "run.csv", "-o", "out"],
                    ["calibrate", "rig.toml", "scan.uff", "--manifest", "m.csv", "-o", "out"]):
        assert parser.parse_args(command).figure_format == "png"
        assert parser.parse_args([*command, "--figure-format", "pdf"]).figure_format == "pdf"
    seen: dict = {}

    def report(rig, scan, runs, out_dir, **options):
        seen.update(options)
        path = Path(out_dir) / "report.html"
        path.write_text("<!DOCTYPE html>", encoding="utf-8")
        return path

    monkeypatch.setattr("forcecal.report.pipeline.run_report", report)
    monkeypatch.setattr("forcecal.model.spatial.load_model", lambda path: object())
    out = tmp_path / "out"
    assert main(["report", str(paper_dir / "rig.toml"), str(tmp_path / "model.json"),
                 str(paper_dir / "runs" / "paper.csv"), "-o", str(out), "-q",
                 "--figure-format", "svg"]) == 0
    assert seen["figure_format"] == "svg"
    assert (out / "report.html").is_file()
