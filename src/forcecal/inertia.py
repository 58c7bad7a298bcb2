"""Mass coupling of relaxation shapes and deflection shapes (METHOD.md eq. 6).

m_r[phi] = integral(rho psi_r phi) + sum_k m_k psi_r(x_k) phi(x_k), by Gauss-Legendre
quadrature along the beam (exact for the polynomial shapes of :mod:`forcecal.basis` up to the
quadrature's degree) plus the lumped masses.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .relaxation import relaxation_shapes
from .rig import Rig

__all__ = ["mass_coupling", "mass_weights"]

_N_QUAD = 64


def mass_weights(rig: Rig, n_quad: int = _N_QUAD) -> tuple[np.ndarray, np.ndarray]:
    """Points and mass-weighted relaxation shapes that turn any shape into its couplings.

    Returns
    -------
    points : (n_q,) or (n_q, 2) array [m], quadrature nodes then the lumped masses' positions
    weights : (n_gauges, n_q) array [kg]: m_r[phi] = weights[r] @ phi(points)
    """
    st = rig.structure
    if st.kind != "beam":
        raise NotImplementedError("mass coupling over a plate outline")
    xi, wi = np.polynomial.legendre.leggauss(n_quad)
    x = 0.5 * st.length * (xi + 1.0)
    w = 0.5 * st.length * wi * st.mass_per_length
    xm = np.array([m.x for m in st.masses])
    mm = np.array([m.mass for m in st.masses])
    pts = np.concatenate([x, xm])
    weights = relaxation_shapes(rig, pts) * np.concatenate([w, mm])[None, :]
    return pts, weights


def mass_coupling(rig: Rig, shape: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """Couplings m_r[phi] of every relaxed gauge with a shape.

    Parameters
    ----------
    shape : callable mapping points (n,) [m] to values (n,) or (n, k), real or complex

    Returns
    -------
    (n_gauges,) or (n_gauges, k) array [kg x unit of the shape]
    """
    pts, weights = mass_weights(rig)
    return weights @ shape(pts)
