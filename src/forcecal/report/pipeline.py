"""Reports assembled from the user's data: run forces and campaign calibration.

``run_report``: spatial model, forces of every run (with the truth overlaid when a folder of
``NAME.forces.csv`` ground truth is given), figures as PNG and one self-contained HTML page.
``calibration_report``: the campaign's calibration certificate (:mod:`.certificate`) with
fig. 9.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.figure import Figure

from ..forces.steady import ForceEstimate, reconstruct
from ..io.results import write_estimate
from ..io.run_files import read_table_csv
from ..model.scan import HarmonicShapes, harmonic_shapes
from ..model.spatial import SpatialModel, build_spatial_model, check_model_rig
from ..records import Run, Scan, ScanFRF, ScanSpectra
from ..rig import Rig
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
    save_png,
)
from .html import Image, Preformatted, Section, Table, estimate_table, write_report

if TYPE_CHECKING:
    from ..campaign import CampaignResult

__all__ = ["calibration_report", "run_report"]

_SHAPE_FIGURES: dict[int, Callable[[HarmonicShapes, SpatialModel], Figure]] = {
    1: fig_shapes, 2: fig_shapes_2d, 3: fig_shapes_body,
}
"""The shape figure (fig. 3) of a structure by its dimension: beam, plate, body."""


def _pct(x: float) -> str:
    return f"{100 * x:.3g} %"


def _scan_shapes(rig: Rig, scan: Scan | ScanSpectra | ScanFRF, n_harmonics: int
                 ) -> HarmonicShapes:
    """The scan's harmonic shapes at the rig's nominal drive frequency."""
    return harmonic_shapes(scan, rig.drive_frequency, n_harmonics)


def _model_scan(model: SpatialModel, rig: Rig) -> Scan | ScanSpectra | None:
    """The model's first scan, read again for fig. 3 (None when it is no longer there)."""
    from ..errors import ForcecalError
    from ..io.scan_files import read_scan

    path = Path(model.scans[0] if model.scans else model.source)
    if not path.is_file():
        return None
    try:
        scan = read_scan(path, locations=rig.structure.directed)
    except ForcecalError:
        return None
    return None if isinstance(scan, ScanFRF) else scan


def _model_section(model: SpatialModel, shapes_png: Path | None,
                   fig: Figure | None) -> Section:
    """The spatial model's section: fundamental, harmonic shapes table and fig. 3."""
    rows: list[list[Any]] = [[int(n), s.order, f"{model.snr[int(n) - 1]:.1f}",
                              len(model.members(k))]
                             for k, (n, s) in enumerate(zip(model.harmonics, model.shapes,
                                                            strict=True))]
    rows += [[n, "-", f"dropped: {why}", 0] for n, why in sorted(model.dropped.items())]
    text = (f"Fundamental refined from the scan: {model.f0:.6g} Hz; {model.n_points} scan points. "
            f"Lowest MAC between the harmonics' shapes: {model.similarity.min():.5f}, so "
            + ("one shape serves all harmonics (the paper's eq. 19)."
               if model.one_shape else "each harmonic keeps its own shape."))
    if len(model.scans) > 1:
        text += (f" Built from {len(model.scans)} scans under different loads ("
                 + ", ".join(model.scans) + "): each harmonic holds the shapes of the scans "
                 "that add to its span, and every run uses those its probes need.")
    blocks: list[Any] = [
        text,
        Table(rows, header=["harmonic", "basis order (GCV)", "scan signal-to-noise",
                            "shapes"], caption="Harmonic shapes"),
    ]
    if fig is not None and shapes_png is not None:
        blocks.append(Image(fig, caption="Fig. 3: phase-aligned harmonic deflection shapes over "
                                         "the scan with the fitted curves (other scans' shapes "
                                         "dotted, scaled onto the first's), and their normalized "
                                         f"overlay. ({shapes_png.name})"))
    else:
        blocks.append("Fig. 3 needs the scan's records: the model's scan "
                      f"'{model.scans[0] if model.scans else model.source}' is not at hand.")
    return Section("Spatial model (SLDV scan)", blocks)


def _ac_error(x: np.ndarray, true: np.ndarray) -> float:
    """RMS of the error's AC part relative to the AC RMS of the truth [1]."""
    e = x - true
    ac = np.sqrt(np.mean((true - true.mean()) ** 2))
    return float(np.sqrt(np.mean((e - e.mean()) ** 2)) / ac)


def _truth_errors(est: ForceEstimate, truth: dict[str, np.ndarray]) -> list[list[str]]:
    """Rows (force, error of the full method, error of the reactions only) against the truth."""
    rows = []
    for k, name in enumerate((*est.force_names, "total")):
        true = truth[name]
        est_s = est.total_series if name == "total" else est.series[k]
        stat = (est.static_series.sum(axis=0) if name == "total" else est.static_series[k])
        rows.append([name, _pct(_ac_error(est_s, true)), _pct(_ac_error(stat, true))])
    return rows


