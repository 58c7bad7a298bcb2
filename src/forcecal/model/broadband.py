"""A scan under a broadband drive (a sweep, a chirp, random): the shapes over a band (METHOD.md
section 7, "any drive").

Under one load pattern (forces that keep their ratio) the deflection at any frequency is one
operating shape, and over a band these shapes span a few real shapes: the rigid motions, the
flexible modes in the band and the quasi-static part of the modes above it. Finding the span
needs no modal parameters. :func:`build_broadband_model`:

1. per point, the frequency response of the displacement to the reference and the standard
   uncertainty of its Re and of its Im (:mod:`forcecal.model.frf`);
2. over the lines of the band, each in units of its own noise, a singular value
   decomposition: the span keeps the shapes that stand clear of noise alone;
3. the span's shapes fitted over the points with the structure's basis (one order for all),
   their mass couplings (eq. 6), and every line's operating shape in their coordinates;
4. the operating shape's ratios a_k / a_1 over frequency (:mod:`.ratios`): smoothed or a modal
   model's (:mod:`.modal`), as the lines' residuals favour.

The operating shapes over the band are then a family, phi(x, nu) = sum_k phi_k(x) a_k(nu): a
steady run takes each harmonic's own (:func:`steady_model`), any other drive corrects the
first shape's inertia frequency by frequency (:meth:`BroadbandModel.inertia_correction`).
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .._atomic import write_text_atomic
from ..errors import InputError
from ..records import Scan, ScanFRF, ScanSpectra
from ..rig import Rig
from ..schema.broadband_file import BROADBAND_KEYS, check_broadband_document
from .basis import ShapeFit, column_fits, shape_similarity
from .coverage import check_scan_coverage, check_scan_on_rig
from .frf import scan_response
from .inertia import mass_coupling
from .ratio_errors import shared_ratio_errors
from .ratios import RatioChoice, drive_line_ratios
from .screening import MAX_SET_ASIDE, record_weights
from .spatial import (
    MIN_SNR,
    SpatialModel,
    check_rig_keys,
    read_model_document,
    rig_keys,
    set_aside_notes,
    shape_from_json,
    shape_to_json,
)

__all__ = [
    "STEADY_HARMONICS",
    "BroadbandModel",
    "build_broadband_model",
    "load_any_model",
    "steady_model",
]

MIN_COHERENCE = 0.5
"""Lines whose median coherence over the points is below this carry too little of the drive
to shape the span."""
MAX_CHI2 = 2.0
"""A span that leaves the lines' reduced chi-square above this is noted."""
MAX_SHAPES = 6
"""Most shapes a span keeps."""
SV_MARGIN = 1.5
"""A shape joins the span when its singular value stands this many times above the largest
of a noise-only matrix of the same size."""
STEADY_HARMONICS = 6
"""Harmonics a steady run is reconstructed with from a broadband model."""


