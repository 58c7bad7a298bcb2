"""Euler-Bernoulli beam by Hermite cubic finite elements.

Degrees of freedom per node: deflection w [m] and rotation theta = dw/dx [rad], ordered
``[w_0, theta_0, w_1, theta_1, ...]``. Point springs, dampers and masses attach anywhere along
the beam through the element's shape functions, so no node has to sit on a gauge or a pole.

This model is the simulator's own physics: it knows nothing of the estimator's bases.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from .modal import ModalModel

__all__: list[str] = []


def _element_matrices(ei: float, rho_a: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness [N/m] and consistent mass [kg] matrices of one element of length h."""
    k = ei / h**3 * np.array([
        [12.0, 6 * h, -12.0, 6 * h],
        [6 * h, 4 * h**2, -6 * h, 2 * h**2],
        [-12.0, -6 * h, 12.0, -6 * h],
        [6 * h, 2 * h**2, -6 * h, 4 * h**2],
    ])
    m = rho_a * h / 420.0 * np.array([
        [156.0, 22 * h, 54.0, -13 * h],
        [22 * h, 4 * h**2, 13 * h, -3 * h**2],
        [54.0, 13 * h, 156.0, -22 * h],
        [-13 * h, -3 * h**2, -22 * h, 4 * h**2],
    ])
    return k, m


def hermite_row(nodes: np.ndarray, x: float | np.ndarray) -> np.ndarray:
    """Rows mapping nodal DOFs to the deflection w(x).

    Parameters
    ----------
    nodes : (n_nodes,) array [m]
        Node coordinates, increasing.
    x : float or (n_points,) array [m]
        Where the deflection is wanted, within [nodes[0], nodes[-1]].

    Returns
    -------
    (n_points, 2 * n_nodes) array [1]
        Row k maps the nodal DOFs to w(x_k); (2 * n_nodes,) for a scalar x.
    """
    scalar = np.ndim(x) == 0
    xs = np.atleast_1d(np.asarray(x, dtype=float))
    n_nodes = len(nodes)
    e = np.clip(np.searchsorted(nodes, xs, side="right") - 1, 0, n_nodes - 2)
    h = nodes[e + 1] - nodes[e]
    xi = (xs - nodes[e]) / h
    rows = np.zeros((len(xs), 2 * n_nodes))
    idx = np.arange(len(xs))
    rows[idx, 2 * e] = 1 - 3 * xi**2 + 2 * xi**3
    rows[idx, 2 * e + 1] = h * (xi - 2 * xi**2 + xi**3)
    rows[idx, 2 * e + 2] = 3 * xi**2 - 2 * xi**3
    rows[idx, 2 * e + 3] = h * (-(xi**2) + xi**3)
    return rows[0] if scalar else rows


@dataclass(frozen=True)
class BeamModel(ModalModel):
    """Assembled beam on point springs.

    Attributes
    ----------
    nodes : (n_nodes,) array [m]
        Node coordinates along the beam.
    stiffness : (n_dof, n_dof) array [N/m]
        Beam bending plus the gauge springs.
    mass : (n_dof, n_dof) array [kg]
        Consistent distributed mass plus lumped masses.
    damping : (n_dof, n_dof) array [N s/m]
        ``beta * stiffness``.
    bending_stiffness : (n_dof, n_dof) array [N/m]
        The beam alone (no springs), singular.
    springs : tuple of (x [m], stiffness [N/m])
        The gauge springs.
    beta : float [s]
        Damping is ``beta * stiffness``.
    """

    nodes: np.ndarray
    stiffness: np.ndarray
    mass: np.ndarray
    damping: np.ndarray
    bending_stiffness: np.ndarray
    springs: tuple[tuple[float, float], ...] = field(default=())
    beta: float = 0.0

    def row(self, x: float | np.ndarray) -> np.ndarray:
        """Rows mapping nodal DOFs to w(x) [1]; see :func:`hermite_row`."""
        return hermite_row(self.nodes, x)

    def rigid_mode(self, a: float, b: float) -> np.ndarray:
        """Nodal vector of the rigid motion w(x) = a + b x (exact in the Hermite basis).

        Parameters
        ----------
        a : float
            Translation [m].
        b : float
            Rotation [rad].

        Returns
        -------
        (n_dof,) array
            Deflections [m] and rotations [rad] of every node.
        """
        v = np.empty(self.n_dof)
        v[0::2] = a + b * self.nodes
        v[1::2] = b
        return v