def _read_truth(truth_dir: str | Path | None, run: Run) -> dict[str, np.ndarray] | None:
    """The run's ground truth ``NAME.forces.csv`` in ``truth_dir``, or None without one."""
    if truth_dir is None or not (Path(truth_dir) / f"{run.name}.forces.csv").is_file():
        return None
    _, truth = read_table_csv(Path(truth_dir) / f"{run.name}.forces.csv")
    return truth


def _run_figures(rig: Rig, run: Run, est: ForceEstimate, truth: dict[str, np.ndarray] | None,
                 figs: Path) -> list[Image]:
    """Figs. 6 to 8 and the diagnostics of one run, written as PNG into ``figs``."""
    images = []
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
        images.append(Image(f, caption=f"{caption} ({png.name})"))
    return images


def _budget_table(est: ForceEstimate) -> tuple[list[list[Any]], list[str], str]:
    """Rows (source, each force's and the total's DC and fundamental std) of the budget."""
    names = [*est.force_names, "total"]
    idx = [est.combination_names.index(n) for n in names]
    header = ["source"] + [f"{n} {part}" for n in names for part in ("DC", "n = 1")]

    def cells(std: np.ndarray) -> list[str]:
        return [f"{std[k, j]:.3g}" for k in idx for j in (0, 1)]

    rows: list[list[Any]] = [[src, *cells(std)] for src, std in est.budget.items()]
    assert est.combination_std is not None
    rows.append(["combined standard uncertainty", *cells(est.combination_std)])
    rows.append(["expanded (k = 2)", *cells(est.expanded())])
    if est.monte_carlo_std is not None:
        rows.append([f"Monte Carlo ({est.monte_carlo_draws} draws, noise and type B)",
                     *cells(est.monte_carlo_std)])
    caption = ("Uncertainty budget, N: each source's standard uncertainty. "
               + (est.type_b.describe() if est.type_b is not None else ""))
    return rows, header, caption


def _run_section(rig: Rig, est: ForceEstimate, run: Run, truth: dict[str, np.ndarray] | None,
                 figs: Path) -> Section:
    """One run's section: its forces with uncertainties, errors against the truth, figures."""
    blocks: list[Any] = [
        f"Refined fundamental {est.f0:.6g} Hz. The inertia accounts for "
        f"{_pct(est.inertia_share)} of the AC force: that is how far a reactions-only "
        f"estimate is off. Standard uncertainty of the total force waveform: "
        f"{est.waveform_std:.3g} N (RMS over time).",
        Table(estimate_table(est)[1:], header=estimate_table(est)[0],
              caption="Force phasors with standard uncertainties"),
    ]
    if est.budget:
        blocks.append(Table(*_budget_table(est)))
    if truth is not None:
        blocks.append(Table(_truth_errors(est, truth),
                            header=["force", "error (full method)", "error (reactions only)"],
                            caption="Against the ground truth, % of its AC RMS"))
    if est.notes:
        blocks.append(Preformatted("\n".join(est.notes)))
    blocks += _run_figures(rig, run, est, truth, figs)
    return Section(f"Run {run.name}", blocks)


def run_report(rig: Rig, scan: Scan | ScanSpectra | ScanFRF | SpatialModel, runs: Sequence[Run],
               out_dir: str | Path,
               truth_dir: str | Path | None = None, n_harmonics: int = 6,
               criterion: str = "gcv", basis: str = "polynomial",
               provenance: dict | None = None,
               progress: Callable[[str], None] | None = None) -> Path:
    """Model, forces, figures and ``OUT/report.html`` for runs.

    Parameters
    ----------
    rig : Rig
        The rig the scan and the runs were measured on.
    scan : Scan or SpatialModel
        The SLDV scan the spatial model is built from, or a model already built (from one
        scan or several: fig. 3 then shows its first scan's measured shapes when that file is
        still where the model says, and the fitted shapes only otherwise).
    runs : Sequence of Run
        The runs whose forces are reconstructed.
    out_dir : str or pathlib.Path
        The output folder: ``model.json``, the estimates, ``figures/*.png``, ``report.html``.
    truth_dir : str or pathlib.Path, optional
        A folder of ground truth ``NAME.forces.csv`` per run, overlaid where present.
    n_harmonics : int
        As for :func:`forcecal.model.spatial.build_spatial_model`.
    criterion : str
        As for :func:`forcecal.model.spatial.build_spatial_model`.
    basis : str
        As for :func:`forcecal.model.spatial.build_spatial_model`.
    provenance : dict, optional
        :func:`forcecal.provenance.provenance` of the inputs (default: of the model's scans and
        the runs' files, as far as they are files).
    progress : callable, optional
        Called with a line as each stage starts (the model, each run, the page).

    Returns
    -------
    pathlib.Path
        The path of ``report.html``.
    """
    out = Path(out_dir)
    figs = out / "figures"
    say = progress or (lambda _line: None)
    say("  spatial model and fig. 3")
    if isinstance(scan, SpatialModel):
        check_model_rig(scan, rig)
        model, first = scan, _model_scan(scan, rig)
        hs = None if first is None else _scan_shapes(rig, first, len(model.snr))
    else:
        hs = _scan_shapes(rig, scan, n_harmonics)
        model = build_spatial_model(rig, scan, n_harmonics=n_harmonics, criterion=criterion,
                                    shapes=hs, basis=basis)
    model.save(out / "model.json")
    if hs is not None:
        fig = _SHAPE_FIGURES[rig.structure.dim](hs, model)
        shapes_png = save_png(fig, figs / "shapes.png")
        sections = [_model_section(model, shapes_png, fig)]
    else:
        sections = [_model_section(model, None, None)]
    summary = []
    for k, run in enumerate(runs):
        say(f"  run {k + 1}/{len(runs)} {run.name}: forces and figs. 6-8")
        est = reconstruct(rig, model, run)
        write_estimate(est, out)
        summary.append([run.name, f"{est.f0:.6g}", _pct(est.inertia_share),
                        f"{est.waveform_std:.3g}", f"{est.psi_condition:.3g}"])
        sections.append(_run_section(rig, est, run, _read_truth(truth_dir, run), figs))
    sections.insert(0, Section("Summary", [Table(
        summary, header=["run", "f0 (Hz)", "inertia share", "total-force std (N)",
                         "cond(Psi)"])]))
    if provenance is None:
        from ..provenance import provenance as make

        provenance = make([rig.source, *(model.scans or [model.source]),
                           *(r.source for r in runs)])
    sections.append(provenance_section(provenance))
    return write_report(out / "report.html", f"forcecal: forces of {rig.name}", sections)


