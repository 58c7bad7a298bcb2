"""The spatial response model: smooth harmonic shapes and their mass couplings.

Built off line from a scan (METHOD.md section 3, steps 2 and 3): each harmonic the scan supports
gets its own shape phi_n(x), fitted over the scan points with an orthonormal polynomial basis
whose order is chosen by GCV (or BIC); the mass coupling m_{r,n} of every relaxed gauge with
phi_n follows by quadrature. The shapes are not forced to vanish at the gauges: the gauges'
small compliance is real rigid motion and belongs in the inertia.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from .._atomic import write_text_atomic
from ..errors import DataError, InputError
from ..records import Scan, ScanFRF, ScanSpectra
from ..rig import Rig, rig_to_dict
from ..schema.json_files import MAX_DOCUMENT_BYTES, object_pairs, reject_constant
from ..schema.model_file import check_model_document
from .basis import PolynomialBasis, ShapeFit, shape_similarity
from .coverage import check_scan_coverage, check_scan_on_rig
from .inertia import mass_coupling
from .scan import HarmonicShapes, harmonic_shapes, steady_scan, unusable_spectra
from .screening import Screening, record_weights, screen_records, unusable_records
from .vector_basis import AXES, VectorShapeFit

__all__ = [
    "SpatialModel",
    "build_spatial_model",
    "check_model_rig",
    "check_rig_keys",
    "load_model",
    "merge_models",
]


# --- from spatial ---
Fit = ShapeFit | VectorShapeFit


MIN_SNR = 3.0
"""A harmonic is kept when its fitted shape rises this many times above its own noise
(:func:`shape_snr`); a harmonic whose RMS amplitude per record reaches it serves the screening
of the records."""
ONE_SHAPE_MAC = 0.999
"""Harmonics whose shapes all agree to this MAC are served by one shape (the paper's eq. 19)."""


@dataclass(frozen=True)
class SpatialModel:
    """Harmonic shapes phi_n and mass couplings m_{r,n}.

    Attributes
    ----------
    f0 : [Hz] the scan's refined fundamental
    harmonics : (n_harm,) int, the harmonics with a shape
    shapes : one ShapeFit per harmonic; phi_n(x) = shapes[k].evaluate(x) [m] (on a body a
        VectorShapeFit, evaluated at locations)
    couplings : (n_harm, n_gauges) complex [kg m]: m_{r,n} = integral(rho psi_r phi_n) + lumped
    similarity : (n_harm, n_harm) MAC of the fitted shapes over the scan points [1]
    snr : (n_harm_scanned,) the scan's signal-to-noise ratio of every harmonic 1..H
    dropped : {harmonic: reason} harmonics left out
    set_aside : {record index: reason} scan records left out of the shapes
        (:mod:`forcecal.model.screening`)
    rig : the keys of the rig the model was built for (:func:`rig_keys`); a model is refused
        for a rig whose geometry, masses or sensor layout differ (:func:`check_model_rig`)
    span : per harmonic, the shapes that other scans of the rig (under other loads) add
        beyond ``shapes[k]``; empty for a model built from one scan (:mod:`forcecal.model.spatial`)
    span_couplings : per harmonic, (n_gauges, n_extra) complex [kg m] their mass couplings
    scans : the scans the model was built from (``source`` is the first)
    member_scans : per harmonic, the scan (index into ``scans``) of each member of its span,
        ``shapes[k]``'s first
    static_shape : the quasi-static shape, when the scan measured one (a broadband scan's
        operating shape at the lowest line of its band, :func:`forcecal.model.broadband.
        steady_model`); None: the fundamental's shape stands in for it
        (:func:`forcecal.actuator.gaps.quasi_static_shape`). Not written to the model file: a model
        that has one is built from a broadband model, which is.
    file : the MODEL.json the model was read from (:func:`load_model`); empty for a model
        built here. Refusals name the model by it (:attr:`origin`).
    drive : (H+1,) complex [A], the scan's coil current, harmonics 0..H, aligned and scaled as
        the shapes are (:attr:`forcecal.model.scan.HarmonicShapes.drive`): the drive under
        which a coordinate of 1 is the scan's motion; None for a model of several scans or of
        spectra (:mod:`forcecal.forces.scan_check`)
    shared_errors : errors of the shapes that every run of the model shares, whatever its
        frequency: (name, (n_harm, n_coef) complex change of each shape's coefficients, (n_coef,)
        complex change of the quasi-static shape's), each one standard deviation (a broadband
        model's smoothed ratios, :meth:`forcecal.model.broadband.BroadbandModel.mixing_directions`);
        the shapes' own covariances hold the rest. Not written to the model file.
    """

    f0: float
    harmonics: np.ndarray
    shapes: tuple[ShapeFit | VectorShapeFit, ...]
    couplings: np.ndarray
    similarity: np.ndarray
    snr: np.ndarray
    gauge_names: tuple[str, ...]
    dropped: dict[int, str] = field(default_factory=dict)
    n_points: int = 0
    source: str = "<scan>"
    notes: tuple[str, ...] = ()
    rig: dict[str, float | str] = field(default_factory=dict)
    set_aside: dict[int, str] = field(default_factory=dict)
    span: tuple[tuple[Fit, ...], ...] = ()
    span_couplings: tuple[np.ndarray, ...] = ()
    scans: tuple[str, ...] = ()
    member_scans: tuple[tuple[int, ...], ...] = ()
    static_shape: ShapeFit | VectorShapeFit | None = None
    file: str = ""
    drive: np.ndarray | None = None
    shared_errors: tuple[tuple[str, np.ndarray, np.ndarray], ...] = ()

    @property
    def origin(self) -> str:
        """What a refusal names the model by: the MODEL.json it was read from, else its scan."""
        return self.file or self.source

    @property
    def drive_rms(self) -> float | None:
        """[A] the RMS of the scan's coil current, from its harmonics; None when not kept."""
        if self.drive is None:
            return None
        return float(np.sqrt(abs(self.drive[0]) ** 2 + np.sum(np.abs(self.drive[1:]) ** 2) / 2))

    @property
    def one_shape(self) -> bool:
        """Whether one shape serves every harmonic (all pairwise MAC >= ONE_SHAPE_MAC)."""
        return bool(np.all(self.similarity >= ONE_SHAPE_MAC))

    def index(self, n: int) -> int:
        """Position of harmonic n in :attr:`harmonics`."""
        hits = np.flatnonzero(self.harmonics == n)
        if not len(hits):
            raise KeyError(n)
        return int(hits[0])

    def shape_values(self, n: int, points: np.ndarray) -> np.ndarray:
        """phi_n at points, complex (n_points,) [m]."""
        return self.shapes[self.index(n)].evaluate(points)

    def members(self, k: int) -> tuple[Fit, ...]:
        """Harmonic k's span of shapes: ``shapes[k]``, then those other scans add.

        Parameters
        ----------
        k : int
            Position of the harmonic in :attr:`harmonics`.

        Returns
        -------
        tuple of ShapeFit or VectorShapeFit
        """
        return (self.shapes[k], *(self.span[k] if self.span else ()))

    def shape_covariance(self, k: int, member: int = 0) -> np.ndarray:
        """The whole covariance of Re and of Im of harmonic k's member shape's coefficients:
        its own and, for ``shapes[k]``, the errors every run of the model shares
        (:attr:`shared_errors`, which a single run's estimate counts as its own)."""
        cov = np.asarray(self.members(k)[member].coefficient_covariance, dtype=float)
        if member or not self.shared_errors:
            return cov
        # each shared error moves Re or Im of the coefficients; Re and Im alike in all
        parts = [(c[k].real, c[k].imag) for _, c, _ in self.shared_errors]
        shared = 0.5 * sum(np.outer(re, re) + np.outer(im, im) for re, im in parts)
        out: np.ndarray = cov + shared
        return out

    def member_couplings(self, k: int) -> np.ndarray:
        """(n_gauges, n_members) complex [kg m]: the mass couplings of harmonic k's span."""
        extra = self.span_couplings[k] if self.span else np.zeros((len(self.gauge_names), 0))
        return np.column_stack([self.couplings[k], extra])

    def member_values(self, k: int, points: np.ndarray) -> np.ndarray:
        """(n_points, n_members) complex [m]: harmonic k's span of shapes at points."""
        return np.column_stack([f.evaluate(points) for f in self.members(k)])

    def member_std(self, k: int, points: np.ndarray) -> np.ndarray:
        """(n_points, n_members) [m]: the fitted shapes' standard uncertainties at points."""
        return np.column_stack([f.std(points) for f in self.members(k)])

    def member_names(self, k: int) -> tuple[str, ...]:
        """The scan each member of harmonic k's span comes from."""
        if not self.member_scans:
            return (self.source,)
        return tuple(self.scans[i] for i in self.member_scans[k])

    def _summary(self) -> list[tuple[str, str]]:
        """(what, value) rows shown by the reprs."""
        return [("scan", self.source), ("f0", f"{self.f0:.6g} Hz"),
                ("harmonics (order)", ", ".join(f"{int(n)} ({s.order})" for n, s in
                                                zip(self.harmonics, self.shapes, strict=True))),
                ("dropped", ", ".join(str(n) for n in self.dropped) or "none"),
                ("points", str(self.n_points)),
                ("records set aside", str(len(self.set_aside)))] + (
            [("scans", ", ".join(self.scans)),
             ("shapes per harmonic", ", ".join(f"{int(n)}: {len(self.members(k))}"
                                               for k, n in enumerate(self.harmonics)))]
            if len(self.scans) > 1 else [])

    def __repr__(self) -> str:
        """One line: f0, the harmonics with their shapes' orders, the records set aside."""
        return "SpatialModel(" + ", ".join(f"{k} {v}" for k, v in self._summary()) + ")"

    def _repr_html_(self) -> str:
        """A small table for notebooks."""
        from html import escape

        rows = "".join(f"<tr><th>{escape(k)}</th><td>{escape(v)}</td></tr>"
                       for k, v in self._summary())
        return f"<p><b>SpatialModel</b></p><table>{rows}</table>"

    # ----------------------------------------------------------------- JSON

    def harmonic(self, rig: Rig, f0: float | None) -> SpatialModel:
        """The harmonic model of a steady run at ``f0`` [Hz]: this one."""
        return self

    def to_json(self) -> dict:
        shape = shape_to_json
        return {
            "format": "forcecal spatial model 1",
            "source": self.source,
            "f0_hz": self.f0,
            "n_points": self.n_points,
            "gauges": list(self.gauge_names),
            "harmonics": [int(n) for n in self.harmonics],
            "snr": self.snr.tolist(),
            "dropped": {str(k): v for k, v in self.dropped.items()},
            "one_shape_serves_all": self.one_shape,
            "similarity_mac": self.similarity.tolist(),
            "couplings_re": self.couplings.real.tolist(),
            "couplings_im": self.couplings.imag.tolist(),
            "shapes": [shape(s) for s in self.shapes],
            "notes": list(self.notes),
            "set_aside": [{"record": k + 1, "reason": why} for k, why in self.set_aside.items()],
            "rig": {"sha256": _digest(self.rig), "keys": self.rig},
            **({} if self.drive is None else {"drive_re": self.drive.real.tolist(),
                                              "drive_im": self.drive.imag.tolist()}),
            **({} if not self.span else {
                "scans": list(self.scans),
                "span": [{"harmonic": int(n), "scans": list(self.member_scans[k]),
                          "shapes": [shape(s) for s in self.span[k]],
                          "couplings_re": self.span_couplings[k].real.tolist(),
                          "couplings_im": self.span_couplings[k].imag.tolist()}
                         for k, n in enumerate(self.harmonics)]}),
        }

    @classmethod
    def from_json(cls, doc: dict, source: str = "<model>") -> SpatialModel:
        check_model_document(doc, source)  # the schema: format, types, sizes, finite numbers

        any_shape = shape_from_json
        try:
            shapes = [any_shape(s) for s in doc["shapes"]]
            span = doc.get("span", [])
            n_g = len(doc["gauges"])
            return cls(
                f0=float(doc["f0_hz"]),
                harmonics=np.asarray(doc["harmonics"], dtype=int),
                shapes=tuple(shapes),
                couplings=np.asarray(doc["couplings_re"]) + 1j * np.asarray(doc["couplings_im"]),
                similarity=np.asarray(doc["similarity_mac"], dtype=float),
                snr=np.asarray(doc["snr"], dtype=float),
                gauge_names=tuple(doc["gauges"]),
                dropped={int(k): v for k, v in doc.get("dropped", {}).items()},
                n_points=int(doc.get("n_points", 0)),
                source=doc.get("source", source),
                notes=tuple(doc.get("notes", ())),
                rig=dict(doc.get("rig", {}).get("keys", {})),
                set_aside={int(r["record"]) - 1: str(r["reason"])
                           for r in doc.get("set_aside", [])},
                span=tuple(tuple(any_shape(s) for s in m["shapes"]) for m in span),
                span_couplings=tuple(
                    (np.asarray(m["couplings_re"]) + 1j * np.asarray(m["couplings_im"]))
                    .reshape(n_g, len(m["shapes"])) for m in span),
                scans=tuple(doc.get("scans", ())),
                member_scans=tuple(tuple(int(i) for i in m["scans"]) for m in span),
                drive=_drive(doc),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"model '{source}': not a forcecal spatial model ({exc})") from None

    def save(self, path: str | Path) -> Path:
        return write_text_atomic(path, json.dumps(self.to_json(), indent=1))


def _drive(doc: dict) -> np.ndarray | None:
    """The model file's scan drive, when it holds one (both parts, of one length)."""
    re, im = doc.get("drive_re"), doc.get("drive_im")
    if re is None or im is None or len(re) != len(im):
        return None
    return np.asarray(re, dtype=float) + 1j * np.asarray(im, dtype=float)


def shape_to_json(s: Fit) -> dict:
    """A fitted shape (a ShapeFit, or a body's VectorShapeFit) as JSON."""
    if isinstance(s, VectorShapeFit):
        return {"components": [{"axis": AXES[a], **shape_to_json(c)}
                               for a, c in zip(s.axes, s.components, strict=True)]}
    return {
        "order": s.order,
        **({} if s.basis.order == s.order else {"basis_order": s.basis.order}),
        "criterion": s.criterion,
        "domain": s.basis.domain.tolist(),
        "family": s.basis.family,
        "basis": s.basis.coefficients.tolist(),
        **({} if s.basis.columns is None else {"columns": s.basis.columns.tolist()}),
        "coefficients_re": s.coefficients.real.tolist(),
        "coefficients_im": s.coefficients.imag.tolist(),
        "residual_std": s.residual_std,
        "coefficient_covariance": s.coefficient_covariance.tolist(),
        "orders": np.asarray(s.orders).tolist(),
        "score": np.asarray(s.score).tolist(),
    }


def shape_from_json(s: dict) -> Fit:
    """The shape :func:`shape_to_json` wrote."""
    if "components" in s:
        return VectorShapeFit(tuple(AXES.index(c["axis"]) for c in s["components"]),
                              tuple(_shape_fit(c) for c in s["components"]))
    return _shape_fit(s)


def _shape_fit(s: dict) -> ShapeFit:
    basis = PolynomialBasis(int(s.get("basis_order", s["order"])),
                            np.asarray(s["domain"], dtype=float),
                            np.asarray(s["basis"], dtype=float), s.get("family", "legendre"),
                            np.asarray(s["columns"], dtype=int) if "columns" in s else None)
    coef = np.asarray(s["coefficients_re"]) + 1j * np.asarray(s["coefficients_im"])
    return ShapeFit(
        basis=basis, coefficients=coef, order=int(s["order"]), orders=np.asarray(s["orders"]),
        score=np.asarray(s["score"]), criterion=s["criterion"],
        residual_std=float(s["residual_std"]),
        coefficient_covariance=np.asarray(s["coefficient_covariance"]))


def load_model(path: str | Path) -> SpatialModel:
    """Read a spatial model written by :meth:`SpatialModel.save`.

    Parameters
    ----------
    path : str or Path
        The MODEL.json file.

    Returns
    -------
    SpatialModel
    """
    model = SpatialModel.from_json(read_model_document(path), source=str(path))
    return replace(model, file=str(path))


def read_model_document(path: str | Path) -> Any:
    """The JSON of a MODEL.json file (strict: no NaN or Infinity), any kind of model.

    Raises
    ------
    InputError
        A missing or oversized file, or one that is not valid JSON.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"model '{path}': file not found")
    if path.stat().st_size > MAX_DOCUMENT_BYTES:
        raise InputError(f"model '{path}': {path.stat().st_size} bytes; a model file is at most "
                         f"{MAX_DOCUMENT_BYTES} bytes")
    try:
        doc = json.loads(path.read_text(encoding="utf-8"), parse_constant=reject_constant,
                         object_pairs_hook=object_pairs)
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"model '{path}': not JSON ({exc})") from None
    except RecursionError:
        raise InputError(f"model '{path}': not a forcecal spatial model (JSON nested too "
                         "deeply)") from None
    except ValueError as exc:  # NaN/Infinity constants, an integer beyond the digit limit
        raise InputError(f"model '{path}': not valid JSON ({exc})") from None
    return doc


def build_spatial_model(rig: Rig, scan: Scan | ScanSpectra | ScanFRF
                        | Sequence[Scan | ScanSpectra],
                        n_harmonics: int = 6,
                        criterion: str = "gcv", shapes: HarmonicShapes | None = None,
                        basis: str = "polynomial") -> SpatialModel:
    """Fit a shape per supported harmonic and its mass couplings; from several scans of the
    rig under different loads, a span of shapes per harmonic (:mod:`forcecal.model.spatial`).

    Parameters
    ----------
    rig : Rig
        The rig (structure extent, mass distribution, gauges).
    scan : Scan, ScanSpectra or a sequence of them
        The SLDV scan (time records or spectra), or several scans of the rig under different
        loads (each harmonic then holds the shapes of every scan that adds to its span); points
        on the structure.
    n_harmonics : int
        H: harmonics 1..H are considered; those below ``MIN_SNR`` are dropped.
    criterion : str
        "gcv" or "bic", how each shape's order is chosen.
    shapes : HarmonicShapes, optional
        The measured harmonic shapes, when already computed from ``scan`` (one scan only).
    basis : str
        "polynomial" (orthonormal Legendre polynomials, the black box the paper prefers) or
        "modes" (rigid motions plus the bending modes of the structure pinned at its gauges,
        the physical alternative; beams and plates); either is orthonormalized on the scan
        points.

    Returns
    -------
    SpatialModel
    """
    if not isinstance(scan, Scan | ScanSpectra | ScanFRF):
        scans = list(scan)
        if not scans or not all(isinstance(s, Scan | ScanSpectra) for s in scans):
            raise InputError("build_spatial_model: 'scan' must be a Scan or a non-empty list of "
                             "Scans (from forcecal.read_scan)")
        if len(scans) > 1:
            return merge_models(rig, [build_spatial_model(rig, s, n_harmonics, criterion,
                                                          basis=basis) for s in scans])
        scan = scans[0]
    scan = steady_scan(scan)
    check_scan_on_rig(rig, scan)
    hs = shapes if shapes is not None else harmonic_shapes(scan, rig.drive_frequency,
                                                           n_harmonics)
    covered = check_scan_coverage(rig, scan)  # once the drive is confirmed; before any fit
    st = rig.structure
    if basis not in ("polynomial", "modes"):
        raise InputError(f"basis '{basis}' is unknown (choose 'polynomial' or 'modes')")
    if basis not in st.bases:
        raise InputError(f"rig '{rig.source}': the {basis} basis does not serve a "
                         f"{st.kind}; its shapes use the "
                         + " or ".join(f"{b} basis (--basis {b})" for b in st.bases))
    points = st.coordinates(hs.points, source=f"scan '{scan.source}'")
    fits, screening, snr, dropped = _screened_fits(rig, scan, hs, points, criterion, basis)
    keep = screening.keep
    kept = [int(n) for n in hs.harmonics if int(n) not in dropped]
    if not kept:
        raise InputError(f"scan '{scan.source}': no harmonic rises above the noise "
                         f"(signal-to-noise {snr.max():.1f} at best)")
    chosen = [fits[n] for n in kept]
    couplings = np.stack([mass_coupling(rig, f.evaluate) for f in chosen])
    vals = [f.evaluate(points[keep]) for f in chosen]
    mac = np.array([[shape_similarity(a, b) for b in vals] for a in vals])
    notes = covered + st.model_notes(chosen) + set_aside_notes(scan, screening.reasons)
    if screening.note:
        notes += (f"scan '{scan.source}': {screening.note}",)
    return SpatialModel(f0=hs.f0, harmonics=np.array(kept), shapes=tuple(chosen),
                        couplings=couplings, similarity=mac, snr=snr,
                        gauge_names=tuple(rig.gauge_names), dropped=dropped,
                        n_points=int(np.count_nonzero(keep)), source=scan.source, notes=notes,
                        rig=rig_keys(rig), set_aside=dict(sorted(screening.reasons.items())),
                        drive=hs.drive)


def shape_snr(snr: float, n_records: int, n_functions: int) -> float:
    """How many times a fitted shape rises above its own noise [1]: sqrt(N (snr^2 - 1) / p)
    for N records of RMS signal-to-noise ``snr`` (noise alone gives 1) fitted with p functions,
    the shape's signal energy over the p coefficients' noise; 0 when ``snr`` <= 1."""
    return math.sqrt(max(snr**2 - 1.0, 0.0) * n_records / max(n_functions, 1))


def _screened_fits(rig: Rig, scan: Scan | ScanSpectra, hs: HarmonicShapes, points: np.ndarray,
                   criterion: str, basis: str
                   ) -> tuple[dict[int, Fit], Screening, np.ndarray, dict[int, str]]:
    """Every resolved harmonic's shape fitted over the records that survive the screening
    (:mod:`forcecal.model.screening`), with the records' floored weights; the screening; every
    harmonic's signal-to-noise ratio over the records kept; the harmonics dropped and why.

    The records are screened on the harmonics whose RMS amplitude per record is ``MIN_SNR``
    times the noise; a harmonic is resolved when its fitted shape is (:func:`shape_snr`):
    a weak harmonic over many records is determined as well as a strong one over few."""
    st = rig.structure
    ok = (hs.reference_ok if hs.reference_ok is not None
          else np.ones(scan.n_points, dtype=bool))
    reasons = unusable_records(scan, ok) if isinstance(scan, Scan) else unusable_spectra(scan, ok)
    usable = np.ones(scan.n_points, dtype=bool)
    usable[list(reasons)] = False
    snr = hs.snr(usable)
    resolved = [(k, int(n)) for k, n in enumerate(hs.harmonics) if snr[k] >= MIN_SNR]
    cache: dict[tuple[bytes, int], Fit] = {}
    strongest = int(np.argmax(snr))

    def fit(idx: np.ndarray, weights: np.ndarray, row: int) -> Fit:
        # the weights are record_weights(hs.std[row, idx]) on every call, so the records and
        # the harmonic identify a fit: the screening's last fits serve as the final ones.
        # A weaker harmonic is given at least the strongest one's order over the same records
        # (min_order): its shape is no simpler, only its noise hides the detail, and a
        # truncated shape biases the inertia beyond what its coefficients' covariance states
        key = (idx.tobytes(), row)
        if key not in cache:
            floor = 1
            if row != strongest:
                top = fit(idx, record_weights(hs.std[strongest, idx]), strongest)
                floor = min(c.order for c in getattr(top, "components", (top,)))
            try:
                cache[key] = st.fit_shape(points[idx], hs.values[row, idx], criterion, weights,
                                          basis, min_order=floor)
            except DataError as exc:
                raise InputError(f"scan '{scan.source}': {exc}") from None
        return cache[key]

    screening = screen_records(points, hs.values, hs.std, resolved, fit, reasons)
    idx = np.flatnonzero(screening.keep)
    snr = hs.snr(screening.keep)
    fits: dict[int, Fit] = {}
    dropped: dict[int, str] = {}
    for k, n in enumerate(hs.harmonics):
        if snr[k] <= 1.0:
            dropped[int(n)] = f"scan signal-to-noise {snr[k]:.1f}: noise alone"
            continue
        f = fit(idx, record_weights(hs.std[k, idx]), k)
        rise = shape_snr(float(snr[k]), len(idx), f.fitted_basis.n_funcs)
        if rise >= MIN_SNR:
            fits[int(n)] = f
        else:
            dropped[int(n)] = (f"scan signal-to-noise {snr[k]:.1f}: its shape over {len(idx)} "
                               f"records and {f.fitted_basis.n_funcs} functions rises {rise:.1f} "
                               f"< {MIN_SNR:g} times above its noise")
    return fits, screening, snr, dropped


def set_aside_notes(scan: Scan | ScanSpectra | ScanFRF, reasons: dict[int, str]
                    ) -> tuple[str, ...]:
    """One note per record set aside, naming it by its number and position."""
    notes = []
    for k, why in sorted(reasons.items()):
        where = ", ".join(f"{c:.4g}" for c in scan.points[k, :3])
        notes.append(f"scan '{scan.source}': record {k + 1} at ({where}) m set aside: {why}")
    return tuple(notes)


def rig_keys(rig: Rig) -> dict[str, float | str]:
    """What a spatial model depends on in its rig, as flat keys (``structure.length``,
    ``structure.masses[0].mass``, ``gauges[1].x``, ``sensors[0].direction[2]``...): the
    structure, its masses, and every gauge's, force point's and sensor's name, position and
    direction; not the channels' scales, the gaps, the actuator or the acquisition.

    Parameters
    ----------
    rig : Rig

    Returns
    -------
    dict
        Key -> number or name.
    """
    doc = rig_to_dict(rig)
    keep = {k: doc[k] for k in ("structure", "gauges", "forces", "sensors")}
    for key in ("gauges", "forces", "sensors"):
        keep[key] = [{a: v for a, v in p.items() if a not in ("scale", "gap", "core")}
                     for p in doc[key]]
    flat: dict[str, float | str] = {}
    _flatten(keep, "", flat)
    return flat


def _flatten(value: object, path: str, out: dict[str, float | str]) -> None:
    if isinstance(value, dict):
        for k, v in value.items():
            _flatten(v, f"{path}.{k}" if path else str(k), out)
    elif isinstance(value, list | tuple):
        for k, v in enumerate(value):
            _flatten(v, f"{path}[{k}]", out)
    elif isinstance(value, int | float) and not isinstance(value, bool):
        out[path] = float(value)
    else:
        out[path] = str(value)


def _digest(keys: dict[str, float | str]) -> str:
    return hashlib.sha256(json.dumps(keys, sort_keys=True).encode()).hexdigest()


def check_model_rig(model: SpatialModel, rig: Rig) -> None:
    """Refuse a model built for another rig, naming the first key that differs.

    Parameters
    ----------
    model : SpatialModel
    rig : Rig

    Raises
    ------
    InputError
        When the rig's geometry, masses or sensor layout differ from the model's rig (a model
        written before models recorded their rig is accepted).
    """
    check_rig_keys(model.rig, model.origin, rig)


def check_rig_keys(keys: dict[str, float | str], source: str, rig: Rig) -> None:
    """Refuse a model (from ``source``) built for a rig of other ``keys`` (:func:`rig_keys`);
    a model without keys is accepted.

    Raises
    ------
    InputError
        Naming the model, the first key that differs with its two values, and the others.
    """
    if not keys:
        return
    now = rig_keys(rig)
    changed = []
    for key in sorted(set(keys) | set(now)):
        was, is_ = keys.get(key), now.get(key)
        same = (isinstance(was, float) and isinstance(is_, float)
                and math.isclose(was, is_, rel_tol=1e-9, abs_tol=1e-12)) or was == is_
        if not same:
            changed.append((key, "absent" if was is None else repr(was),
                            "none" if is_ is None else repr(is_)))
    if not changed:
        return
    (first, old, new), more = changed[0], changed[1:]
    also = "; ".join(f"'{k}' {a} -> {b}" for k, a, b in more[:MORE_KEYS]) + (
        f"; {len(more) - MORE_KEYS} more" if len(more) > MORE_KEYS else "")
    raise InputError(
        f"model '{source}' was built for a rig whose key '{first}' is {old}, but rig "
        f"'{rig.source}' has {new}" + (f" (other keys changed: {also})" if more else "")
        + ": its shapes and mass couplings belong to the other rig; build the model again "
        "with 'forcecal scan'")


MORE_KEYS = 3
"""Changed rig keys a refused model's message lists beyond the first."""


# --- from span ---
SCAN_FREQUENCY_TOLERANCE = 0.01
"""Largest relative difference between the scans' fundamentals: shapes at other frequencies
belong to another dynamic response, not to the same span."""
SAME_SHAPE = 3.0
"""A scan's shape is the same as the span's when the part of it the span misses is below this
many times the shapes' own standard uncertainty (RMS over the structure)."""


def merge_models(rig: Rig, models: Sequence[SpatialModel]) -> SpatialModel:
    """One spatial model from the models of several scans of the same rig.

    Parameters
    ----------
    rig : Rig
        The rig every scan was taken on.
    models : sequence of SpatialModel
        One per scan, built by :func:`forcecal.model.spatial.build_spatial_model`; the first one's
        shapes are each harmonic's first member.

    Returns
    -------
    SpatialModel
        Harmonics resolved by any scan; each holds the shapes of the scans that resolve it and
        add to its span.

    Raises
    ------
    InputError
        Scans driven at different fundamentals.
    """
    first = models[0]
    if len(models) == 1:
        return first
    for m in models[1:]:
        if abs(m.f0 / first.f0 - 1.0) > SCAN_FREQUENCY_TOLERANCE:
            raise InputError(
                f"scan '{m.source}': driven at {m.f0:.6g} Hz but scan '{first.source}' at "
                f"{first.f0:.6g} Hz; the scans of one model must share the drive frequency "
                "(their shapes are the same dynamic response under different loads)")
    grid = rig.structure.grid()
    harmonics = sorted({int(n) for m in models for n in m.harmonics})
    shapes, couplings, span, span_couplings, member_scans = [], [], [], [], []
    notes = [n for m in models for n in m.notes]
    for n in harmonics:
        members = [(i, m.shapes[m.index(n)], m.couplings[m.index(n)])
                   for i, m in enumerate(models) if n in m.harmonics]
        kept = [members[0]]
        for i, fit, coupling in members[1:]:
            values = np.column_stack([f.evaluate(grid) for _, f, _ in kept])
            ratio = _novelty(values, [f.std(grid) for _, f, _ in kept], fit.evaluate(grid),
                             fit.std(grid))
            if ratio < SAME_SHAPE:
                notes.append(f"harmonic {n}: scan '{models[i].source}' adds nothing to the span "
                             f"(its shape differs from the others' by {ratio:.1f} times their "
                             "uncertainty): left out")
                continue
            kept.append((i, fit, coupling))
        shapes.append(kept[0][1])
        couplings.append(kept[0][2])
        span.append(tuple(f for _, f, _ in kept[1:]))
        span_couplings.append(np.array([c for _, _, c in kept[1:]]).T.reshape(
            len(rig.gauges), len(kept) - 1))
        member_scans.append(tuple(i for i, _, _ in kept))
        if len(kept) > 1:
            pair = shape_similarity(kept[0][1].evaluate(grid), kept[1][1].evaluate(grid))
            notes.append(f"harmonic {n}: {len(kept)} shapes (scans "
                         + ", ".join(f"'{models[i].source}'" for i, _, _ in kept)
                         + f"; MAC of the first two {pair:.4f})")
    vals = [f.evaluate(grid) for f in shapes]
    mac = np.array([[shape_similarity(a, b) for b in vals] for a in vals])
    n_snr = max(len(m.snr) for m in models)
    snr = np.max(np.stack([np.pad(m.snr, (0, n_snr - len(m.snr))) for m in models]), axis=0)
    dropped = {n: why for m in reversed(models) for n, why in m.dropped.items()
               if n not in harmonics}
    return SpatialModel(
        f0=first.f0, harmonics=np.array(harmonics), shapes=tuple(shapes),
        couplings=np.array(couplings), similarity=mac, snr=snr,
        gauge_names=first.gauge_names, dropped=dict(sorted(dropped.items())),
        n_points=sum(m.n_points for m in models), source=first.source, notes=tuple(notes),
        rig=first.rig, set_aside=first.set_aside, span=tuple(span),
        span_couplings=tuple(span_couplings), scans=tuple(m.source for m in models),
        member_scans=tuple(member_scans))


def _novelty(values: np.ndarray, stds: list[np.ndarray], new: np.ndarray,
             new_std: np.ndarray) -> float:
    """RMS of the part of ``new`` outside the span of ``values`` (least squares over the
    points), relative to the RMS of the uncertainty of that part."""
    coef, *_ = np.linalg.lstsq(values, new, rcond=None)
    miss = new - values @ coef
    var = new_std**2 + sum(abs(c) ** 2 * s**2 for c, s in zip(coef, stds, strict=True))
    return float(np.sqrt(np.mean(np.abs(miss) ** 2) / max(np.mean(var), 1e-300)))