@dataclass(frozen=True)
class BroadbandModel:
    """The span of a broadband scan's operating shapes and its mass couplings.

    Attributes
    ----------
    band : (low, high) [Hz]
        Where the shapes were measured.
    shapes : tuple of ShapeFit
        The span's real shapes phi_k(x) [m per unit coordinate], strongest first.
    couplings : (n_gauges, n_shapes) array [kg]
        m_{r,k} = integral(rho psi_r phi_k) + lumped masses.
    frequencies : (n_lines,) array [Hz]
        The lines the span was found from.
    coordinates : (n_shapes, n_lines) complex array
        Each line's operating shape in the span's coordinates (per unit reference).
    singular_values : (n_sv,) array [1]
        Of the lines scaled to unit RMS, strongest first.
    chi2 : (n_sv,) array [1]
        The lines' median reduced chi-square left by a span of 1, 2, ... shapes.
    line_snr : (n_lines,) array [1]
        Every line's signal-to-noise ratio over the points (RMS response over the median
        noise of Re and Im, as a steady scan's :meth:`forcecal.model.scan.HarmonicShapes.snr`).
    gauge_names : tuple of str
    n_points : int
        Scan records used.
    source : str
    notes : tuple of str
    rig : dict
        The keys of the rig the model was built for (:func:`forcecal.model.spatial.rig_keys`).
    ratios : (n_shapes, n_lines) complex array or None
        The operating shape's smoothed ratios a_k / a_1 at every line (the first row 1); None
        (a model written before they were kept) takes each line's own ratio.
    ratio_std : (n_shapes, n_lines) array or None
        Their standard uncertainty, of Re and of Im each (:func:`.ratios.smooth_ratios`).
    ratio_choice : RatioChoice
        Whether the ratios are the splines' or the modal model's, and why.
    reference : (float, float) or None [A]
        The scan's reference (coil current) mean and standard deviation about it (medians
        over its time records): the bias the shapes were measured under; None from spectra or
        FRFs, which hold no DC.
    file : str
        The MODEL.json the model was read from (:func:`load_any_model`); empty for a model
        built here. Refusals name the model by it (:attr:`origin`).
    ratio_directions : tuple of (n_dirs, n_lines) arrays, or None
        Per shape, the part of its ratio's error that neighbouring lines share (the lines'
        noise through the splines, or the modal model's parameters' through its ratios,
        :func:`error_directions`; of Re and of Im each, the first shape's empty):
        ``ratio_std`` holds it and each line's own part. None: every line's error its own (a
        model written before they were kept).
    """

    band: tuple[float, float]
    shapes: tuple[ShapeFit, ...]
    couplings: np.ndarray
    frequencies: np.ndarray
    coordinates: np.ndarray
    singular_values: np.ndarray
    chi2: np.ndarray
    line_snr: np.ndarray
    gauge_names: tuple[str, ...]
    n_points: int = 0
    source: str = "<scan>"
    notes: tuple[str, ...] = ()
    rig: dict[str, float | str] = field(default_factory=dict)
    ratios: np.ndarray | None = None
    ratio_std: np.ndarray | None = None
    file: str = ""
    ratio_choice: RatioChoice = field(default_factory=RatioChoice)
    reference: tuple[float, float] | None = None
    ratio_directions: tuple[np.ndarray, ...] | None = None

    @property
    def origin(self) -> str:
        """What a refusal names the model by: the MODEL.json it was read from, else its scan."""
        return self.file or self.source

    @property
    def drive_rms(self) -> float | None:
        """[A] the RMS of the scan's coil current (its bias and its spread); None when not kept
        (spectra, FRFs)."""
        return None if self.reference is None else float(np.hypot(*self.reference))

    def __repr__(self) -> str:
        """One line: the scan, the band, the shapes, the points and lines, the notes."""
        return (f"BroadbandModel(scan '{self.source}', band {self.band[0]:g}-{self.band[1]:g} "
                f"Hz, {self.n_shapes} shape(s) (order {self.shapes[0].order}), {self.n_points} "
                f"points, {self.frequencies.size} lines, {len(self.notes)} note(s))")

    @property
    def n_shapes(self) -> int:
        """Shapes in the span."""
        return len(self.shapes)

    def values(self, points: np.ndarray) -> np.ndarray:
        """(n_points, n_shapes) [m]: the span's shapes at points (structure coordinates)."""
        return np.column_stack([s.evaluate(points) for s in self.shapes])

    def stds(self, points: np.ndarray) -> np.ndarray:
        """(n_points, n_shapes) [m]: the fitted shapes' standard uncertainties at points."""
        return np.column_stack([s.std(points) for s in self.shapes])

    def mixing(self, frequencies: np.ndarray) -> np.ndarray:
        """(n_shapes, n_freq) complex [1]: the operating shape at each frequency in the span's
        coordinates, relative to the first shape's: 1, a_2 / a_1, ...

        The smoothed ratios (:attr:`ratios`) are interpolated linearly between the scan's
        lines and held beyond the first and the last. Near a mode the coordinates themselves
        swing through the resonance, but their ratios stay smooth (quadratic in the frequency:
        the resonant shape's denominator cancels).
        """
        f = np.atleast_1d(np.asarray(frequencies, float))
        if self.ratios is not None:
            lines, ratio = self.frequencies, self.ratios
        else:
            live = self.line_snr >= 1.0
            if np.count_nonzero(live) < 2:
                live = np.ones_like(live)
            lines = self.frequencies[live]
            first = self.coordinates[0, live]
            tiny = np.finfo(float).tiny
            ratio = self.coordinates[:, live] / np.where(np.abs(first) > tiny, first, tiny)
        out = np.empty((self.n_shapes, len(f)), complex)
        for k in range(self.n_shapes):
            out[k] = (np.interp(f, lines, ratio[k].real)
                      + 1j * np.interp(f, lines, ratio[k].imag))
        return out

    def mixing_std(self, frequencies: np.ndarray) -> np.ndarray:
        """(n_shapes, n_freq) [1]: the standard uncertainty of Re and of Im of each ratio of
        :meth:`mixing` (interpolated as the ratios are; zero when the model has none)."""
        f = np.atleast_1d(np.asarray(frequencies, float))
        if self.ratio_std is None:
            return np.zeros((self.n_shapes, len(f)))
        return np.array([np.interp(f, self.frequencies, s) for s in self.ratio_std])

    def mixing_directions(self, frequencies: np.ndarray) -> list[tuple[int, np.ndarray]]:
        """Each shape's ratio error directions at ``frequencies`` (n_freq,) [Hz], interpolated
        as the ratios are: (k, (n_dirs, n_freq) array [1]) for every shape that has some."""
        if self.ratio_directions is None:
            return []
        f = np.atleast_1d(np.asarray(frequencies, float))
        return [(k, np.array([np.interp(f, self.frequencies, d) for d in dirs]))
                for k, dirs in enumerate(self.ratio_directions) if len(dirs)]

    def inertia_correction(self, frequencies: np.ndarray, probe_shapes: np.ndarray,
                           weights: np.ndarray) -> np.ndarray:
        """(n_gauges, n_freq) complex [1]: what the inertia J_r = m_{r,1} q''_1 of the first
        shape alone must be multiplied by at each frequency, q_1 taken from the probes by
        weighted least squares on the first shape.

        At frequency nu the deflection is phi(x) c, phi = sum_k phi_k a_k(nu) the operating
        shape (:meth:`mixing`); q_1 = beta c with beta = (g_1^T W G a) / (g_1^T W g_1)
        (G[j, k] = phi_k(l_j), g_1 its first column), so J_r = -w^2 (m_r . a) c =
        (m_r . a) / (beta m_{r,1}) * m_{r,1} q''_1.

        Parameters
        ----------
        frequencies : (n_freq,) array [Hz]
        probe_shapes : (n_probes, n_shapes) array [m]
            The span's shapes at the probes (G).
        weights : (n_probes,) array
            The probes' weights (inverse noise variances).
        """
        mix = self.mixing(frequencies)
        g1 = probe_shapes[:, 0]
        beta = (g1 * weights) @ (probe_shapes @ mix) / ((g1 * weights) @ g1)
        return (self.couplings @ mix) / (beta * self.couplings[:, :1])

    def harmonic(self, rig: Rig, f0: float) -> SpatialModel:
        """The harmonic model of a steady run at ``f0`` [Hz] (:func:`steady_model`, with
        :data:`STEADY_HARMONICS` harmonics)."""
        return steady_model(self, rig, f0, STEADY_HARMONICS)

    def to_json(self) -> dict[str, Any]:
        """A JSON-able description (``kind`` = "broadband")."""
        return {"kind": "broadband", "band": list(self.band),
                "shapes": [shape_to_json(s) for s in self.shapes],
                "couplings": self.couplings.tolist(),
                "frequencies": self.frequencies.tolist(),
                "coordinates": {"re": self.coordinates.real.tolist(),
                                "im": self.coordinates.imag.tolist()},
                "singular_values": self.singular_values.tolist(), "chi2": self.chi2.tolist(),
                "line_snr": self.line_snr.tolist(),
                "gauge_names": list(self.gauge_names), "n_points": self.n_points,
                "source": self.source, "notes": list(self.notes), "rig": self.rig,
                **({} if self.ratios is None else {"ratios": {
                    "re": self.ratios.real.tolist(), "im": self.ratios.imag.tolist()}}),
                **({} if self.ratio_std is None else {"ratio_std": self.ratio_std.tolist()}),
                "ratio_model": self.ratio_choice.to_json(),
                **({} if self.reference is None else {"reference_dc_a": self.reference[0],
                                                      "reference_ac_a": self.reference[1]}),
                **({} if self.ratio_directions is None else {"ratio_directions": [
                    d.tolist() for d in self.ratio_directions]})}

    @classmethod
    def from_json(cls, doc: dict[str, Any], source: str = "<model>") -> BroadbandModel:
        """The model :meth:`to_json` wrote.

        Raises
        ------
        InputError
            ``model 'SOURCE': key 'KEY' WHAT``: a key unknown (with the nearest valid one),
            missing, written twice, of the wrong type or beyond its bound, or lists whose sizes
            disagree (:func:`forcecal.schema.broadband_file.check_broadband_document`).
        """
        check_broadband_document(doc, source)
        ratios = _complex(doc["ratios"]) if "ratios" in doc else None
        ratio_std = np.asarray(doc["ratio_std"], float) if "ratio_std" in doc else None
        choice = (RatioChoice.from_json(doc["ratio_model"]) if "ratio_model" in doc
                  else RatioChoice())
        return cls(band=(float(doc["band"][0]), float(doc["band"][1])),
                   shapes=tuple(_real_shape(shape_from_json(s)) for s in doc["shapes"]),
                   couplings=np.asarray(doc["couplings"], float),
                   frequencies=np.asarray(doc["frequencies"], float),
                   coordinates=_complex(doc["coordinates"]),
                   singular_values=np.asarray(doc["singular_values"], float),
                   chi2=np.asarray(doc["chi2"], float),
                   line_snr=np.asarray(doc["line_snr"], float),
                   gauge_names=tuple(doc["gauge_names"]), n_points=int(doc["n_points"]),
                   source=str(doc["source"]), notes=tuple(doc["notes"]),
                   rig=dict(doc["rig"]), ratios=ratios, ratio_std=ratio_std,
                   ratio_choice=choice, ratio_directions=None if "ratio_directions" not in doc
                   else tuple(np.asarray(d, float).reshape(-1, len(doc["frequencies"]))
                              for d in doc["ratio_directions"]),
                   reference=(
                       None if doc.get("reference_dc_a") is None
                       else (float(doc["reference_dc_a"]), float(doc.get("reference_ac_a", 0)))))

    def save(self, path: str | Path) -> Path:
        """Write the model as JSON (atomically)."""
        return write_text_atomic(path, json.dumps(self.to_json(), indent=1))


