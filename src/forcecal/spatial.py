"""The spatial response model: smooth harmonic shapes and their mass couplings.

Built off line from a scan (METHOD.md section 3, steps 2 and 3): each harmonic the scan supports
gets its own shape phi_n(x), fitted over the scan points with an orthonormal polynomial basis
whose order is chosen by GCV (or BIC); the mass coupling m_{r,n} of every relaxed gauge with
phi_n follows by quadrature. The shapes are not forced to vanish at the gauges: the gauges'
small compliance is real rigid motion and belongs in the inertia.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .basis import PolynomialBasis, ShapeFit, fit_shape, shape_similarity
from .errors import DataError, InputError
from .inertia import mass_coupling
from .records import Scan
from .rig import Rig, inside_polygon
from .scan import HarmonicShapes, harmonic_shapes
from .vector_basis import AXES, VectorShapeFit, fit_vector_shape

__all__ = [
    "SpatialModel",
    "build_spatial_model",
    "load_model",
    "structure_coordinates",
    "structure_extent",
    "structure_grid",
]

MIN_SNR = 3.0
"""A harmonic is kept when its RMS shape amplitude exceeds this many times the noise."""
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
    """

    f0: float
    harmonics: np.ndarray
    shapes: tuple[ShapeFit, ...]
    couplings: np.ndarray
    similarity: np.ndarray
    snr: np.ndarray
    gauge_names: tuple[str, ...]
    dropped: dict[int, str] = field(default_factory=dict)
    n_points: int = 0
    source: str = "<scan>"
    notes: tuple[str, ...] = ()

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

    # ----------------------------------------------------------------- JSON

    def to_json(self) -> dict:
        def shape(s: ShapeFit | VectorShapeFit) -> dict:
            if isinstance(s, VectorShapeFit):
                return {"components": [{"axis": AXES[a], **shape(c)}
                                       for a, c in zip(s.axes, s.components, strict=True)]}
            return {
                "order": s.order,
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
        }

    @classmethod
    def from_json(cls, doc: dict, source: str = "<model>") -> SpatialModel:
        def shape(s: dict) -> ShapeFit:
            basis = PolynomialBasis(int(s["order"]), np.asarray(s["domain"], dtype=float),
                                    np.asarray(s["basis"], dtype=float),
                                    s.get("family", "legendre"),
                                    np.asarray(s["columns"], dtype=int) if "columns" in s
                                    else None)
            coef = np.asarray(s["coefficients_re"]) + 1j * np.asarray(s["coefficients_im"])
            return ShapeFit(
                basis=basis, coefficients=coef, order=int(s["order"]),
                orders=np.asarray(s["orders"]), score=np.asarray(s["score"]),
                criterion=s["criterion"], residual_std=float(s["residual_std"]),
                coefficient_covariance=np.asarray(s["coefficient_covariance"]))

        try:
            shapes = [VectorShapeFit(tuple(AXES.index(c["axis"]) for c in s["components"]),
                                     tuple(shape(c) for c in s["components"]))
                      if "components" in s else shape(s) for s in doc["shapes"]]
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
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"model '{source}': not a forcecal spatial model ({exc})") from None

    def save(self, path: str | Path) -> Path:
        from .io.atomic import write_text_atomic

        return write_text_atomic(path, json.dumps(self.to_json(), indent=1))


