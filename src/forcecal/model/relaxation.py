"""Relaxation shapes of statically determinate gauges (METHOD.md section 2).

Releasing gauge r by a unit amount while the others stay put moves the structure rigidly by
psi_r, with psi_r(g_r) = 1 and psi_r(g_s) = 0. The shapes are the rigid-body modes of the
structure combined so that the matrix [psi_r(g_s)] is the identity:

- beam in plane bending: w = 1, x;
- plate in out-of-plane bending: w = 1, x, y;
- 3-D body: u = t + theta x (x - c), three translations and three rotations. A gauge, a force
  or a sensor on a body measures the component d . u along its direction d, so every shape is
  evaluated at *locations* (x, y, z, dx, dy, dz) (:func:`forcecal.structures.locations`).

Each structure kind answers its rigid modes (:meth:`forcecal.structures.Structure.rigid_modes`);
this module only combines them.

The gauges hold the structure statically determinately when there are as many as rigid modes
and that matrix is invertible (the paper's conditions II-IV; on a body it is singular when, for
example, every gauge's line of action meets one line, or all lie parallel to one plane);
otherwise :class:`ConditioningError` says so.
"""

from __future__ import annotations

import numpy as np

from ..errors import ConditioningError
from ..rig import Rig

__all__ = ["force_matrix"]

_MAX_COND = 1e8


def _coefficients(rig: Rig) -> np.ndarray:
    """(n_gauges, n_modes) coefficients C with psi = C @ modes."""
    st = rig.structure
    gauges = st.coordinates(rig.gauge_points)
    at_gauges = st.rigid_modes(gauges, st.frame(gauges))           # (n_modes, n_gauges)
    if at_gauges.shape[1] != st.n_rigid:
        raise ConditioningError(
            f"rig '{rig.source}': {at_gauges.shape[1]} gauges for {st.n_rigid} "
            "rigid-body modes; the support is not statically determinate")
    cond = np.linalg.cond(at_gauges)
    if not np.isfinite(cond) or cond > _MAX_COND:
        raise ConditioningError(
            f"rig '{rig.source}': the gauges {', '.join(rig.gauge_names)} do not hold the "
            f"structure statically determinately (their relaxation shapes are not independent: "
            f"{st.singular_support})")
    inverse: np.ndarray = np.linalg.inv(at_gauges)
    return inverse


def relaxation_shapes(rig: Rig, points: np.ndarray) -> np.ndarray:
    """psi_r at points.

    Parameters
    ----------
    rig : Rig
        The rig (its gauges and structure).
    points : ndarray
        Rig points ((n_points, 2) (x, y) [m]; on a body (n_points, 6) locations) or the
        structure's own coordinates (x (n_points,) on a beam).

    Returns
    -------
    (n_gauges, n_points) ndarray [1]
    """
    st = rig.structure
    frame = st.frame(st.coordinates(rig.gauge_points))
    shapes: np.ndarray = _coefficients(rig) @ st.rigid_modes(st.coordinates(points), frame)
    return shapes


def force_matrix(rig: Rig) -> np.ndarray:
    """Psi[r, n] = psi_r(x_n) (on a body d_n . psi_r(x_n)): how each external force loads each
    relaxed gauge.

    Parameters
    ----------
    rig : Rig

    Returns
    -------
    (n_gauges, n_forces) ndarray [1]
    """
    return relaxation_shapes(rig, rig.force_points)
