"""Reports assembled from the user's data: run forces and campaign calibration.

``run_report``: spatial model, forces of every run (with the truth overlaid when a folder of
``NAME.forces.csv`` ground truth is given), figures as PNG, SVG or PDF files and one
self-contained HTML page, its figures numbered 1 to N with captions that say what each draws.
``calibration_report``: the campaign's calibration certificate (:mod:`.certificate`) with
fig. 9.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from itertools import count
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.figure import Figure

from ..errors import InputError
from ..forces.steady import ForceEstimate, reconstruct
from ..io.results import write_estimate
from ..io.run_files import read_table_csv
from ..model.scan import HarmonicShapes, harmonic_shapes
from ..model.spatial import SpatialModel, build_spatial_model, check_model_rig
from ..records import Run, Scan, ScanFRF, ScanSpectra
from ..rig import Rig
from .cells import plus_minus, prefixed_unit, quantity, relative_paths, unc, value
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
    figure_bytes,
)
from .figures.output import FORMATS, write_bytes
from .html import (
    CSS_PX_PER_INCH,
    Image,
    Preformatted,
    Section,
    Table,
    data_uri,
    estimate_table,
    write_report,
)

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


def _figure(fig: Figure, page: Path, stem: str, fmt: str, caption: str) -> Image:
    """``fig`` written as ``page/figures/STEM.FMT`` and the page's image of it: a PNG or SVG
    embedded, a PDF linked beside an embedded PNG preview; shown at its drawn size."""
    data = figure_bytes(fig, fmt)
    path = write_bytes(data, page / "figures" / f"{stem}.{fmt}")
    rel = path.relative_to(page).as_posix()
    width = fig.get_figwidth() * CSS_PX_PER_INCH
    if fmt == "pdf":
        return Image(figure_bytes(fig, "png"), caption=f"{caption} (PDF: {rel}; the image "
                     "links to it)", width=width, link=rel)
    return Image(data, caption=f"{caption} ({rel})", width=width)


def _check_format(fmt: str) -> None:
    """Refuse a figure format forcecal does not write."""
    if fmt not in FORMATS:
        raise InputError(f"figure format '{fmt}': expected one of {', '.join(FORMATS)}")


def _shapes_caption(number: int, model: SpatialModel, dim: int) -> str:
    """What the shape figure of a beam, a plate or a body draws, in words."""
    aside = "; the scan records set aside crossed" if model.set_aside else ""
    head = f"Fig. {number} (after the paper's fig. 3): "
    if dim == 2:
        return (head + "each harmonic's fitted shape over the plate, normalized to its peak "
                "(filled contours; black: node lines), with the scan points" + aside + ".")
    if dim == 3:
        return (head + "every scan record's phasor (Re and Im) against the vector model at "
                "its location, per harmonic, one colour per measuring axis" + aside + ".")
    others = any(len(model.members(k)) > 1 for k in range(len(model.harmonics)))
    return (head + "left, each harmonic's phase-aligned deflection shape over the scan, "
            "measured (markers, ±1σ bars) and fitted (lines)"
            + ("; the other scans' shapes dotted, scaled onto the first's" if others else "")
            + aside + "; right, the fitted shapes normalized to their peak and overlaid, with "
            "the measured points alike and the MAC values between the harmonics' shapes.")


def _model_section(model: SpatialModel, shapes: Image | None) -> Section:
    """The spatial model's section: fundamental, harmonic shapes table and the shape figure."""
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
    if shapes is not None:
        blocks.append(shapes)
    else:
        blocks.append("The shape figure needs the scan's records: the model's scan "
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


def _run_figures(rig: Rig, model: SpatialModel, run: Run, est: ForceEstimate,
                 truth: dict[str, np.ndarray] | None, page: Path, fmt: str,
                 numbers: Iterator[int]) -> list[Image]:
    """The figures of one run (the paper's figs. 6 to 8 and the diagnostics), numbered."""
    below = ("its error against the truth (dotted above)" if truth else
             "its residual about its Fourier series, averaged over the record's periods")
    figures = (
        ("signals", fig_signals(run, rig, est), "(after the paper's fig. 6): the coil current "
         "and each probe's displacement over the first three periods, measured (wide) with "
         "the Fourier series fitted over the whole record (dashed)."),
        ("coordinates", fig_coordinates(run, rig, est, model=model), "(after the paper's fig. "
         "7): the generalized coordinate of each harmonic as the displacement at its shape's "
         "peak and the acceleration it gives (±2σ bars), and the inertia force each harmonic "
         "contributes, summed over the gauges."),
        ("forces", fig_forces(est, truth), "(after the paper's fig. 8): the inertia term and "
         "the reaction at each gauge; each force and the total beside the reactions-only "
         "estimate (dashed)" + (" and the truth (dotted)" if truth else "") + "; under each, "
         + below + ", with the ±2σ band of the estimate."),
        ("residuals", fig_residuals(est, run, rig), ": the harmonic-fit residual of every "
         "channel over the record; the probes' reduced chi-square per harmonic with the range "
         "the probe check accepts; each force's amplitude per harmonic (±1σ bars) beside the "
         "reactions-only one."),
    )
    return [_figure(f, page, f"{run.name}.{name}", fmt,
                    f"Fig. {next(numbers)}" + ("" if text.startswith(":") else " ") + text)
            for name, f, text in figures]


def _budget_table(est: ForceEstimate) -> tuple[list[list[Any]], list[str], str]:
    """Rows (source, each force's and the total's DC and fundamental std) of the budget, in
    the unit that suits its largest entry."""
    names = [*est.force_names, "total"]
    idx = [est.combination_names.index(n) for n in names]
    header = ["source"] + [f"{n} {part}" for n in names for part in ("DC", "n = 1")]
    assert est.combination_std is not None
    factor, unit = prefixed_unit(float(np.max(est.expanded()[idx][:, :2])), "N")

    def cells(std: np.ndarray) -> list[str]:
        return [unc(factor * std[k, j]) for k in idx for j in (0, 1)]

    rows: list[list[Any]] = [[src, *cells(std)] for src, std in est.budget.items()]
    rows.append(["combined standard uncertainty", *cells(est.combination_std)])
    rows.append(["expanded (k = 2)", *cells(est.expanded())])
    if est.monte_carlo_std is not None:
        rows.append([f"Monte Carlo ({est.monte_carlo_draws} draws, noise and type B)",
                     *cells(est.monte_carlo_std)])
    caption = (f"Uncertainty budget, {unit}: each source's standard uncertainty. "
               + (est.type_b.describe() if est.type_b is not None else ""))
    return rows, header, caption


def _run_section(rig: Rig, model: SpatialModel, est: ForceEstimate, run: Run,
                 truth: dict[str, np.ndarray] | None, page: Path, fmt: str,
                 numbers: Iterator[int]) -> Section:
    """One run's section: its forces with uncertainties, errors against the truth, figures."""
    blocks: list[Any] = [
        f"Refined fundamental {plus_minus(est.f0, est.f0_std, 'Hz')}. The inertia accounts "
        f"for {_pct(est.inertia_share)} of the AC force: that is how far a reactions-only "
        f"estimate is off. Standard uncertainty of the total force waveform: "
        f"{quantity(est.waveform_std, 'N', 2)} (RMS over time).",
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
    blocks += _run_figures(rig, model, run, est, truth, page, fmt, numbers)
    return Section(f"Run {run.name}", blocks)


def _summary(estimates: Sequence[ForceEstimate]) -> Section:
    """One row per run: fundamental, inertia share, total-force uncertainty, conditioning."""
    factor, unit = prefixed_unit(max(e.waveform_std for e in estimates), "N")
    rows = [[e.run_name, value(e.f0, e.f0_std), _pct(e.inertia_share),
             unc(factor * e.waveform_std), f"{e.psi_condition:.3g}"] for e in estimates]
    return Section("Summary", [Table(rows, header=[
        "run", "f0 [Hz]", "inertia share", f"total-force std [{unit}]", "cond(Psi)"])])


def run_report(rig: Rig, scan: Scan | ScanSpectra | ScanFRF | SpatialModel, runs: Sequence[Run],
               out_dir: str | Path,
               truth_dir: str | Path | None = None, n_harmonics: int = 6,
               criterion: str = "gcv", basis: str = "polynomial",
               provenance: dict | None = None,
               progress: Callable[[str], None] | None = None,
               figure_format: str = "png") -> Path:
    """Model, forces, figures and ``OUT/report.html`` for runs.

    Parameters
    ----------
    rig : Rig
        The rig the scan and the runs were measured on.
    scan : Scan or SpatialModel
        The SLDV scan the spatial model is built from, or a model already built (from one
        scan or several: the shape figure then shows its first scan's measured shapes when
        that file is still where the model says, and is left out otherwise).
    runs : Sequence of Run
        The runs whose forces are reconstructed.
    out_dir : str or pathlib.Path
        The output folder: ``model.json``, the estimates, ``figures/*``, ``report.html``.
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
    figure_format : str
        ``"png"`` (default) or ``"svg"``, embedded in the page, or ``"pdf"``, linked from it
        beside an embedded PNG preview; the files are ``figures/*.FORMAT``.

    Returns
    -------
    pathlib.Path
        The path of ``report.html``.
    """
    _check_format(figure_format)
    out = Path(out_dir)
    say = progress or (lambda _line: None)
    say("  spatial model and its shape figure")
    if isinstance(scan, SpatialModel):
        check_model_rig(scan, rig)
        model, first = scan, _model_scan(scan, rig)
        hs = None if first is None else _scan_shapes(rig, first, len(model.snr))
    else:
        hs = _scan_shapes(rig, scan, n_harmonics)
        model = build_spatial_model(rig, scan, n_harmonics=n_harmonics, criterion=criterion,
                                    shapes=hs, basis=basis)
    model.save(out / "model.json")
    numbers = count(1)
    shapes = None if hs is None else _figure(
        _SHAPE_FIGURES[rig.structure.dim](hs, model), out, "shapes", figure_format,
        _shapes_caption(next(numbers), model, rig.structure.dim))
    sections = [_model_section(model, shapes)]
    estimates = []
    for k, run in enumerate(runs):
        say(f"  run {k + 1}/{len(runs)} {run.name}: forces and figures")
        est = reconstruct(rig, model, run)
        write_estimate(est, out)
        estimates.append(est)
        sections.append(_run_section(rig, model, est, run, _read_truth(truth_dir, run), out,
                                     figure_format, numbers))
    sections.insert(0, _summary(estimates))
    if provenance is None:
        from ..provenance import provenance as make

        provenance = make([rig.source, *(model.scans or [model.source]),
                           *(r.source for r in runs)])
    sections.append(provenance_section(provenance))
    return write_report(out / "report.html", f"forcecal: forces of {rig.name}", sections)


def provenance_section(prov: dict) -> Section:
    """The report's last section: version, date, command line, every input's SHA-256, the
    inputs' paths relative to one stated root (:func:`forcecal.report.cells.relative_paths`)."""
    root, paths = relative_paths([f["path"] for f in prov["inputs"]])
    rows = [[path, f.get("bytes", "-"), f.get("sha256", "not a file")]
            for path, f in zip(paths, prov["inputs"], strict=True)]
    return Section("Provenance", [
        f"forcecal {prov['forcecal_version']} (Python {prov['python']}), "
        f"{prov['created_utc']}; command: {prov['command']}",
        f"Input paths are relative to {root} (the folder that holds every input).",
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
                       out_dir: str | Path, provenance: dict | None = None,
                       figure_format: str = "png") -> Path:
    """The calibration certificate of a campaign as ``OUT/report.html``, fig. 9 as a file.

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
        The output folder: ``figures/calibration.FORMAT`` and ``report.html``.
    provenance : dict, optional
        :func:`forcecal.provenance.provenance` of the inputs (default: of
        :func:`campaign_inputs`, with this process's command line); the campaign's files it
        does not list are added.
    figure_format : str
        ``"png"`` (default) or ``"svg"``, embedded in the page, or ``"pdf"``, linked from it
        beside an embedded PNG preview.

    Returns
    -------
    pathlib.Path
        The path of ``report.html``.
    """
    from .._atomic import write_text_atomic
    from ..provenance import file_digest
    from ..provenance import provenance as make
    from .certificate import calibration_certificate

    _check_format(figure_format)
    out = Path(out_dir)
    fig = fig_calibration(CalibrationPoints.from_campaign(result), result.calibration)
    image = _figure(fig, out, "calibration", figure_format, "")
    inputs = campaign_inputs(rig, model, result)
    prov = make(inputs) if provenance is None else _with_inputs(provenance, inputs)
    written = out / "calibration.json"
    assert isinstance(image.figure, bytes)
    figure = {"src": data_uri(image.figure), "width": f"{image.width:.0f}",
              "link": image.link, "file": f"figures/calibration.{figure_format}"}
    if result.calibration.law_object.needs_flux:
        figure["caption"] = ("Fig. 1 (after the paper's fig. 9): each run's mean force and the "
                             "amplitude of its fundamental against the DC current, one colour "
                             "per static gap and one marker per AC amplitude; the law predicts "
                             "from flux and is drawn at each run's own measured flux.")
    page = calibration_certificate(
        rig, result, prov, model=model, figure=figure,
        calibration_file=((written.name, file_digest(written)) if written.is_file() else None))
    return write_text_atomic(out / "report.html", page)