def load_model(path: str | Path) -> SpatialModel:
    """Read a spatial model written by :meth:`SpatialModel.save`."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"model '{path}': file not found")
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"model '{path}': not JSON ({exc})") from None
    return SpatialModel.from_json(doc, source=str(path))


def build_spatial_model(rig: Rig, scan: Scan, n_harmonics: int = 6, criterion: str = "gcv",
                        shapes: HarmonicShapes | None = None,
                        basis: str = "polynomial") -> SpatialModel:
    """Fit a shape per supported harmonic and its mass couplings.

    Parameters
    ----------
    rig : the rig (structure extent, mass distribution, gauges)
    scan : the SLDV scan; its points must lie on the structure
    n_harmonics : H, harmonics 1..H are considered; those below ``MIN_SNR`` are dropped
    criterion : "gcv" or "bic", how each shape's order is chosen
    shapes : the measured harmonic shapes, when already computed from ``scan``
    basis : "polynomial" (orthonormal Legendre polynomials, the black box the paper prefers)
        or "modes" (rigid motions plus the bending modes of the structure pinned at its gauges,
        the physical alternative); either is orthonormalized on the scan points
    """
    if rig.frequency is None:
        raise InputError(f"rig '{rig.source}': key 'acquisition.frequency' is missing "
                         "(the nominal drive frequency)")
    hs = shapes if shapes is not None else harmonic_shapes(scan, rig.frequency, n_harmonics)
    if basis not in ("polynomial", "modes"):
        raise InputError(f"basis '{basis}' is unknown (choose 'polynomial' or 'modes')")
    if basis == "modes" and rig.is_body:
        raise InputError(f"rig '{rig.source}': the mode-shape basis serves beams and plates; "
                         "a body's shapes use the polynomials (--basis polynomial)")
    _check_points_on_structure(rig, scan)
    extent = structure_extent(rig)
    points = structure_coordinates(rig, hs.points, source=scan.source)
    snr = hs.snr()
    kept, fits, dropped = [], [], {}
    for k, n in enumerate(hs.harmonics):
        if snr[k] < MIN_SNR:
            dropped[int(n)] = f"scan signal-to-noise {snr[k]:.1f} < {MIN_SNR:g}"
            continue
        weights = _inverse_variance(hs.std[k])
        if rig.is_body:
            try:
                fits.append(fit_vector_shape(points, hs.values[k], extent, criterion, weights))
            except DataError as exc:
                raise InputError(f"scan '{scan.source}': {exc}") from None
        else:
            fits.append(fit_shape(points, hs.values[k], extent, criterion=criterion,
                                  weights=weights,
                                  family="modes" if basis == "modes" else "legendre"))
        kept.append(int(n))
    if not kept:
        raise InputError(f"scan '{scan.source}': no harmonic rises above the noise "
                         f"(signal-to-noise {snr.max():.1f} at best)")
    couplings = np.stack([mass_coupling(rig, f.evaluate) for f in fits])
    vals = [f.evaluate(points) for f in fits]
    mac = np.array([[shape_similarity(a, b) for b in vals] for a in vals])
    notes = ()
    if rig.is_body:
        missing = [AXES[a] for a in range(3) if a not in fits[0].axes]
        if missing:
            notes = (f"the scan measures no motion along {', '.join(missing)}; the body's "
                     "inertia along it is taken as zero",)
    return SpatialModel(f0=hs.f0, harmonics=np.array(kept), shapes=tuple(fits),
                        couplings=couplings, similarity=mac, snr=snr,
                        gauge_names=tuple(rig.gauge_names), dropped=dropped,
                        n_points=len(points), source=scan.source, notes=notes)


def structure_extent(rig: Rig):
    """The structure's extent mapped onto the basis domain: (0, L), the outline's box, or the
    box around a body's blocks."""
    st = rig.structure
    if st.kind == "beam":
        return (0.0, st.length)
    if st.kind == "body":
        lo = np.min([blk[0] for blk in st.blocks], axis=0)
        hi = np.max([blk[1] for blk in st.blocks], axis=0)
        return tuple((float(a), float(b)) for a, b in zip(lo, hi, strict=True))
    v = np.asarray(st.outline)
    return ((v[:, 0].min(), v[:, 0].max()), (v[:, 1].min(), v[:, 1].max()))


def structure_coordinates(rig: Rig, points: np.ndarray, source: str = "<points>") -> np.ndarray:
    """Points in the structure's own coordinates: x (n,) on a beam, (x, y) (n, 2) on a plate,
    locations (n, 6) on a body."""
    pts = np.asarray(points, dtype=float)
    if pts.ndim == 1:
        pts = pts[:, None]
    if rig.is_body:
        if pts.shape[1] != 6:
            raise InputError(f"'{source}': a body's points need coordinates and a measuring "
                             f"direction (x, y, z, dx, dy, dz); found {pts.shape[1]} columns")
        return pts
    return pts[:, 0] if rig.structure.kind == "beam" else pts[:, :2]


def structure_grid(rig: Rig, n: int = 401) -> np.ndarray:
    """Points covering the structure (for peaks of shapes): a line, a grid inside the outline,
    or on a body a grid through its blocks, each point along x, y and z."""
    st = rig.structure
    if st.kind == "beam":
        return np.linspace(0.0, st.length, n)
    if st.kind == "body":
        side = max(int(round((n / 3) ** (1 / 3))), 2)
        pts = np.vstack([np.stack(np.meshgrid(*[np.linspace(lo[a], hi[a], side)
                                                 for a in range(3)], indexing="ij"),
                                  axis=-1).reshape(-1, 3) for lo, hi in st.blocks])
        return np.vstack([np.column_stack([pts, np.tile(e, (len(pts), 1))]) for e in np.eye(3)])
    (x0, x1), (y0, y1) = structure_extent(rig)
    side = int(np.sqrt(n)) + 1
    xx, yy = np.meshgrid(np.linspace(x0, x1, side), np.linspace(y0, y1, side))
    pts = np.column_stack([xx.ravel(), yy.ravel()])
    return pts[inside_polygon(np.asarray(st.outline), pts)]


def _inverse_variance(std: np.ndarray) -> np.ndarray:
    """Relative weights 1/std^2 scaled to mean 1 (equal weights for noise-free data)."""
    top = float(np.max(std))
    if top <= 0:
        return np.ones_like(std)
    w = 1.0 / np.maximum(std / top, 1e-6) ** 2
    return w / w.mean()


def _check_points_on_structure(rig: Rig, scan: Scan) -> None:
    pts = structure_coordinates(rig, scan.points, source=f"scan '{scan.source}'")
    if rig.is_body:
        for k, p in enumerate(pts):
            if not rig.structure.contains(*p[:3], tol=1e-6):
                raise InputError(f"scan '{scan.source}': point {k + 1} at (x, y, z) = "
                                 f"({p[0]:.4g}, {p[1]:.4g}, {p[2]:.4g}) m lies in none of the "
                                 f"blocks of rig '{rig.source}'")
        return
    for k, p in enumerate(scan.points):
        if not rig.structure.contains(p[0], p[1] if len(p) > 1 else 0.0, tol=1e-6):
            raise InputError(f"scan '{scan.source}': point {k + 1} at x = {p[0]:.4g} m lies off "
                             f"the structure of rig '{rig.source}'")
