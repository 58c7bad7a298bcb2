"""A scan under a broadband drive (a sweep, a chirp, random): the shapes over a band.

Under one load pattern (forces that keep their ratio: one magnet, or a U-core whose two poles
share one flux) the deflection at any frequency is one operating shape, and over a band these
shapes span a few real shapes: the rigid motions, the flexible modes in the band and the
quasi-static part of the modes above it (METHOD.md section 7, "any drive"). Finding the span
needs no modal parameters: the magnet's negative stiffness shifts the poles of responses
referred to the coil current, never the shapes they mix.

1. Per point, the frequency response of the displacement to the reference,
   H1 = S_xr / S_rr (Welch averages, Hann window, half overlap), and its coherence; the
   standard uncertainty of its Re and of its Im, |H| sqrt((1 - coh) / (2 n_avg coh))
   (Bendat and Piersol, random errors of frequency-response estimates).
2. Over the lines of the band: every line scaled to unit RMS over the points (each frequency
   counts alike), Re and Im side by side, a singular value decomposition. The span keeps the
   fewest shapes that leave the lines' residual within their noise, never more than the
   sensors (eq. 16: Nq <= NS).
3. The span's shapes fitted over the points with the structure's basis (one order for all) and
   their mass couplings by quadrature (eq. 6).

A steady run then uses the span as every harmonic's members (:func:`steady_model`, the
harmonic path of :mod:`forcecal.forces` unchanged); any other drive is solved sample by sample
(:mod:`forcecal.transient`).
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import scipy.signal

from ._atomic import write_text_atomic
from .basis import ShapeFit
from .errors import InputError
from .inertia import mass_coupling
from .records import Scan, ScanSpectra
from .rig import Rig
from .screening import record_weights
from .spatial import (
    MIN_SNR,
    SpatialModel,
    check_rig_keys,
    read_model_document,
    rig_keys,
    shape_from_json,
    shape_to_json,
)

__all__ = ["STEADY_HARMONICS", "BroadbandModel", "ScanResponse", "build_broadband_model",
           "load_any_model", "scan_response", "steady_model"]

MIN_COHERENCE = 0.5
"""Lines whose median coherence over the points is below this carry too little of the drive
to shape the span."""
MAX_CHI2 = 2.0
"""The span is large enough when the lines' median reduced chi-square is below this."""
STEADY_HARMONICS = 6
"""Harmonics a steady run is reconstructed with from a broadband model."""
SEGMENTS = 8
"""Welch segments aimed at per record (half overlap): the frequency resolution is about
``SEGMENTS / (2 T)`` for records of T seconds."""


@dataclass(frozen=True)
class ScanResponse:
    """Every scan point's frequency response to the drive over the band.

    Attributes
    ----------
    points : (n_points, n_dim) array [m]
        The scan points, as :class:`forcecal.records.Scan` holds them.
    frequencies : (n_lines,) array [Hz]
        The lines in the band.
    values : (n_points, n_lines) complex array [m per unit of the reference]
        H1 of the displacement.
    std : (n_points, n_lines) array
        Standard uncertainty of Re and of Im of ``values``.
    coherence : (n_points, n_lines) array [1]
        Ordinary coherence of response and reference.
    source : str
        The scan's file, for messages.
    """

    points: np.ndarray
    frequencies: np.ndarray
    values: np.ndarray
    std: np.ndarray
    coherence: np.ndarray
    source: str = "<scan>"