def _complex(doc: dict[str, Any]) -> np.ndarray:
    return np.asarray(doc["re"], float) + 1j * np.asarray(doc["im"], float)


def _real_shape(s: object) -> ShapeFit:
    """A span shape read back: real coefficients (the schema admits scalar fields only)."""
    assert isinstance(s, ShapeFit), "a broadband model's shapes are scalar fields"
    return dataclasses.replace(s, coefficients=np.real(s.coefficients))


def build_broadband_model(rig: Rig, scan: Scan | ScanSpectra | ScanFRF,
                          criterion: str = "gcv") -> BroadbandModel:
    """The span of the operating shapes of a scan under a broadband drive.

    Parameters
    ----------
    rig : Rig
        With ``acquisition.band``; a beam or a plate.
    scan : Scan, ScanSpectra or ScanFRF
        Time records, or their spectra as SLDV software exports them (every line of the
        record's transform over the band: the drive periodic in the record, the lines between
        its own giving the noise, :func:`forcecal.model.frf.scan_response`), or its FRFs and their
        coherence (the rig giving ``acquisition.scan_averages``).
    criterion : str
        "gcv" or "bic", how the shapes' order is chosen.

    Returns
    -------
    BroadbandModel

    Raises
    ------
    InputError
        No band in the rig, a body, spectra of a drive not periodic in their record, FRFs
        without the rig's number of averages, more than ``MAX_SET_ASIDE`` of the points dead
        (no response on any line; fewer are set aside, noted), or a drive that leaves no line
        coherent.
    """
    band = _broadband_band(rig, scan)
    check_scan_on_rig(rig, scan)
    covered = check_scan_coverage(rig, scan)
    st = rig.structure
    resp, dead = scan_response(scan, band, rig.scan_averages).without_dead()
    good = _drive_lines(scan, band, resp.coherence, len(dead))
    tiny = np.finfo(float).tiny
    h, std = resp.values[:, good], np.maximum(resp.std[:, good], tiny)
    a, s_noise, u, sv, chi2 = _line_span(h, std)
    d, note = _span_size(sv, chi2, a.shape)
    notes = [*covered, *([f"scan '{scan.source}': {note}"] if note else [])]
    notes += set_aside_notes(scan, dead)
    points = st.coordinates(resp.points, source=f"scan '{scan.source}'")
    weights = record_weights(np.median(s_noise, axis=1))
    shapes = _span_shapes(rig, points, u, sv, d, weights, criterion)
    couplings = np.column_stack([np.real(mass_coupling(rig, s.evaluate)) for s in shapes])
    basis = np.column_stack([s.evaluate(points) for s in shapes])
    coords, cov = _line_coordinates(basis, weights, resp.values, resp.std, good, h, std,
                                    len(points), len(resp.frequencies))
    ratios, ratio_std, choice, directions = drive_line_ratios(resp.frequencies, coords, cov,
                                                                good)
    line_snr = (np.sqrt(np.mean(np.abs(resp.values) ** 2, axis=0))
                / (np.sqrt(2) * np.maximum(np.median(resp.std, axis=0), tiny)))
    return BroadbandModel(band=band, shapes=shapes, couplings=couplings,
                          frequencies=resp.frequencies, coordinates=coords,
                          singular_values=sv[:min(len(sv), 12)], chi2=chi2, line_snr=line_snr,
                          gauge_names=tuple(rig.gauge_names), n_points=len(points),
                          source=scan.source, notes=tuple(notes), rig=rig_keys(rig),
                          ratios=ratios, ratio_std=ratio_std, ratio_choice=choice,
                          reference=_reference_level(scan), ratio_directions=directions)


