"""Kirchhoff plate by conforming Bogner-Fox-Schmit (BFS) finite elements.

The rectangle [0, a] x [0, b] is cut into an nx x ny mesh of rectangular elements. Each node
carries four degrees of freedom, ordered ``[w, w_x, w_y, w_xy]`` (deflection [m], the two slopes
[rad] and the twist [1/m]); node (i, j) at (xs[i], ys[j]) is node number ``j * (nx + 1) + i``
and owns DOFs ``4 * node + (0, 1, 2, 3)``. The element's shape functions are the tensor products
of the 1-D Hermite cubics, so w and both slopes are continuous across element edges (a
conforming element) and every bilinear field, in particular each rigid motion
``c0 + c1 x + c2 y``, is represented exactly.

Element stiffness from the bending energy density
``D/2 [(w_xx)^2 + (w_yy)^2 + 2 nu w_xx w_yy + 2 (1 - nu) w_xy^2]`` and consistent mass from
``rho h w^2 / 2``, both by 4 x 4 Gauss quadrature (exact for these bicubic integrands). Point
springs (the force gauges) and lumped masses attach anywhere through the shape functions.

This model is the simulator's own physics: it knows nothing of the estimator's bases. It offers
the interface :func:`forcecal.simulate.integrate.integrate` uses of a beam (``stiffness``,
``mass``, ``damping = beta K``, ``bending_stiffness``, ``beta``, ``row``, ``modes``,
``rigid_mode``), with ``dim = 2``: ``row`` takes (x, y) points.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike

from .modal import ModalModel

__all__: list[str] = []

# local DOF k of an element: corner (ix, iy) = _CORNERS[k // 4], nodal DOF d = k % 4
# (w, w_x, w_y, w_xy); its shape function is X[kx] * Y[ky] with the 1-D Hermite functions
# ordered [value at 0, slope at 0, value at 1, slope at 1].
_CORNERS = ((0, 0), (1, 0), (0, 1), (1, 1))
_KX = np.array([2 * ix + (d in (1, 3)) for ix, _ in _CORNERS for d in range(4)])
_KY = np.array([2 * iy + (d in (2, 3)) for _, iy in _CORNERS for d in range(4)])


def flexural_rigidity(youngs_modulus: float, thickness: float, poisson: float) -> float:
    """Flexural rigidity D = E h^3 / (12 (1 - nu^2)) of a plate.

    Parameters
    ----------
    youngs_modulus : float
        E [Pa].
    thickness : float
        h [m].
    poisson : float
        Poisson's ratio nu.

    Returns
    -------
    float
        D [N m].
    """
    return youngs_modulus * thickness**3 / (12.0 * (1.0 - poisson**2))


def _hermite(xi: np.ndarray, h: np.ndarray | float, deriv: int) -> np.ndarray:
    """1-D Hermite cubics on an element of length h, differentiated ``deriv`` times in x.

    Returns (n, 4): [value at 0, slope at 0, value at 1, slope at 1] at local xi in [0, 1];
    the slope functions carry the factor h, so their x-derivative at their node is 1.
    """
    xi = np.asarray(xi, dtype=float)
    h = np.broadcast_to(np.asarray(h, dtype=float), xi.shape)
    if deriv == 0:
        cols = (1 - 3 * xi**2 + 2 * xi**3, h * (xi - 2 * xi**2 + xi**3),
                3 * xi**2 - 2 * xi**3, h * (-(xi**2) + xi**3))
    elif deriv == 1:
        cols = ((-6 * xi + 6 * xi**2) / h, 1 - 4 * xi + 3 * xi**2,
                (6 * xi - 6 * xi**2) / h, -2 * xi + 3 * xi**2)
    elif deriv == 2:
        cols = ((-6 + 12 * xi) / h**2, (-4 + 6 * xi) / h,
                (6 - 12 * xi) / h**2, (-2 + 6 * xi) / h)
    else:
        raise ValueError("deriv must be 0, 1 or 2")
    return np.stack(cols, axis=-1)


def _element_matrices(d: float, nu: float, rho_h: float, hx: float,
                      hy: float) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness [N/m] and consistent mass [kg] (16 x 16) of one hx x hy BFS element."""
    g, wg = np.polynomial.legendre.leggauss(4)
    g, wg = (g + 1) / 2, wg / 2                                  # on [0, 1]
    xi_grid, eta_grid = np.meshgrid(g, g, indexing="ij")
    xi, eta = xi_grid.ravel(), eta_grid.ravel()
    weight = np.outer(wg, wg).ravel() * hx * hy                 # (16,) physical area weights
    x0, x1, x2 = (_hermite(xi, hx, k)[:, _KX] for k in range(3))
    y0, y1, y2 = (_hermite(eta, hy, k)[:, _KY] for k in range(3))
    w, wxx, wyy, wxy = x0 * y0, x2 * y0, x0 * y2, x1 * y1       # (n_gauss, 16)
    ww = w * weight[:, None]
    m = rho_h * (w.T @ ww)
    k = d * ((wxx * weight[:, None]).T @ wxx + (wyy * weight[:, None]).T @ wyy
             + nu * ((wxx * weight[:, None]).T @ wyy + (wyy * weight[:, None]).T @ wxx)
             + 2 * (1 - nu) * (wxy * weight[:, None]).T @ wxy)
    return 0.5 * (k + k.T), 0.5 * (m + m.T)