def scan_response(scan: Scan, band: tuple[float, float]) -> ScanResponse:
    """Each record's frequency response (H1) over ``band``.

    Parameters
    ----------
    scan : Scan
        Time records under a broadband drive, the coil current as reference.
    band : (low, high) [Hz]
        The band the drive covered.

    Returns
    -------
    ScanResponse

    Raises
    ------
    InputError
        Records too short to resolve the band, or a band without a line.
    """
    n = scan.response.shape[1]
    nperseg = int(2 * n // (SEGMENTS + 1))
    if nperseg < 16 or scan.fs / nperseg > (band[1] - band[0]) / 4:
        raise InputError(f"scan '{scan.source}': records of {n} samples resolve "
                         f"{scan.fs / max(nperseg, 1):.3g} Hz, too coarse for the band "
                         f"{band[0]:g}-{band[1]:g} Hz")
    if band[1] >= scan.fs / 2:
        raise InputError(f"scan '{scan.source}': the band's top {band[1]:g} Hz is not below "
                         f"the Nyquist frequency {scan.fs / 2:g} Hz")
    kw = {"fs": scan.fs, "nperseg": nperseg, "window": "hann", "detrend": "constant"}
    f, s_rr = scipy.signal.welch(scan.reference, axis=-1, **kw)
    _, s_xx = scipy.signal.welch(scan.response, axis=-1, **kw)
    _, s_rx = scipy.signal.csd(scan.reference, scan.response, axis=-1, **kw)
    lines = (f >= max(band[0], f[1])) & (f <= band[1])
    if not np.any(lines):
        raise InputError(f"scan '{scan.source}': no spectral line in the band "
                         f"{band[0]:g}-{band[1]:g} Hz")
    f, s_rr, s_xx, s_rx = f[lines], s_rr[:, lines], s_xx[:, lines], s_rx[:, lines]
    tiny = np.finfo(float).tiny
    h = s_rx / np.maximum(s_rr, tiny)
    coh = np.clip(np.abs(s_rx) ** 2 / np.maximum(s_rr * s_xx, tiny), 1e-12, 1.0)
    if scan.quantity == "velocity":
        h = h / (2j * np.pi * f)
    n_avg = max((n - nperseg) // (nperseg // 2) + 1, 1)
    std = np.abs(h) * np.sqrt((1.0 - coh) / (2.0 * n_avg * coh))
    return ScanResponse(points=scan.points, frequencies=f, values=h, std=std, coherence=coh,
                        source=scan.source)


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
        noise of Re and Im, as a steady scan's :meth:`forcecal.scan.HarmonicShapes.snr`).
    gauge_names : tuple of str
    n_points : int
        Scan records used.
    source : str
    notes : tuple of str
    rig : dict
        The keys of the rig the model was built for (:func:`forcecal.spatial.rig_keys`).
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
                "source": self.source, "notes": list(self.notes), "rig": self.rig}

    @classmethod
    def from_json(cls, doc: dict[str, Any], source: str = "<model>") -> BroadbandModel:
        """The model :meth:`to_json` wrote.

        Raises
        ------
        InputError
            A key missing or malformed.
        """
        try:
            if doc.get("kind") != "broadband":
                raise ValueError("kind is not 'broadband'")
            shapes = tuple(_real_shape(shape_from_json(s)) for s in doc["shapes"])
            coords = np.asarray(doc["coordinates"]["re"], float) + 1j * np.asarray(
                doc["coordinates"]["im"], float)
            model = cls(band=(float(doc["band"][0]), float(doc["band"][1])), shapes=shapes,
                        couplings=np.asarray(doc["couplings"], float),
                        frequencies=np.asarray(doc["frequencies"], float), coordinates=coords,
                        singular_values=np.asarray(doc["singular_values"], float),
                        chi2=np.asarray(doc["chi2"], float),
                        line_snr=np.asarray(doc["line_snr"], float),
                        gauge_names=tuple(doc["gauge_names"]), n_points=int(doc["n_points"]),
                        source=str(doc["source"]), notes=tuple(doc["notes"]),
                        rig=dict(doc["rig"]))
        except (KeyError, TypeError, ValueError, IndexError, AttributeError) as exc:
            raise InputError(f"model '{source}': not a broadband model ({exc!r})") from None
        _check_sizes(model, source)
        return model

    def save(self, path: str | Path) -> Path:
        """Write the model as JSON (atomically)."""
        return write_text_atomic(path, json.dumps(self.to_json(), indent=1))


def _check_sizes(m: BroadbandModel, source: str) -> None:
    """Refuse a broadband model whose arrays disagree or hold non-finite numbers."""
    n_k, n_lines = len(m.shapes), len(m.frequencies)
    wrong = ("no shape" if not n_k else
             "its band is not a band" if not 0 <= m.band[0] < m.band[1] else
             "its couplings are not (gauges, shapes)"
             if m.couplings.shape != (len(m.gauge_names), n_k) else
             "its coordinates are not (shapes, lines)"
             if m.coordinates.shape != (n_k, n_lines) or m.line_snr.shape != (n_lines,) else
             "it holds non-finite numbers" if not all(
                 np.all(np.isfinite(a)) for a in (m.couplings, m.frequencies, m.coordinates,
                                                  m.line_snr, *(f.coefficients for f in m.shapes)))
             else "")
    if wrong:
        raise InputError(f"model '{source}': not a broadband model ({wrong})")


def _real_shape(s: object) -> ShapeFit:
    """A span shape read back: real coefficients."""
    if not isinstance(s, ShapeFit):
        raise TypeError("a broadband model's shapes are scalar fields")
    return dataclasses.replace(s, coefficients=np.real(s.coefficients))


def build_broadband_model(rig: Rig, scan: Scan | ScanSpectra,
                          criterion: str = "gcv") -> BroadbandModel:
    """The span of the operating shapes of a scan under a broadband drive.

    Parameters
    ----------
    rig : Rig
        With ``acquisition.band``; a beam or a plate.
    scan : Scan
        Time records (a spectrum export holds one line per harmonic, not a band).
    criterion : str
        "gcv" or "bic", how the shapes' order is chosen.

    Returns
    -------
    BroadbandModel

    Raises
    ------
    InputError
        No band in the rig, a spectrum scan, a body, or a drive that leaves no line coherent.
    """
    if rig.band is None:
        raise InputError(f"rig '{rig.source}': a broadband scan needs 'acquisition.band'")
    if not isinstance(scan, Scan):
        raise InputError(f"scan '{scan.source}': a broadband model is built from time records "
                         "(a spectrum export holds the lines of one fundamental)")
    st = rig.structure
    if st.directed:
        raise InputError(f"rig '{rig.source}': broadband shapes are built for beams and plates "
                         "(a body's vector shapes are not supported over a band)")
    resp = scan_response(scan, rig.band)
    good = np.median(resp.coherence, axis=0) >= MIN_COHERENCE
    if np.count_nonzero(good) < 3:
        raise InputError(f"scan '{scan.source}': {np.count_nonzero(good)} line(s) of the band "
                         f"{rig.band[0]:g}-{rig.band[1]:g} Hz carry the drive (median "
                         f"coherence >= {MIN_COHERENCE}); is the drive broadband?")
    h, std = resp.values[:, good], resp.std[:, good]
    scale = np.sqrt(np.mean(np.abs(h) ** 2, axis=0))
    a = np.hstack([(h / scale).real, (h / scale).imag])
    s_noise = np.hstack([std / scale, std / scale])
    u, sv, _ = np.linalg.svd(a, full_matrices=False)
    chi2 = np.array([_chi2(a, s_noise, u[:, :d]) for d in range(1, min(len(sv), 6) + 1)])
    max_shapes = len(rig.sensors)
    within = np.flatnonzero(chi2[:max_shapes] <= MAX_CHI2)
    d = int(within[0]) + 1 if len(within) else max_shapes
    notes = []
    if not len(within):
        notes.append(f"scan '{scan.source}': {max_shapes} shapes (one per sensor) leave the "
                     f"lines' reduced chi-square at {chi2[max_shapes - 1]:.3g} > {MAX_CHI2:g}: "
                     "the deflection needs more shapes than the sensors can resolve")
    points = st.coordinates(scan.points, source=f"scan '{scan.source}'")
    weights = record_weights(np.median(s_noise, axis=1))
    fit = st.fit_shape(points, u[:, :d], criterion, weights, "polynomial")
    assert isinstance(fit, ShapeFit), "a beam's or a plate's shape"
    shapes = tuple(ShapeFit(basis=fit.basis, coefficients=fit.coefficients[:, k],
                            order=fit.order, orders=fit.orders, score=fit.score,
                            criterion=fit.criterion, residual_std=fit.residual_std,
                            coefficient_covariance=fit.coefficient_covariance)
                   for k in range(d))
    couplings = np.column_stack([np.real(mass_coupling(rig, s.evaluate)) for s in shapes])
    basis = np.column_stack([s.evaluate(points) for s in shapes])
    coords = np.linalg.lstsq(basis, resp.values, rcond=None)[0]
    line_snr = (np.sqrt(np.mean(np.abs(resp.values) ** 2, axis=0))
                / (np.sqrt(2) * np.maximum(np.median(resp.std, axis=0), np.finfo(float).tiny)))
    return BroadbandModel(band=rig.band, shapes=shapes, couplings=couplings,
                          frequencies=resp.frequencies, coordinates=coords,
                          singular_values=sv[:min(len(sv), 12)], chi2=chi2, line_snr=line_snr,
                          gauge_names=tuple(rig.gauge_names), n_points=len(points),
                          source=scan.source, notes=tuple(notes), rig=rig_keys(rig))


def _chi2(a: np.ndarray, noise: np.ndarray, basis: np.ndarray) -> float:
    """The lines' median reduced chi-square after projecting them onto ``basis``'s span."""
    resid = a - basis @ (basis.T @ a)
    dof = max(a.shape[0] - basis.shape[1], 1)
    per_line = np.sum((resid / np.maximum(noise, np.finfo(float).tiny)) ** 2, axis=0) / dof
    return float(np.median(per_line))


def steady_model(model: BroadbandModel, rig: Rig, f0: float, n_harmonics: int) -> SpatialModel:
    """The harmonic path's model of a steady run at ``f0`` from a broadband model: every
    harmonic in the band holds the span as its members (:mod:`forcecal.span`). Its scan
    signal-to-noise ratio is that of the scan's lines at n f0; one below
    :data:`forcecal.spatial.MIN_SNR` is noted, not dropped (the span's shapes do not rest on
    that line, and near a resonance, where coherence drops, the inertia matters most).

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
    check_rig_keys(model.rig, model.source, rig)
    n = np.arange(1, n_harmonics + 1)
    snr = np.interp(n * f0, model.frequencies, model.line_snr)
    inside = n * f0 <= model.band[1]
    if not inside[0]:
        raise InputError(f"a drive at {f0:.4g} Hz lies above the band {model.band[0]:g}-"
                         f"{model.band[1]:g} Hz of the broadband model '{model.source}'")
    dropped = {int(k): f"{k * f0:.4g} Hz above the scan's band ({model.band[1]:g} Hz)"
               for k in n[~inside]}
    notes = model.notes + tuple(
        f"harmonic {k} ({k * f0:.4g} Hz): the scan's lines there have signal-to-noise "
        f"{r:.1f} < {MIN_SNR:g} (coherence lost, as near a resonance the lines under-resolve); "
        "its shapes are the span's" for k, r in zip(n[inside], snr[inside], strict=True)
        if r < MIN_SNR)
    kept = n[inside]
    # the harmonic path's shapes are complex phasor shapes
    shapes = tuple(dataclasses.replace(f, coefficients=f.coefficients.astype(complex))
                   for f in model.shapes)
    first, rest = shapes[0], shapes[1:]
    coupling = model.couplings.astype(complex)
    return SpatialModel(
        f0=f0, harmonics=kept, shapes=(first,) * len(kept),
        couplings=np.tile(coupling[:, 0], (len(kept), 1)),
        similarity=np.ones((len(kept), len(kept))),
        snr=snr, gauge_names=model.gauge_names, dropped=dict(sorted(dropped.items())),
        n_points=model.n_points, source=model.source, notes=notes, rig=model.rig,
        span=(tuple(rest),) * len(kept) if rest else (),
        span_couplings=(coupling[:, 1:],) * len(kept) if rest else (),
        scans=(model.source,) * model.n_shapes if rest else (),
        member_scans=(tuple(range(model.n_shapes)),) * len(kept) if rest else ())


def load_any_model(path: str | Path) -> SpatialModel | BroadbandModel:
    """A MODEL.json written by ``scan``: a harmonic (steady) model or a broadband one, read
    once (:func:`forcecal.spatial.read_model_document`).

    Raises
    ------
    InputError
        As :func:`forcecal.spatial.load_model`, or a broadband document that does not read.
    """
    doc = read_model_document(path)
    if isinstance(doc, dict) and doc.get("kind") == "broadband":
        return BroadbandModel.from_json(doc, source=str(path))
    return SpatialModel.from_json(doc, source=str(path))
