"""Relaxation shapes of statically determinate gauges (METHOD.md section 2).

Releasing gauge r by a unit amount while the others stay put moves the structure rigidly by
psi_r, with psi_r(g_r) = 1 and psi_r(g_s) = 0. The shapes are the rigid-body modes of the
structure (beam in plane bending: 1, x; plate in out-of-plane bending: 1, x, y) combined so that
the matrix [psi_r(g_s)] is the identity.
"""

from __future__ import annotations

import numpy as np

from .errors import ConditioningError
from .rig import Rig

__all__ = ["force_matrix", "relaxation_shapes", "rigid_modes"]


def rigid_modes(kind: str, points: np.ndarray) -> np.ndarray:
    """Rigid-body modes of out-of-plane motion evaluated at points.

    Parameters
    ----------
    kind : "beam" (modes 1, x) or "plate" (modes 1, x, y)
    points : (n_points, 2) array [m]

    Returns
    -------
    (n_modes, n_points) array [1, m]
    """
    pts = np.atleast_2d(np.asarray(points, dtype=float))
    rows = [np.ones(len(pts)), pts[:, 0]]
    if kind == "plate":
        rows.append(pts[:, 1])
    return np.stack(rows)


def _coefficients(rig: Rig) -> np.ndarray:
    """(n_gauges, n_modes) coefficients C with psi = C @ modes."""
    modes_at_gauges = rigid_modes(rig.structure.kind, rig.gauge_points)   # (n_modes, n_gauges)
    if modes_at_gauges.shape[0] != modes_at_gauges.shape[1]:
        raise ConditioningError(
            f"rig '{rig.source}': {modes_at_gauges.shape[1]} gauges for "
            f"{modes_at_gauges.shape[0]} rigid-body modes; the support is not statically "
            "determinate")
    cond = np.linalg.cond(modes_at_gauges)
    if not np.isfinite(cond) or cond > 1e8:
        raise ConditioningError(
            f"rig '{rig.source}': the gauges {', '.join(rig.gauge_names)} do not hold the "
            "structure statically determinately (their relaxation shapes are not independent: "
            "gauges on one line, or at one point)")
    return np.linalg.inv(modes_at_gauges)


def relaxation_shapes(rig: Rig, points: np.ndarray) -> np.ndarray:
    """psi_r at points.

    Parameters
    ----------
    rig : the rig (its gauge positions and structure kind)
    points : (n_points,) or (n_points, 2) array [m]

    Returns
    -------
    (n_gauges, n_points) array [1]
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim == 1:
        pts = np.column_stack([pts, np.zeros_like(pts)])
    return _coefficients(rig) @ rigid_modes(rig.structure.kind, pts)


def force_matrix(rig: Rig) -> np.ndarray:
    """Psi[r, n] = psi_r(x_n): how each external force loads each relaxed gauge, (n_gauges,
    n_forces) [1]."""
    return relaxation_shapes(rig, rig.force_points)