def _reference_level(scan: Scan | ScanSpectra | ScanFRF) -> tuple[float, float] | None:
    """The scan's reference mean and standard deviation [A], medians over its time records
    (None for spectra or FRFs)."""
    if not isinstance(scan, Scan):
        return None
    ref = scan.reference
    return float(np.median(ref.mean(axis=1))), float(np.median(ref.std(axis=1)))


def _broadband_band(rig: Rig, scan: Scan | ScanSpectra | ScanFRF) -> tuple[float, float]:
    """The rig's band, once the rig and the scan can give a broadband model: InputError for
    a rig without a band, a body, or FRFs without the rig's number of averages."""
    if rig.band is None:
        raise InputError(f"rig '{rig.source}': a broadband scan needs 'acquisition.band'")
    if rig.structure.directed:
        raise InputError(f"rig '{rig.source}': broadband shapes are built for beams and plates "
                         "(a body's vector shapes are not supported over a band)")
    if isinstance(scan, ScanFRF) and rig.scan_averages is None:
        raise InputError(f"rig '{rig.source}': the scan '{scan.source}' holds FRFs, whose noise "
                         "follows from their coherence and the number of averages behind them; "
                         "a Universal File does not record that number: give it as "
                         "'acquisition.scan_averages'")
    return rig.band


