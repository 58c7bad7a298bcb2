"""Relaxation shapes of statically determinate gauges (METHOD.md section 2).

Releasing gauge r by a unit amount while the others stay put moves the structure rigidly by
psi_r, with psi_r(g_r) = 1 and psi_r(g_s) = 0. The shapes are the rigid-body modes of the
structure combined so that the matrix [psi_r(g_s)] is the identity:

- beam in plane bending: w = 1, x;
- plate in out-of-plane bending: w = 1, x, y;
- 3-D body: u = t + theta x (x - c), three translations and three rotations. A gauge, a force
  or a sensor on a body measures the component d . u along its direction d, so every shape is
  evaluated at *locations* (x, y, z, dx, dy, dz) (:func:`forcecal.rig.locations`).

The gauges hold the structure statically determinately when there are as many as rigid modes
and that matrix is invertible (the paper's conditions II-IV; on a body it is singular when, for
example, every gauge's line of action meets one line, or all lie parallel to one plane);
otherwise :class:`ConditioningError` says so.
"""

from __future__ import annotations

import numpy as np

from .errors import ConditioningError
from .rig import RIGID_MODES, Rig

__all__ = ["force_matrix", "relaxation_shapes", "rigid_modes"]

_MAX_COND = 1e8


def rigid_modes(kind: str, points: np.ndarray, centre: np.ndarray | None = None,
                scale: float = 1.0) -> np.ndarray:
    """Rigid-body modes evaluated at points (beam, plate) or locations (body).

    Parameters
    ----------
    kind : "beam" (modes 1, x), "plate" (modes 1, x, y) or "body" (the translations along x, y,
        z, then the rotations about axes through ``centre``, divided by ``scale``)
    points : (n_points, 2) (x, y) [m], or on a body (n_points, 6) locations
    centre : (3,) [m] the rotations' centre on a body (default the origin)
    scale : [m] length dividing the rotations, so that every mode is of order 1

    Returns
    -------
    (n_modes, n_points) array [1, m]
    """
    pts = np.atleast_2d(np.asarray(points, dtype=float))
    if kind == "body":
        if pts.shape[1] != 6:
            raise ValueError(f"a body's shapes take locations (n, 6); got shape {pts.shape}")
        r = pts[:, :3] - (np.zeros(3) if centre is None else centre)
        d = pts[:, 3:]
        # d . (theta x r) = theta . (r x d)
        return np.vstack([d.T, np.cross(r, d).T / scale])
    rows = [np.ones(len(pts)), pts[:, 0]]
    if kind == "plate":
        rows.append(pts[:, 1])
    return np.stack(rows)


def _frame(rig: Rig) -> tuple[np.ndarray | None, float]:
    """Centre and length scale of a body's rotations: the gauges' centroid and spread."""
    if not rig.is_body:
        return None, 1.0
    g = rig.gauge_points[:, :3]
    centre = g.mean(axis=0)
    return centre, max(float(np.max(np.linalg.norm(g - centre, axis=1))), 1e-9)


def _coefficients(rig: Rig) -> np.ndarray:
    """(n_gauges, n_modes) coefficients C with psi = C @ modes."""
    kind = rig.structure.kind
    centre, scale = _frame(rig)
    at_gauges = rigid_modes(kind, rig.gauge_points, centre, scale)     # (n_modes, n_gauges)
    if at_gauges.shape[1] != RIGID_MODES[kind]:
        raise ConditioningError(
            f"rig '{rig.source}': {at_gauges.shape[1]} gauges for {RIGID_MODES[kind]} "
            "rigid-body modes; the support is not statically determinate")
    cond = np.linalg.cond(at_gauges)
    if not np.isfinite(cond) or cond > _MAX_COND:
        why = ("some rigid motion moves none of them, e.g. their lines of action all meet "
               "one line or all lie parallel to one plane" if kind == "body" else
               "gauges on one line, or at one point")
        raise ConditioningError(
            f"rig '{rig.source}': the gauges {', '.join(rig.gauge_names)} do not hold the "
            f"structure statically determinately (their relaxation shapes are not independent: "
            f"{why})")
    return np.linalg.inv(at_gauges)


def relaxation_shapes(rig: Rig, points: np.ndarray) -> np.ndarray:
    """psi_r at points.

    Parameters
    ----------
    rig : the rig (its gauges and structure kind)
    points : (n_points,) x or (n_points, 2) (x, y) [m]; on a body (n_points, 6) locations

    Returns
    -------
    (n_gauges, n_points) array [1]
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim == 1:
        pts = np.column_stack([pts, np.zeros_like(pts)])
    centre, scale = _frame(rig)
    return _coefficients(rig) @ rigid_modes(rig.structure.kind, pts, centre, scale)


def force_matrix(rig: Rig) -> np.ndarray:
    """Psi[r, n] = psi_r(x_n) (on a body d_n . psi_r(x_n)): how each external force loads each
    relaxed gauge, (n_gauges, n_forces) [1]."""
    return relaxation_shapes(rig, rig.force_points)
