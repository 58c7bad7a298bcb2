"""Whether a scan belongs to its rig: of the rig's kind of structure, on it, and covering the
points where the model's shapes are used (METHOD.md section 3, steps 2-4).

Checked when a scan meets the rig, before any fit: a plate's grid given to a beam rig, a
beam's line given to a plate rig, a point off the structure, or a gauge, force point, sensor
or lumped mass beyond the scanned extent (its shape values would be extrapolated) is refused
naming the scan, the rig and what differs. An SLDV scan rarely reaches the very edges: a rig
point a little beyond it (``COVERAGE_MARGIN``) is noted, not refused.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..records import Scan, ScanFRF, ScanSpectra
from ..rig import Rig
from ..structures.base import ranges_text

__all__ = ["check_scan_coverage", "check_scan_on_rig"]

COVERAGE_MARGIN = 0.05
"""How far a rig point may lie beyond the scanned extent, as a fraction of the structure's
largest extent (a few percent short of the edges is a normal scan): farther, it is refused."""


def check_scan_on_rig(rig: Rig, scan: Scan | ScanSpectra | ScanFRF) -> None:
    """Refuse a scan that is not of the rig's structure: its points of another kind of
    structure, or off it.

    Parameters
    ----------
    rig : Rig
    scan : Scan, ScanSpectra or ScanFRF
        Its points (n_points, n_dim) [m] in the rig's axes.

    Raises
    ------
    InputError
        Points of another kind of structure (:meth:`forcecal.structures.Structure.
        scan_mismatch`) or a point off the structure; naming the scan, the rig and what
        differs.
    """
    pts = _points(scan)
    why = rig.structure.scan_mismatch(pts)
    if why:
        raise InputError(f"scan '{scan.source}' on rig '{rig.source}': {why}")
    _check_points_on_structure(rig, scan, pts)


def check_scan_coverage(rig: Rig, scan: Scan | ScanSpectra | ScanFRF) -> tuple[str, ...]:
    """Refuse a scan of the rig's structure (:func:`check_scan_on_rig`) that stops clearly
    short of where the rig's points lie.

    Parameters
    ----------
    rig : Rig
    scan : Scan, ScanSpectra or ScanFRF

    Returns
    -------
    tuple of str
        Notes: rig points a little beyond the scanned extent (within ``COVERAGE_MARGIN``),
        parts of the structure the scan leaves out.

    Raises
    ------
    InputError
        A gauge, force point, sensor or lumped mass beyond the scanned extent by more than
        ``COVERAGE_MARGIN``, naming each, the scan, the rig, the scanned extent and the
        structure's.
    """
    return _coverage(rig, scan, _points(scan))


def _points(scan: Scan | ScanSpectra | ScanFRF) -> np.ndarray:
    return np.asarray(scan.points, dtype=float).reshape(scan.n_points, -1)


def _check_points_on_structure(rig: Rig, scan: Scan | ScanSpectra | ScanFRF,
                               pts: np.ndarray) -> None:
    st = rig.structure
    st.coordinates(pts, source=f"scan '{scan.source}' on rig '{rig.source}'")
    for k, p in enumerate(pts):
        xyz = [float(c) for c in p[:3]] + [0.0] * (3 - min(len(p), 3))
        if not st.contains(xyz[0], xyz[1], xyz[2], tol=1e-6):
            where = ", ".join(f"{c:.4g}" for c in xyz[:st.dim])
            axes = ", ".join(st.axes)
            raise InputError(f"scan '{scan.source}': point {k + 1} at "
                             + (f"x = {where}" if st.dim == 1 else f"({axes}) = ({where})")
                             + f" m lies off the structure of rig '{rig.source}'")


def _coverage(rig: Rig, scan: Scan | ScanSpectra | ScanFRF, pts: np.ndarray
              ) -> tuple[str, ...]:
    """Refuse rig points clearly beyond the scanned extent; notes for those a little beyond
    it and for parts of the structure the scan leaves out."""
    st = rig.structure
    axes = st.axes
    lo, hi = pts[:, :st.dim].min(axis=0), pts[:, :st.dim].max(axis=0)
    box = np.asarray(st.extent(), dtype=float).reshape(-1, 2)
    margin = COVERAGE_MARGIN * float(np.max(box[:, 1] - box[:, 0]))
    scanned = f"the scan covers {ranges_text(lo, hi, axes)}"
    items = ([(f"gauge {p.name}", (p.x, p.y, p.z)) for p in rig.gauges]
             + [(f"force point {p.name}", (p.x, p.y, p.z)) for p in rig.forces]
             + [(f"sensor {p.name}", (p.x, p.y, p.z)) for p in rig.sensors]
             + [(f"lumped mass structure.masses[{k}]", (m.x, m.y, m.z))
                for k, m in enumerate(st.masses)])
    far, near = [], []
    for name, xyz in items:
        c = np.asarray(xyz[:st.dim])
        beyond = float(np.max(np.maximum(lo - c, c - hi)))
        at = (f"x = {c[0]:.4g}" if st.dim == 1 else
              f"({', '.join(axes)}) = ({', '.join(f'{v:.4g}' for v in c)})")
        if beyond > margin:
            far.append(f"{name} at {at} m ({beyond:.3g} m beyond)")
        elif beyond > 1e-9:
            near.append(f"{name} ({beyond:.3g} m)")
    if far:
        raise InputError(
            f"scan '{scan.source}' on rig '{rig.source}': " + ", ".join(far)
            + f" {'lies' if len(far) == 1 else 'lie'} outside the scanned extent "
            f"{ranges_text(lo, hi, axes)} (the rig's structure spans "
            f"{ranges_text(box[:, 0], box[:, 1], axes)}; a scan may stop short of a point by "
            f"{margin:.3g} m, {COVERAGE_MARGIN:.0%} of the structure): the shapes would be "
            "extrapolated there; scan up to every gauge, force point and sensor")
    notes = []
    if near:
        notes.append(f"scan '{scan.source}': {scanned}; " + ", ".join(near)
                     + f" {'lies' if len(near) == 1 else 'lie'} a little beyond it: "
                     + ("its shape values are" if len(near) == 1 else "their shape values are")
                     + " extrapolated")
    short = np.maximum(lo - box[:, 0], box[:, 1] - hi)
    if np.any(short > margin):
        notes.append(f"scan '{scan.source}': {scanned} of the structure's "
                     f"{ranges_text(box[:, 0], box[:, 1], axes)}: the shapes, and the inertia "
                     "they give, are extrapolated over the rest")
    return tuple(notes)