def assemble_beam(
    length: float,
    ei: float,
    mass_per_length: float,
    n_elements: int = 60,
    masses: tuple[tuple[float, float], ...] = (),
    springs: tuple[tuple[float, float], ...] = (),
    beta: float = 0.0,
) -> BeamModel:
    """Assemble a free-free beam with lumped masses and point springs.

    Parameters
    ----------
    length : float
        Beam length [m].
    ei : float
        Bending stiffness [N m^2].
    mass_per_length : float
        Distributed mass [kg/m].
    n_elements : int
        Number of equal Hermite elements.
    masses : tuple of (x [m], m [kg])
        Point masses.
    springs : tuple of (x [m], k [N/m])
        Grounded springs: the force gauges.
    beta : float
        Stiffness-proportional damping coefficient [s]: ``C = beta K``. On the beam it is
        internal (rigid motions are stress free, so it exerts no net force or moment on the
        structure); on a gauge it is a dashpot ``beta k`` inside the gauge, whose force the
        gauge measures. Either way the rigid-body balance of METHOD.md eq. 6 holds exactly.

    Returns
    -------
    BeamModel
        The assembled matrices and the springs.
    """
    nodes = np.linspace(0.0, length, n_elements + 1)
    n_dof = 2 * len(nodes)
    kb = np.zeros((n_dof, n_dof))
    mm = np.zeros((n_dof, n_dof))
    for e in range(n_elements):
        ke, me = _element_matrices(ei, mass_per_length, nodes[e + 1] - nodes[e])
        sl = slice(2 * e, 2 * e + 4)
        kb[sl, sl] += ke
        mm[sl, sl] += me
    for x, m in masses:
        r = hermite_row(nodes, x)
        mm += m * np.outer(r, r)
    kk = kb.copy()
    for x, k in springs:
        r = hermite_row(nodes, x)
        kk += k * np.outer(r, r)
    return BeamModel(nodes=nodes, stiffness=kk, mass=mm, damping=beta * kk, bending_stiffness=kb,
                     springs=tuple(springs), beta=beta)


def natural_frequencies(model: ModalModel, n: int | None = None) -> np.ndarray:
    """Undamped natural frequencies of an assembled model (beam, plate or body), ascending.

    Parameters
    ----------
    model : ModalModel
        The model, with its ``stiffness`` [N/m] and ``mass`` [kg] matrices.
    n : int, optional
        How many of the lowest frequencies to return (default all).

    Returns
    -------
    (n_dof,) or (n,) array [Hz]
        The rigid modes give 0.
    """
    w2 = scipy.linalg.eigh(model.stiffness, model.mass, eigvals_only=True)
    f = np.sqrt(np.clip(w2, 0.0, None)) / (2 * np.pi)
    return f if n is None else f[:n]


def pinned_pinned_frequencies(length: float, ei: float, mass_per_length: float,
                              n_elements: int = 60, n_modes: int = 3) -> np.ndarray:
    """Natural frequencies [Hz] of the beam pinned at both ends (w = 0 at x = 0 and L).

    Parameters
    ----------
    length : float
        Beam length [m].
    ei : float
        Bending stiffness [N m^2].
    mass_per_length : float
        Distributed mass [kg/m].
    n_elements : int
        Number of equal Hermite elements.
    n_modes : int
        How many of the lowest frequencies to return.

    Returns
    -------
    (n_modes,) array [Hz]
    """
    model = assemble_beam(length, ei, mass_per_length, n_elements)
    free = np.setdiff1d(np.arange(model.n_dof), [0, model.n_dof - 2])
    w2 = scipy.linalg.eigh(model.bending_stiffness[np.ix_(free, free)],
                           model.mass[np.ix_(free, free)], eigvals_only=True)
    return np.sqrt(w2[:n_modes]) / (2 * np.pi)


def pinned_static_deflection(length: float, ei: float, load: float, x_load: float,
                             x_eval: float, n_elements: int = 60) -> float:
    """Static deflection at x_eval of the pinned-pinned beam under a point load.

    Parameters
    ----------
    length : float
        Beam length [m].
    ei : float
        Bending stiffness [N m^2].
    load : float
        The point load [N].
    x_load : float
        Where the load acts [m].
    x_eval : float
        Where the deflection is wanted [m].
    n_elements : int
        Number of equal Hermite elements.

    Returns
    -------
    float
        The deflection [m].
    """
    model = assemble_beam(length, ei, 1.0, n_elements)
    free = np.setdiff1d(np.arange(model.n_dof), [0, model.n_dof - 2])
    f = load * model.row(x_load)
    u = np.zeros(model.n_dof)
    u[free] = np.linalg.solve(model.bending_stiffness[np.ix_(free, free)], f[free])
    return float(model.row(x_eval) @ u)