def _element_dofs(nx: int, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """(n, 16) global DOFs of elements (i, j) in local order."""
    i, j = np.atleast_1d(i), np.atleast_1d(j)
    cols = []
    for ix, iy in _CORNERS:
        node = (j + iy) * (nx + 1) + (i + ix)
        cols += [4 * node + d for d in range(4)]
    return np.stack(cols, axis=-1)


def bfs_row(xs: np.ndarray, ys: np.ndarray, points: ArrayLike) -> np.ndarray:
    """Rows mapping nodal DOFs to the deflection w(x, y).

    Parameters
    ----------
    xs : (nx + 1,) array [m]
        Node x coordinates, increasing.
    ys : (ny + 1,) array [m]
        Node y coordinates, increasing.
    points : (n_points, 2) or (2,) array [m]
        (x, y) on the rectangle, or one point.

    Returns
    -------
    (n_points, 4 * (nx + 1) * (ny + 1)) array [1]
        Row k maps the nodal DOFs to w(x_k, y_k); (n_dof,) for a single point.

    Raises
    ------
    ValueError
        Points that are not (x, y) pairs.
    """
    pts = np.asarray(points, dtype=float)
    single = pts.ndim == 1
    pts = np.atleast_2d(pts)
    if pts.shape[-1] != 2:
        raise ValueError(f"plate points must be (n, 2) (x, y) pairs, got shape {pts.shape}")
    nx, ny = len(xs) - 1, len(ys) - 1
    i = np.clip(np.searchsorted(xs, pts[:, 0], side="right") - 1, 0, nx - 1)
    j = np.clip(np.searchsorted(ys, pts[:, 1], side="right") - 1, 0, ny - 1)
    hx, hy = xs[i + 1] - xs[i], ys[j + 1] - ys[j]
    fx = _hermite((pts[:, 0] - xs[i]) / hx, hx, 0)[:, _KX]
    fy = _hermite((pts[:, 1] - ys[j]) / hy, hy, 0)[:, _KY]
    rows = np.zeros((len(pts), 4 * (nx + 1) * (ny + 1)))
    np.put_along_axis(rows, _element_dofs(nx, i, j), fx * fy, axis=1)
    return rows[0] if single else rows


@dataclass(frozen=True)
class PlateModel(ModalModel):
    """Assembled rectangular plate on point springs.

    Attributes
    ----------
    xs : (nx + 1,) array [m]
        Node x coordinates.
    ys : (ny + 1,) array [m]
        Node y coordinates.
    stiffness : (n_dof, n_dof) array [N/m]
        Plate bending plus the gauge springs.
    mass : (n_dof, n_dof) array [kg]
        Consistent distributed mass plus lumped masses.
    damping : (n_dof, n_dof) array [N s/m]
        ``beta * stiffness``.
    bending_stiffness : (n_dof, n_dof) array [N/m]
        The plate alone (no springs), singular.
    springs : tuple of (x [m], y [m], stiffness [N/m])
        The gauge springs.
    beta : float [s]
        Damping is ``beta * stiffness``.
    """

    dim: ClassVar[int] = 2

    xs: np.ndarray
    ys: np.ndarray
    stiffness: np.ndarray
    mass: np.ndarray
    damping: np.ndarray
    bending_stiffness: np.ndarray
    springs: tuple[tuple[float, float, float], ...] = field(default=())
    beta: float = 0.0

    @property
    def nodes(self) -> np.ndarray:
        """(n_nodes, 2) node coordinates [m], node j * (nx + 1) + i at (xs[i], ys[j])."""
        gx, gy = np.meshgrid(self.xs, self.ys, indexing="xy")
        return np.column_stack([gx.ravel(), gy.ravel()])

    def row(self, points: ArrayLike) -> np.ndarray:
        """Rows mapping nodal DOFs to w at (n, 2) points [m]: (n, n_dof); see :func:`bfs_row`."""
        return bfs_row(self.xs, self.ys, points)

    def rigid_mode(self, c0: float, c1: float, c2: float = 0.0) -> np.ndarray:
        """Nodal vector of the rigid motion w = c0 + c1 x + c2 y (exact in the BFS basis).

        Parameters
        ----------
        c0 : float
            Translation [m].
        c1 : float
            Rotation about y, the slope along x [rad].
        c2 : float
            Rotation about x, the slope along y [rad].

        Returns
        -------
        (n_dof,) array
            [w, w_x, w_y, w_xy] of every node.
        """
        nodes = self.nodes
        v = np.zeros(self.n_dof)
        v[0::4] = c0 + c1 * nodes[:, 0] + c2 * nodes[:, 1]
        v[1::4] = c1
        v[2::4] = c2
        return v


def assemble_plate(
    a: float,
    b: float,
    flexural: float,
    mass_per_area: float,
    poisson: float,
    mesh: tuple[int, int] = (10, 8),
    masses: tuple[tuple[float, float, float], ...] = (),
    springs: tuple[tuple[float, float, float], ...] = (),
    beta: float = 0.0,
) -> PlateModel:
    """Assemble a free rectangular plate with lumped masses and point springs.

    Parameters
    ----------
    a : float
        Side length along x [m].
    b : float
        Side length along y [m].
    flexural : float
        Flexural rigidity D [N m].
    mass_per_area : float
        rho h [kg/m^2].
    poisson : float
        Poisson's ratio nu.
    mesh : (nx, ny)
        Elements along x and y.
    masses : tuple of (x [m], y [m], m [kg])
        Point masses.
    springs : tuple of (x [m], y [m], k [N/m])
        Grounded springs: the force gauges.
    beta : float
        Stiffness-proportional damping coefficient [s]: ``C = beta K``. On the plate it is
        internal (rigid motions are stress free: no net force or moment), on a gauge a dashpot
        inside the gauge whose force the gauge measures, so the rigid-body balance of
        METHOD.md eq. 6 holds exactly.

    Returns
    -------
    PlateModel
        The assembled matrices and the springs.

    Raises
    ------
    ValueError
        A mesh without an element along x or y.
    """
    nx, ny = (int(n) for n in mesh)
    if nx < 1 or ny < 1:
        raise ValueError(f"mesh {mesh} needs at least one element each way")
    xs, ys = np.linspace(0.0, a, nx + 1), np.linspace(0.0, b, ny + 1)
    kb, mm = _plate_matrices(xs, ys, flexural, poisson, mass_per_area)
    for x, y, m in masses:
        r = bfs_row(xs, ys, (x, y))
        mm += m * np.outer(r, r)
    kk = kb.copy()
    for x, y, k in springs:
        r = bfs_row(xs, ys, (x, y))
        kk += k * np.outer(r, r)
    return PlateModel(xs=xs, ys=ys, stiffness=kk, mass=mm, damping=beta * kk,
                      bending_stiffness=kb, springs=tuple(springs), beta=beta)


def _plate_matrices(xs: np.ndarray, ys: np.ndarray, flexural: float, poisson: float,
                    mass_per_area: float) -> tuple[np.ndarray, np.ndarray]:
    """Bending stiffness [N/m] and consistent mass [kg] of the free plate on the grid xs x ys
    [m]; each distinct element size is computed once."""
    nx, ny = len(xs) - 1, len(ys) - 1
    n_dof = 4 * (nx + 1) * (ny + 1)
    kb = np.zeros((n_dof, n_dof))
    mm = np.zeros((n_dof, n_dof))
    cache: dict[tuple[float, float], tuple[np.ndarray, np.ndarray]] = {}
    for j in range(ny):
        for i in range(nx):
            h = (float(xs[i + 1] - xs[i]), float(ys[j + 1] - ys[j]))
            if h not in cache:
                cache[h] = _element_matrices(flexural, poisson, mass_per_area, *h)
            ke, me = cache[h]
            dofs = _element_dofs(nx, np.array([i]), np.array([j]))[0]
            ix = np.ix_(dofs, dofs)
            kb[ix] += ke
            mm[ix] += me
    return kb, mm


def simply_supported_dofs(model: PlateModel) -> np.ndarray:
    """DOFs fixed by simple support on all four edges.

    w = 0 along an edge fixes w and its tangential derivative there: w and w_y on the edges
    x = 0 and x = a, w and w_x on the edges y = 0 and y = b (the normal slope and the twist
    stay free, except that a corner fixes both slopes).

    Parameters
    ----------
    model : PlateModel
        The plate.

    Returns
    -------
    (n_fixed,) int array
        The fixed DOFs, ascending.
    """
    nodes = model.nodes
    on_x_edge = np.isclose(nodes[:, 0], model.xs[0]) | np.isclose(nodes[:, 0], model.xs[-1])
    on_y_edge = np.isclose(nodes[:, 1], model.ys[0]) | np.isclose(nodes[:, 1], model.ys[-1])
    fixed = [4 * n for n in np.flatnonzero(on_x_edge | on_y_edge)]
    fixed += [4 * n + 2 for n in np.flatnonzero(on_x_edge)]
    fixed += [4 * n + 1 for n in np.flatnonzero(on_y_edge)]
    return np.unique(fixed)


def simply_supported_frequencies(a: float, b: float, flexural: float, mass_per_area: float,
                                 poisson: float = 0.3, mesh: tuple[int, int] = (8, 8),
                                 n_modes: int = 4) -> np.ndarray:
    """Natural frequencies of the plate simply supported on all four edges.

    Parameters
    ----------
    a : float
        Side length along x [m].
    b : float
        Side length along y [m].
    flexural : float
        Flexural rigidity D [N m].
    mass_per_area : float
        rho h [kg/m^2].
    poisson : float
        Poisson's ratio nu.
    mesh : (nx, ny)
        Elements along x and y.
    n_modes : int
        How many of the lowest frequencies to return.

    Returns
    -------
    (n_modes,) array [Hz]
    """
    model = assemble_plate(a, b, flexural, mass_per_area, poisson, mesh)
    free = np.setdiff1d(np.arange(model.n_dof), simply_supported_dofs(model))
    w2 = scipy.linalg.eigh(model.bending_stiffness[np.ix_(free, free)],
                           model.mass[np.ix_(free, free)], eigvals_only=True,
                           subset_by_index=[0, n_modes - 1])
    return np.sqrt(w2) / (2 * np.pi)


def simply_supported_static_deflection(a: float, b: float, flexural: float, load: float,
                                       load_point: tuple[float, float],
                                       eval_point: tuple[float, float], poisson: float = 0.3,
                                       mesh: tuple[int, int] = (8, 8)) -> float:
    """Static deflection at eval_point of the simply supported plate under a point load.

    Parameters
    ----------
    a : float
        Side length along x [m].
    b : float
        Side length along y [m].
    flexural : float
        Flexural rigidity D [N m].
    load : float
        The point load [N].
    load_point : (x, y)
        Where the load acts [m].
    eval_point : (x, y)
        Where the deflection is wanted [m].
    poisson : float
        Poisson's ratio nu.
    mesh : (nx, ny)
        Elements along x and y.

    Returns
    -------
    float
        The deflection [m].
    """
    model = assemble_plate(a, b, flexural, 1.0, poisson, mesh)
    free = np.setdiff1d(np.arange(model.n_dof), simply_supported_dofs(model))
    f = load * model.row(load_point)
    u = np.zeros(model.n_dof)
    u[free] = np.linalg.solve(model.bending_stiffness[np.ix_(free, free)], f[free])
    return float(model.row(eval_point) @ u)