def provenance_section(prov: dict) -> Section:
    """The report's last section: version, date, command line, every input's SHA-256."""
    rows = [[f["path"], f.get("bytes", "-"), f.get("sha256", "not a file")]
            for f in prov["inputs"]]
    return Section("Provenance", [
        f"forcecal {prov['forcecal_version']} (Python {prov['python']}), "
        f"{prov['created_utc']}; command: {prov['command']}",
        Table(rows, header=["input", "bytes", "SHA-256"], caption="Input files"),
    ])


def campaign_inputs(rig: Rig, model: SpatialModel, result: CampaignResult) -> list[str]:
    """Every input file of a campaign's calibration: the rig, the model's scans, the manifest
    and every run it lists (the tare records too), in that order, each once.

    Parameters
    ----------
    rig : Rig
    model : SpatialModel
    result : CampaignResult

    Returns
    -------
    list of str
        The paths (those that are not files are kept: the provenance says so).
    """
    from ..errors import ForcecalError
    from ..io.manifest import read_manifest

    runs = [str(r.entry.run) for r in result.runs]
    try:
        runs = [str(e.run) for e in read_manifest(result.manifest)]
    except ForcecalError:  # the manifest is no longer there: the runs calibrated are
        pass
    return list(dict.fromkeys([rig.source, *(model.scans or [model.source]), result.manifest,
                               *runs]))


def _with_inputs(prov: dict, paths: Sequence[str]) -> dict:
    """The provenance with the files of ``paths`` it does not list yet added."""
    from ..provenance import provenance as make

    listed = {Path(f["path"]).resolve() for f in prov["inputs"]}
    missing = [p for p in paths if Path(p).resolve() not in listed]
    if not missing:
        return prov
    return {**prov, "inputs": [*prov["inputs"], *make(missing, argv=[])["inputs"]]}


def calibration_report(rig: Rig, model: SpatialModel, result: CampaignResult,
                       out_dir: str | Path, provenance: dict | None = None) -> Path:
    """The calibration certificate of a campaign as ``OUT/report.html``, fig. 9 as a PNG.

    The page is :func:`forcecal.report.certificate.calibration_certificate`: the law, its
    parameters with standard and expanded uncertainties, their correlation, the calibrated
    range and conditions, the uncertainty budget, the candidate laws, the reactions-only
    comparison, the repeatability, the runs, fig. 9 and the provenance. When
    ``OUT/calibration.json`` is already written, its SHA-256 ties the certificate to it.

    Parameters
    ----------
    rig : Rig
        The campaign's rig (its name titles the page).
    model : SpatialModel
        The spatial model the campaign's forces were reconstructed with.
    result : CampaignResult
        The campaign's calibration.
    out_dir : str or pathlib.Path
        The output folder: ``figures/calibration.png`` and ``report.html``.
    provenance : dict, optional
        :func:`forcecal.provenance.provenance` of the inputs (default: of
        :func:`campaign_inputs`, with this process's command line); the campaign's files it
        does not list are added.

    Returns
    -------
    pathlib.Path
        The path of ``report.html``.
    """
    from .._atomic import write_text_atomic
    from ..provenance import file_digest
    from ..provenance import provenance as make
    from .certificate import calibration_certificate
    from .html import data_uri

    out = Path(out_dir)
    fig = fig_calibration(CalibrationPoints.from_campaign(result), result.calibration)
    png = save_png(fig, out / "figures" / "calibration.png")
    inputs = campaign_inputs(rig, model, result)
    prov = make(inputs) if provenance is None else _with_inputs(provenance, inputs)
    written = out / "calibration.json"
    page = calibration_certificate(
        rig, result, prov, model=model, figure=data_uri(png.read_bytes()),
        calibration_file=((written.name, file_digest(written)) if written.is_file() else None))
    return write_text_atomic(out / "report.html", page)
