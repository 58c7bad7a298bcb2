"""Reports assembled from the user's data: run forces and campaign calibration.

``run_report``: spatial model, forces of every run (with the truth overlaid when a folder of
``NAME.forces.csv`` ground truth is given), figures as PNG and one self-contained HTML page.
``calibration_report``: the campaign's fig. 9, the candidate laws and the repeatability.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..forces import ForceEstimate, reconstruct
from ..harmonics import fit_harmonics
from ..io.results import write_estimate
from ..io.run_files import read_table_csv
from ..records import Run, Scan
from ..rig import Rig
from ..scan import harmonic_shapes
from ..spatial import SpatialModel, build_spatial_model
from .figures import (
    CalibrationPoints,
    fig_calibration,
    fig_coordinates,
    fig_forces,
    fig_residuals,
    fig_shapes,
    fig_shapes_2d,
    fig_shapes_body,
    fig_signals,
    law_harmonics,
    save_png,
)
from .html import Image, Preformatted, Section, Table, estimate_table, write_report

__all__ = ["calibration_report", "run_report"]


def _pct(x: float) -> str:
    return f"{100 * x:.3g} %"


def _model_section(model: SpatialModel, shapes_png: Path, fig) -> Section:
    rows = [[int(n), s.order, f"{model.snr[int(n) - 1]:.1f}"]
            for n, s in zip(model.harmonics, model.shapes, strict=True)]
    rows += [[n, "-", f"dropped: {why}"] for n, why in sorted(model.dropped.items())]
    text = (f"Fundamental refined from the scan: {model.f0:.6g} Hz; {model.n_points} scan points. "
            f"Lowest MAC between the harmonics' shapes: {model.similarity.min():.5f}, so "
            + ("one shape serves all harmonics (the paper's eq. 19)."
               if model.one_shape else "each harmonic keeps its own shape."))
    return Section("Spatial model (SLDV scan)", [
        text,
        Table(rows, header=["harmonic", "basis order (GCV)", "scan signal-to-noise"],
              caption="Harmonic shapes"),
        Image(fig, caption="Fig. 3: phase-aligned harmonic deflection shapes over the scan with "
                           "the fitted curves, and their normalized overlay. "
                           f"({shapes_png.name})"),
    ])


def _truth_errors(est: ForceEstimate, truth: dict[str, np.ndarray]) -> list[list[str]]:
    rows = []
    for k, name in enumerate((*est.force_names, "total")):
        true = truth[name]
        est_s = est.total_series if name == "total" else est.series[k]
        stat = (est.static_series.sum(axis=0) if name == "total" else est.static_series[k])
        ac = np.sqrt(np.mean((true - true.mean()) ** 2))

        def err(x, true=true, ac=ac):
            e = x - true
            return np.sqrt(np.mean((e - e.mean()) ** 2)) / ac

        rows.append([name, _pct(err(est_s)), _pct(err(stat))])
    return rows


def run_report(rig: Rig, scan: Scan, runs: Sequence[Run], out_dir: str | Path,
               truth_dir: str | Path | None = None, n_harmonics: int = 6,
               criterion: str = "gcv", basis: str = "polynomial") -> Path:
    """Model, forces, figures and ``OUT/report.html`` for runs; returns the report's path.

    ``n_harmonics``, ``criterion`` and ``basis`` are those of
    :func:`forcecal.spatial.build_spatial_model`.
    """
    out = Path(out_dir)
    figs = out / "figures"
    hs = harmonic_shapes(scan, rig.frequency, n_harmonics) if rig.frequency else None
    model = build_spatial_model(rig, scan, n_harmonics=n_harmonics, criterion=criterion,
                                shapes=hs, basis=basis)
    model.save(out / "model.json")
    fig = {"beam": fig_shapes, "plate": fig_shapes_2d,
           "body": fig_shapes_body}[rig.structure.kind](hs, model)
    shapes_png = save_png(fig, figs / "shapes.png")
    sections = [_model_section(model, shapes_png, fig)]
    summary = []
    for run in runs:
        est = reconstruct(rig, model, run)
        write_estimate(est, out)
        truth = None
        if truth_dir is not None and (Path(truth_dir) / f"{run.name}.forces.csv").is_file():
            _, truth = read_table_csv(Path(truth_dir) / f"{run.name}.forces.csv")
        summary.append([run.name, f"{est.f0:.6g}", _pct(est.inertia_share),
                        f"{est.waveform_std:.3g}", f"{est.psi_condition:.3g}"])
        blocks: list = [
            f"Refined fundamental {est.f0:.6g} Hz. The inertia accounts for "
            f"{_pct(est.inertia_share)} of the AC force: that is how far a reactions-only "
            f"estimate is off. Standard uncertainty of the total force waveform: "
            f"{est.waveform_std:.3g} N (RMS over time).",
            Table(estimate_table(est)[1:], header=estimate_table(est)[0],
                  caption="Force phasors with standard uncertainties"),
        ]
        if truth is not None:
            blocks.append(Table(_truth_errors(est, truth),
                                header=["force", "error (full method)", "error (reactions only)"],
                                caption="Against the ground truth, % of its AC RMS"))
        if est.notes:
            blocks.append(Preformatted("\n".join(est.notes)))
        for name, f, caption in (
            ("signals", fig_signals(run, rig, est),
             "Fig. 6: measured current and displacements with the fitted Fourier series."),
            ("coordinates", fig_coordinates(run, rig, est),
             "Fig. 7: probe signals, generalized coordinates and accelerations."),
            ("forces", fig_forces(est, truth),
             "Fig. 8: inertia contribution and measured reactions; reconstructed forces with "
             "the reactions-only estimate (dashed)" + (" and the truth (dotted)." if truth
                                                       else ".")),
            ("residuals", fig_residuals(est, run, rig),
             "Fit residuals, sensor consistency and per-harmonic amplitudes with uncertainties."),
        ):
            png = save_png(f, figs / f"{run.name}.{name}.png")
            blocks.append(Image(f, caption=f"{caption} ({png.name})"))
        sections.append(Section(f"Run {run.name}", blocks))
    sections.insert(0, Section("Summary", [Table(
        summary, header=["run", "f0 (Hz)", "inertia share", "total-force std (N)",
                         "cond(Psi)"])]))
    return write_report(out / "report.html", f"forcecal: forces of {rig.name}", sections)


def calibration_report(rig: Rig, model: SpatialModel, result, out_dir: str | Path) -> Path:
    """Fig. 9 and the calibration tables of a campaign result as ``OUT/report.html``."""
    from ..campaign import report_text

    out = Path(out_dir)
    dc, ac, law_dc, law_ac = [], [], [], []
    for r in result.runs:
        smp, f0 = r.samples, r.estimate.f0
        fs = smp.n * f0                                 # the samples span one period evenly
        current = fit_harmonics(smp.current, fs, f0, 1, t0=smp.time[0]).phasors
        dc.append(current[0].real)
        ac.append(abs(current[1]))
        # the law at the run's own current and instantaneous gaps (the structure moves)
        a, b = law_harmonics(result.calibration, smp.current, smp.gaps, fs, f0, t0=smp.time[0])
        law_dc.append(a)
        law_ac.append(b)
    est = [r.estimate for r in result.runs]
    points = CalibrationPoints(
        gap=np.array([r.samples.static_gap for r in result.runs]), dc=np.array(dc),
        ac=np.array(ac), force_dc=np.array([e.total[0].real for e in est]),
        force_ac=np.array([abs(e.total[1]) for e in est]),
        force_dc_std=np.array([e.total_std[0] for e in est]),
        force_ac_std=np.array([e.total_std[1] for e in est]),
        law_dc=np.array(law_dc), law_ac=np.array(law_ac), names=tuple(r.name for r in result.runs))
    fig = fig_calibration(points, result.calibration)
    png = save_png(fig, out / "figures" / "calibration.png")
    sections = [
        Section("Calibration", [
            Preformatted(report_text(result)),
            Image(fig, caption="Fig. 9: force against DC current for each gap and AC amplitude, "
                               f"runs as markers, the calibrated law as curves ({png.name})."),
        ]),
    ]
    return write_report(out / "report.html", f"forcecal: calibration of {rig.name}", sections)
