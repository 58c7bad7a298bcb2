"""The inertia term: mass couplings and accelerations (METHOD.md eq. 6 and 23, section 3 steps
3 and 5).

m_r[phi] = integral(rho psi_r phi) + sum_k m_k psi_r(x_k) phi(x_k) is computed with the
structure's own mass quadrature (Gauss-Legendre along a beam, collapsed Gauss rules on a
plate's triangles, tensor Gauss rules through a body's blocks; see
:meth:`forcecal.structures.Structure.mass_quadrature`), exact for the polynomial shapes of
:mod:`forcecal.model.basis` up to the quadrature's degree, plus the lumped masses. On a body both
psi_r and phi are vector fields: the product is their dot product, so every quadrature point
enters three times, once per axis.

With the generalized coordinates Q_n of harmonic n (:mod:`forcecal.forces.coordinates`), the inertia
term of every relaxed gauge is

    J_{r,n} = sum_j m_{r,n,j} Qdd_{n,j},    Qdd_{n,j} = -(n w0)^2 Q_{n,j}

(:func:`inertia_term`), the one implementation used by the batch estimate, the streaming
estimator and the uncertainty propagation.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..rig import Rig
from .relaxation import relaxation_shapes

__all__ = ["inertia_term", "mass_coupling", "mass_weights"]


def mass_weights(rig: Rig) -> tuple[np.ndarray, np.ndarray]:
    """Points and mass-weighted relaxation shapes that turn any shape into its couplings.

    Parameters
    ----------
    rig : Rig

    Returns
    -------
    points : ndarray
        Structure coordinates of the quadrature nodes, then of the lumped masses
        (on a body (n_q, 6) locations, each node and mass along x, y and z).
    weights : (n_gauges, n_q) ndarray
        [kg] m_r[phi] = weights[r] @ phi(points).
    """
    points, masses = rig.structure.mass_quadrature()
    return points, relaxation_shapes(rig, points) * masses[None, :]


def mass_coupling(rig: Rig, shape: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """Couplings m_r[phi] of every relaxed gauge with a shape.

    Parameters
    ----------
    rig : Rig
    shape : callable
        Maps structure coordinates to values (n,) or (n, k), real or complex.

    Returns
    -------
    (n_gauges,) or (n_gauges, k) ndarray
        [kg x unit of the shape]
    """
    pts, weights = mass_weights(rig)
    coupling: np.ndarray = weights @ shape(pts)
    return coupling


def acceleration(q: np.ndarray | complex, w: float) -> np.ndarray | complex:
    """Qdd = -w^2 Q: the acceleration phasor of a coordinate at angular frequency w.

    Parameters
    ----------
    q : complex or ndarray
        Coordinate phasors Q [1] (or any linear map producing them).
    w : float
        [rad/s] n w0 for harmonic n.

    Returns
    -------
    complex or ndarray, as ``q`` [1/s^2]
    """
    return -(w**2) * q


def inertia_term(couplings: np.ndarray, q: np.ndarray | complex, w: float) -> np.ndarray:
    """J_r = sum_j m_{r,j} Qdd_j: the inertia term of every relaxed gauge at one harmonic.

    Parameters
    ----------
    couplings : (n_gauges,) or (n_gauges, n_shapes) complex ndarray
        [kg m] the mass couplings m_{r,n,j} of the harmonic's shapes.
    q : complex, (n_shapes,) or (n_shapes, n_cols) complex ndarray
        Coordinates Q_{n,j} [1]; with extra columns (a linear map from sensor phasors to
        coordinates) the result is the map from those phasors to J.
    w : float
        [rad/s] the harmonic's angular frequency n w0.

    Returns
    -------
    (n_gauges,) or (n_gauges, n_cols) complex ndarray [N]
    """
    m = np.asarray(couplings)
    qdd = np.asarray(acceleration(q, w))
    if m.ndim == 1:
        return np.multiply.outer(m, qdd) if qdd.ndim else m * qdd
    j: np.ndarray = m @ qdd
    return j