def _drive_lines(scan: Scan | ScanSpectra | ScanFRF, band: tuple[float, float],
                 coherence: np.ndarray, n_dead: int) -> np.ndarray:
    """(n_lines,) bool: the lines that carry the drive (median coherence over the points at
    least ``MIN_COHERENCE``). InputError when more than ``MAX_SET_ASIDE`` of the points are
    dead, or fewer than three lines carry the drive."""
    if n_dead > MAX_SET_ASIDE * len(scan.points):
        raise InputError(f"scan '{scan.source}': {n_dead} of its {len(scan.points)} points "
                         "hold no response on any line of the band (dead channels?)")
    good = np.median(coherence, axis=0) >= MIN_COHERENCE
    if np.count_nonzero(good) < 3:
        raise InputError(f"scan '{scan.source}': {np.count_nonzero(good)} line(s) of the band "
                         f"{band[0]:g}-{band[1]:g} Hz carry the drive (median "
                         f"coherence >= {MIN_COHERENCE}); is the drive broadband?")
    return good


def _line_span(h: np.ndarray, std: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Step 2: the lines ``h`` (n_points, n_good) in units of their noise, Re and Im side by
    side (``a``), their noise in those units, the SVD's left vectors and singular values, and
    the reduced chi-square of the spans of 1 .. ``MAX_SHAPES`` + 1 shapes."""
    # every line in units of its own noise: the SVD is then the rank-d least-squares fit
    line_noise = np.median(std, axis=0)
    a = np.hstack([(h / line_noise).real, (h / line_noise).imag])
    s_noise = np.hstack([std / line_noise, std / line_noise])
    u, sv, _ = np.linalg.svd(a, full_matrices=False)
    n_try = min(len(sv), MAX_SHAPES + 1)
    chi2 = np.array([_chi2(a, s_noise, u[:, :d]) for d in range(1, n_try + 1)])
    return a, s_noise, u, sv, chi2


def _span_shapes(rig: Rig, points: np.ndarray, u: np.ndarray, sv: np.ndarray, d: int,
                 weights: np.ndarray, criterion: str) -> tuple[ShapeFit, ...]:
    """Step 3: the span's ``d`` shapes fitted over the points with the structure's basis, all of
    one order."""
    st = rig.structure
    # the span scaled by its singular values: every column carries the data's own noise; one
    # order serves them all, the highest the smooth ones make plausible (an Akaike weight not
    # negligible), not the one of least score: the inertia integrates the shapes over the
    # points, so a bias below the points' noise adds up where the noise averages out (on the
    # test beam's chirp scan at twice its noise, the order of least score, 7 in most draws,
    # erred up to 1.7 times the stated uncertainty there, 1.28 in RMS; the highest plausible,
    # 10-13, 0.80-1.29, 0.98 in RMS)
    smooth = _smooth_patterns(st, points, u[:, :d] * sv[:d], weights, criterion)
    lead = st.fit_shape(points, u[:, smooth] * sv[smooth], criterion, weights, "polynomial")
    fit = st.fit_shape(points, u[:, :d] * sv[:d], criterion, weights, "polynomial",
                       min_order=lead.basis.order if isinstance(lead, ShapeFit) else 1)
    assert isinstance(fit, ShapeFit), "a beam's or a plate's shape"
    # each pattern known to its own residual: the rough ones' misfit, pooled, gave the smooth
    # ones' covariance up to 50 times their own (the lab rig's sweep scan)
    return tuple(dataclasses.replace(s, coefficients=s.coefficients / sv[k],
                                     residual_std=s.residual_std / sv[k],
                                     coefficient_covariance=s.coefficient_covariance / sv[k] ** 2)
                 for k, s in enumerate(column_fits(fit, points, u[:, :d] * sv[:d], weights)))


def _line_coordinates(basis: np.ndarray, weights: np.ndarray, values: np.ndarray,
                      values_std: np.ndarray, good: np.ndarray, h: np.ndarray, std: np.ndarray,
                      n_points: int, n_lines: int) -> tuple[np.ndarray, np.ndarray]:
    """Step 3: every line's operating shape in the span's coordinates (n_shapes, n_lines) and
    their covariance (n_lines, n_shapes, n_shapes), of Re and of Im each, from the points' noise
    and the good lines' misfit to the span."""
    # every line's coordinates by weighted least squares, and their covariance (of Re and of
    # Im each) from the points' noise: A diag(std^2) A^T
    solve = np.linalg.solve(basis.T @ (basis * weights[:, None]), (basis * weights[:, None]).T)
    coords = solve @ values
    cov = np.einsum("kp,pl,jp->lkj", solve, values_std**2, solve)
    # a line the span leaves more than its noise (a shape the span lacks near a mode, where
    # the line is strongest) holds its coordinates less well than its noise says: their
    # covariance takes the line's reduced chi-square off the span (its Birge ratio) above 1
    resid = h - basis @ coords[:, good]
    dof = 2 * max(n_points - basis.shape[1], 1)
    birge = np.ones(n_lines)
    birge[good] = np.maximum(np.sum(np.abs(resid) ** 2 / std**2, axis=0) / dof, 1.0)
    return coords, cov * birge[:, None, None]


ROUGH_RISK = 1e-3
"""A pattern of the span is smooth when a smooth field explains more of it than a pattern
without one would leave at this risk (F-test)."""


def _smooth_patterns(structure: Any, points: np.ndarray, patterns: np.ndarray,
                     weights: np.ndarray, criterion: str) -> list[int]:
    """The columns of ``patterns`` (the span's, over the points, in units of the lines'
    noise) that are smooth fields; the first always.

    Each is fitted alone with the structure's basis (its order by ``criterion``) and counts
    as smooth when the energy the fit explains per function exceeds the F quantile at
    :data:`ROUGH_RISK` of the residual's per degree of freedom.

    Patterns of junk can stand above the singular values' edge, which assumes the lines'
    noise is what their standard uncertainty says at every point: on the ``sweep`` preset's
    chirp scan four of six patterns live on the lines at the mode, where the noise exceeds
    its statement (F 0.0005-0.04, against 1.3e7 and 1.5e3 for the two smooth ones), and on
    the ``lab`` rig's on the mains hum's lines (50 and 150 Hz). In the span they soak that
    junk up, away from the smooth shapes' coordinates (without them the ``lab`` sweep's
    windows erred up to 29 %); but they must not choose the shapes' order: no order fits them,
    so they drag the order down, which left the strong shape's own bias in the inertia.
    """
    from scipy import stats  # on use: a steady stream starts without it

    n = len(points)
    keep = [0]
    for k in range(1, patterns.shape[1]):
        y = patterns[:, k]
        fit = structure.fit_shape(points, y, criterion, weights, "polynomial")
        p = fit.basis.functions_up_to(fit.order)
        rss = float(np.sum(weights * (y - np.real(fit.evaluate(points))) ** 2))
        explained = float(np.sum(weights * y**2)) - rss
        if p < n and explained / p > stats.f.isf(ROUGH_RISK, p, n - p) * rss / (n - p):
            keep.append(k)
    return keep


def _span_size(sv: np.ndarray, chi2: np.ndarray, shape: tuple[int, int]) -> tuple[int, str]:
    """The span's size: shapes whose singular value stands ``SV_MARGIN`` times above the
    largest a matrix of pure noise of this size would give (sqrt(rows) + sqrt(columns), in
    units of the noise), at most :data:`MAX_SHAPES`; and a note when that leaves the lines'
    reduced chi-square above :data:`MAX_CHI2`."""
    edge = np.sqrt(shape[0]) + np.sqrt(shape[1])
    d = int(np.clip(np.count_nonzero(sv > SV_MARGIN * edge), 1, MAX_SHAPES))
    note = ""
    if chi2[d - 1] > MAX_CHI2:
        note = (f"{d} shape(s) leave the lines' reduced chi-square at {chi2[d - 1]:.3g} > "
                f"{MAX_CHI2:g}: the lines' noise is under-stated, or the deflection is not "
                "one load pattern's")
    return d, note


def _chi2(a: np.ndarray, noise: np.ndarray, basis: np.ndarray) -> float:
    """The lines' reduced chi-square (summed over lines and points) after projecting them onto
    ``basis``'s span (the rank-d fit's degrees of freedom taken off)."""
    resid = a - basis @ (basis.T @ a)
    d = basis.shape[1]
    dof = max(a.size - d * (a.shape[0] + a.shape[1] - d), 1)
    return float(np.sum((resid / np.maximum(noise, np.finfo(float).tiny)) ** 2) / dof)


def steady_model(model: BroadbandModel, rig: Rig, f0: float, n_harmonics: int) -> SpatialModel:
    """The harmonic path's model of a steady run at ``f0`` from a broadband model: every
    harmonic in the band gets the operating shape of its own frequency
    (:meth:`BroadbandModel.mixing`), as a steady scan at ``f0`` would have measured it, and
    the DC deflection the operating shape of the band's lowest line (its quasi-static shape,
    which a steady scan lacks). Its scan signal-to-noise ratio is that of the scan's lines at
    n f0; one below :data:`forcecal.model.spatial.MIN_SNR` is noted, not dropped (the shapes rest on
    the span of all lines, and near a resonance the inertia matters most).

    Parameters
    ----------
    model : BroadbandModel
    rig : Rig
        The rig the model was built for.
    f0 : float [Hz]
        The run's fundamental.
    n_harmonics : int
        Harmonics 1..H considered; those above the band are left out, with a reason.

    Returns
    -------
    SpatialModel
    """
    check_rig_keys(model.rig, model.origin, rig)
    n = np.arange(1, n_harmonics + 1)
    snr = np.interp(n * f0, model.frequencies, model.line_snr)
    inside = n * f0 <= model.band[1]
    if not inside[0]:
        raise InputError(f"a drive at {f0:.4g} Hz lies above the band {model.band[0]:g}-"
                         f"{model.band[1]:g} Hz of the broadband model '{model.origin}'")
    dropped = {int(k): f"{k * f0:.4g} Hz above the scan's band ({model.band[1]:g} Hz)"
               for k in n[~inside]}
    notes = model.notes + tuple(
        f"harmonic {k} ({k * f0:.4g} Hz): the scan's lines there have signal-to-noise "
        f"{r:.1f} < {MIN_SNR:g}; its shape is interpolated in the span of all lines"
        for k, r in zip(n[inside], snr[inside], strict=True) if r < MIN_SNR)
    kept = n[inside]
    lowest = model.frequencies[:1]          # the quasi-static shape, with its ratios' error
    at = np.concatenate([kept * f0, lowest])
    mix = model.mixing(at)                                       # (n_shapes, n_kept + 1)
    first = model.shapes[0]
    coefs = np.column_stack([s.coefficients for s in model.shapes]).astype(complex)
    real = coefs.real
    shared, own_var = shared_ratio_errors(model, real, at)
    # each shape's coefficient covariance: the first span shape's fit, and the ratios' own
    # uncertainty along the span's other shapes (delta phi = sum_k phi_k delta r_k); the part
    # the lines share through the splines is one error of every run (``shared_errors``)
    shapes = tuple(dataclasses.replace(
        first, coefficients=coefs @ mix[:, j],
        coefficient_covariance=first.coefficient_covariance
        + (real * own_var[:, j]) @ real.T) for j in range(len(kept)))
    couplings = (model.couplings.astype(complex) @ mix).T       # (n_kept, n_gauges)
    # the shapes share one basis, orthonormal over the scan points: their MAC is that of
    # their coefficients
    mac = np.array([[shape_similarity(p.coefficients, q.coefficients) for q in shapes]
                    for p in shapes])
    static = dataclasses.replace(
        first, coefficients=coefs @ mix[:, -1],
        coefficient_covariance=first.coefficient_covariance + (real * own_var[:, -1]) @ real.T)
    return SpatialModel(
        f0=f0, harmonics=kept, shapes=shapes, couplings=couplings, similarity=mac,
        snr=snr, gauge_names=model.gauge_names, dropped=dict(sorted(dropped.items())),
        n_points=model.n_points, source=model.source, notes=notes, rig=model.rig,
        static_shape=static, file=model.file, shared_errors=shared)


def load_any_model(path: str | Path) -> SpatialModel | BroadbandModel:
    """A MODEL.json written by ``scan``: a harmonic (steady) model or a broadband one, read
    once (:func:`forcecal.model.spatial.read_model_document`).

    A document with a ``kind`` is read as a broadband model (a harmonic model has none; any
    other kind is refused naming the key), and so is one without ``kind`` or ``format`` that
    holds a key only a broadband model has (its ``kind`` misspelt or moved: refused naming
    that key).

    Raises
    ------
    InputError
        As :func:`forcecal.model.spatial.load_model`, or a broadband document that does not
        read (:func:`forcecal.schema.broadband_file.check_broadband_document`).
    """
    doc = read_model_document(path)
    model = MODEL_KINDS[_model_kind(doc)].from_json(doc, source=str(path))
    return dataclasses.replace(model, file=str(path))


def _model_kind(doc: Any) -> str:
    """The kind of model a MODEL.json document is (see :func:`load_any_model`)."""
    if not isinstance(doc, dict):
        return "harmonic"
    if "kind" in doc:  # only a broadband model has one
        return "broadband"
    return "broadband" if "format" not in doc and BROADBAND_KEYS & doc.keys() else "harmonic"


MODEL_KINDS: dict[str, type[SpatialModel] | type[BroadbandModel]] = {
    "harmonic": SpatialModel, "broadband": BroadbandModel}
"""A MODEL.json's kind (:func:`_model_kind`) -> the class that reads it."""
