"""Linear elastic 3-D block (a housing) by 8-node hexahedra with incompatible modes.

The box ``origin + [0, a] x [0, b] x [0, c]`` is cut into an nx x ny x nz mesh of rectangular
boxes. Node (i, j, k) at (xs[i], ys[j], zs[k]) is node number ``(k * (ny + 1) + j) * (nx + 1) + i``
and owns DOFs ``3 * node + (0, 1, 2)``: the displacements (u_x, u_y, u_z) [m]. Inside an element
the displacement is the trilinear interpolation of its eight corners, so every linear field, in
particular each rigid motion ``t + theta x (x - origin)``, is represented exactly. Stiffness
from Hooke's law with Wilson-Taylor incompatible modes, consistent mass, both by Gauss
quadrature (:func:`hex8_element`).

Every place where the displacement is evaluated is a *location*: a row (x, y, z, dx, dy, dz) of a
point [m] and a measuring direction (normalised here); its displacement is d . u(x). Point springs
(the force gauges), lumped masses and poles all use this convention.

This model is the simulator's own physics (the virtual rig, METHOD.md section 6): it knows
nothing of the estimator's bases. It offers the interface
:func:`forcecal.simulate.integrate.integrate` uses of a beam (``stiffness``, ``mass``,
``damping = beta K``, ``bending_stiffness``, ``beta``, ``row``, ``modes``, ``rigid_mode``),
with ``dim = 3``: ``row`` takes (n, 6) locations.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike

from .modal import ModalModel

__all__: list[str] = []

# local node n of an element sits at corner (ix, iy, iz) = _CORNERS[n], n = ix + 2 iy + 4 iz,
# i.e. the global node ordering restricted to one element; local DOF 3 n + c is component c.
_CORNERS = np.array([(ix, iy, iz) for iz in (0, 1) for iy in (0, 1) for ix in (0, 1)])
_SIGNS = 2 * _CORNERS - 1                          # corner in natural coordinates
_GAUSS = _SIGNS / np.sqrt(3.0)                     # the 2 x 2 x 2 Gauss points, weights 1
_SHEAR = ((1, 2), (0, 2), (0, 1))                  # Voigt: xx, yy, zz, yz, xz, xy


def _shape(p: np.ndarray) -> np.ndarray:
    """Trilinear shape functions at natural points p (n, 3): (n, 8)."""
    return np.prod(1 + p[:, None, :] * _SIGNS[None], axis=-1) / 8


def _strain(grad: np.ndarray) -> np.ndarray:
    """Strain-displacement matrix (6, 3 m) of m scalar functions with gradients grad (m, 3);
    DOF 3 f + c is component c of function f; engineering shear strains."""
    b = np.zeros((6, grad.shape[0], 3))
    for a in range(3):
        b[a, :, a] = grad[:, a]
    for v, (a, c) in enumerate(_SHEAR, start=3):
        b[v, :, a], b[v, :, c] = grad[:, c], grad[:, a]
    return b.reshape(6, -1)


def hex8_element(youngs_modulus: float, poisson: float, density: float, hx: float, hy: float,
                 hz: float, incompatible: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness [N/m] and consistent mass [kg] (24 x 24) of one hx x hy x hz box [m].

    Local DOF ``3 n + c`` is component c (x, y, z) at local node n = ix + 2 iy + 4 iz, the corner
    (ix, iy, iz) in {0, 1}^3 (the global ordering restricted to one element).

    Stiffness: isotropic Hooke's law (E, nu) with Wilson-Taylor incompatible modes. Each
    displacement component gets the three element-internal bubbles (1 - xi^2), (1 - eta^2),
    (1 - zeta^2) in the natural coordinates xi, eta, zeta in [-1, 1]; these 9 internal DOFs are
    condensed out statically. They let an element bend without the parasitic shear that locks
    the plain trilinear brick. On a box the Jacobian is constant and the bubbles' strains
    integrate to zero over the element, so the element passes the patch test without Taylor's
    correction. 2 x 2 x 2 Gauss quadrature. Consistent mass from the trilinear shape functions,
    by the same (exact) quadrature.

    Parameters
    ----------
    youngs_modulus : float
        E [Pa].
    poisson : float
        Poisson's ratio nu.
    density : float
        rho [kg/m^3].
    hx : float
        Element size along x [m].
    hy : float
        Element size along y [m].
    hz : float
        Element size along z [m].
    incompatible : bool
        With the Wilson-Taylor incompatible modes (condensed out); False gives the plain
        trilinear brick, which locks in bending.

    Returns
    -------
    stiffness : (24, 24) array [N/m]
    mass : (24, 24) array [kg]
    """
    e, nu = youngs_modulus, poisson
    lam, mu = e * nu / ((1 + nu) * (1 - 2 * nu)), e / (2 * (1 + nu))
    d = np.zeros((6, 6))
    d[:3, :3] = lam
    d[np.arange(3), np.arange(3)] = lam + 2 * mu
    d[np.arange(3, 6), np.arange(3, 6)] = mu
    scale = 2 / np.array([hx, hy, hz])                # d(natural) / d(physical)
    det = hx * hy * hz / 8
    n_in = 9 if incompatible else 0
    k = np.zeros((24 + n_in, 24 + n_in))
    ms = np.zeros((8, 8))
    for p in _GAUSS:
        f = 1 + _SIGNS * p                                # (8, 3) the factors of each N
        dn = np.column_stack([_SIGNS[:, a] * np.prod(np.delete(f, a, axis=1), axis=1)
                              for a in range(3)]) / 8     # (8, 3) d/d natural
        grads = [dn * scale]
        if incompatible:
            grads.append(np.diag(-2 * p * scale))     # bubble a: gradient along axis a only
        b = _strain(np.vstack(grads))
        k += det * b.T @ d @ b
        n = _shape(p[None])[0]
        ms += det * np.outer(n, n)
    if incompatible:
        k = k[:24, :24] - k[:24, 24:] @ np.linalg.solve(k[24:, 24:], k[24:, :24])
    return 0.5 * (k + k.T), density * np.kron(ms, np.eye(3))


def _element_nodes(nx: int, ny: int, i: np.ndarray, j: np.ndarray, k: np.ndarray) -> np.ndarray:
    """(n, 8) global nodes of elements (i, j, k) in local order."""
    return ((k[:, None] + _CORNERS[:, 2]) * (ny + 1) + j[:, None] + _CORNERS[:, 1]) * (nx + 1) \
        + i[:, None] + _CORNERS[:, 0]


def _dofs(nodes: np.ndarray) -> np.ndarray:
    """(n, 8) nodes -> (n, 24) DOFs in local order."""
    return (3 * nodes[:, :, None] + np.arange(3)).reshape(len(nodes), -1)


def solid_row(xs: np.ndarray, ys: np.ndarray, zs: np.ndarray,
              locations: ArrayLike) -> np.ndarray:
    """Rows mapping nodal DOFs to the displacement d . u(x) at locations.

    Parameters
    ----------
    xs : (nx + 1,) array [m]
        Node x coordinates, increasing.
    ys : (ny + 1,) array [m]
        Node y coordinates, increasing.
    zs : (nz + 1,) array [m]
        Node z coordinates, increasing.
    locations : (n, 6) or (6,) array
        Rows (x, y, z [m], dx, dy, dz), or one location; the directions are normalised. A
        point on an element face belongs to the element on its far side (the last element
        along an axis for the block's far face); points outside extrapolate.

    Returns
    -------
    (n, 3 * n_nodes) array [1]
        Row k maps the nodal DOFs to d_k . u(x_k); (n_dof,) for a single location.

    Raises
    ------
    ValueError
        Locations that are not rows of six numbers, or a zero measuring direction.
    """
    loc = np.asarray(locations, dtype=float)
    single = loc.ndim == 1
    loc = np.atleast_2d(loc)
    if loc.ndim != 2 or loc.shape[1] != 6:
        raise ValueError(f"locations must be (n, 6) (x, y, z, dx, dy, dz), got {loc.shape}")
    norm = np.linalg.norm(loc[:, 3:], axis=1)
    if np.any(~(norm > 0)):
        raise ValueError("a location has a zero (or non-finite) measuring direction")
    direction = loc[:, 3:] / norm[:, None]
    cell, local = [], []
    for axis, g in enumerate((xs, ys, zs)):
        e = np.clip(np.searchsorted(g, loc[:, axis], side="right") - 1, 0, len(g) - 2)
        cell.append(e)
        local.append(2 * (loc[:, axis] - g[e]) / (g[e + 1] - g[e]) - 1)
    n = _shape(np.column_stack(local))                               # (n, 8)
    dofs = _dofs(_element_nodes(len(xs) - 1, len(ys) - 1, *cell))
    rows = np.zeros((len(loc), 3 * len(xs) * len(ys) * len(zs)))
    np.put_along_axis(rows, dofs, (n[:, :, None] * direction[:, None, :]).reshape(len(loc), -1),
                      axis=1)
    return rows[0] if single else rows


@dataclass(frozen=True)
class SolidModel(ModalModel):
    """Assembled elastic block on point springs.

    Attributes
    ----------
    xs : (nx + 1,) array [m]
        Node x coordinates.
    ys : (ny + 1,) array [m]
        Node y coordinates.
    zs : (nz + 1,) array [m]
        Node z coordinates.
    stiffness : (n_dof, n_dof) array [N/m]
        The solid plus the gauge springs.
    mass : (n_dof, n_dof) array [kg]
        Consistent distributed mass plus lumped masses.
    damping : (n_dof, n_dof) array [N s/m]
        ``beta * stiffness``.
    bending_stiffness : (n_dof, n_dof) array [N/m]
        The solid alone (no springs): 6 rigid modes.
    springs : tuple of (x, y, z [m], dx, dy, dz, stiffness [N/m])
        The gauge springs, each along its direction.
    beta : float [s]
        Damping is ``beta * stiffness``.
    """

    dim: ClassVar[int] = 3

    xs: np.ndarray
    ys: np.ndarray
    zs: np.ndarray
    stiffness: np.ndarray
    mass: np.ndarray
    damping: np.ndarray
    bending_stiffness: np.ndarray
    springs: tuple[tuple[float, ...], ...] = field(default=())
    beta: float = 0.0

    @property
    def nodes(self) -> np.ndarray:
        """(n_nodes, 3) node coordinates [m] in the global node order."""
        gz, gy, gx = np.meshgrid(self.zs, self.ys, self.xs, indexing="ij")
        return np.column_stack([gx.ravel(), gy.ravel(), gz.ravel()])

    def row(self, locations: ArrayLike) -> np.ndarray:
        """Rows mapping DOFs to d . u at (n, 6) locations: (n, n_dof); see :func:`solid_row`."""
        return solid_row(self.xs, self.ys, self.zs, locations)

    def rigid_mode(self, translation: ArrayLike, rotation: ArrayLike,
                   origin: ArrayLike = (0.0, 0.0, 0.0)) -> np.ndarray:
        """Nodal vector of the rigid motion u(x) = t + theta x (x - origin) (exact here).

        Parameters
        ----------
        translation : (3,) array [m]
            t.
        rotation : (3,) array [rad]
            theta, the small-angle rotation vector.
        origin : (3,) array [m]
            The point the rotation is about.

        Returns
        -------
        (n_dof,) array [m]
            (u_x, u_y, u_z) of every node.
        """
        arm = self.nodes - np.asarray(origin, dtype=float)
        u = np.asarray(translation, dtype=float) + np.cross(np.asarray(rotation, float), arm)
        return u.ravel()


def _solid_matrices(xs: np.ndarray, ys: np.ndarray, zs: np.ndarray, youngs_modulus: float,
                    poisson: float, density: float,
                    incompatible: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness and consistent mass of the free block on the grid xs x ys x zs: each distinct
    element size is computed once and all elements are scattered in one pass."""
    sizes, inverse = zip(*(np.unique(np.diff(g), return_inverse=True) for g in (xs, ys, zs)),
                         strict=True)
    nx, ny, nz = (len(g) - 1 for g in (xs, ys, zs))
    k, j, i = (a.ravel() for a in np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx),
                                               indexing="ij"))
    group = (inverse[2][k] * len(sizes[1]) + inverse[1][j]) * len(sizes[0]) + inverse[0][i]
    elements = [hex8_element(youngs_modulus, poisson, density, hx, hy, hz, incompatible)
                for hz in sizes[2] for hy in sizes[1] for hx in sizes[0]]
    ke, me = (np.stack(m)[group].reshape(len(group), -1) for m in zip(*elements, strict=True))
    dofs = _dofs(_element_nodes(nx, ny, i, j, k))
    n_dof = 3 * len(xs) * len(ys) * len(zs)
    flat = (dofs[:, :, None] * n_dof + dofs[:, None, :]).ravel()
    kb, mm = (np.bincount(flat, weights=m.ravel(), minlength=n_dof**2).reshape(n_dof, n_dof)
              for m in (ke, me))
    return kb, mm


def assemble_solid(
    size: tuple[float, float, float],
    youngs_modulus: float,
    poisson: float,
    density: float,
    mesh: tuple[int, int, int] = (12, 10, 2),
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0),
    masses: tuple[tuple[float, float, float, float], ...] = (),
    springs: tuple[tuple[float, ...], ...] = (),
    beta: float = 0.0,
) -> SolidModel:
    """Assemble a free elastic block with lumped masses and point springs.

    Parameters
    ----------
    size : (a, b, c)
        Side lengths along x, y, z [m]; the block is origin + [0, a] x [0, b] x [0, c].
    youngs_modulus : float
        E [Pa].
    poisson : float
        Poisson's ratio nu.
    density : float
        rho [kg/m^3].
    mesh : (nx, ny, nz)
        Elements along x, y and z.
    origin : (x0, y0, z0)
        The block's lowest corner [m].
    masses : tuple of (x, y, z [m], m [kg])
        Point masses rigidly attached at a point: they add ``m (rx rx^T + ry ry^T + rz rz^T)``,
        r* the rows of the point along each axis.
    springs : tuple of (x, y, z [m], dx, dy, dz, k [N/m])
        Grounded springs acting along d at a point (the force gauges): they add ``k r r^T``,
        r the row of the location.
    beta : float
        Stiffness-proportional damping coefficient [s]: ``C = beta K``. In the solid it is
        internal (rigid motions are stress free: no net force or moment), on a gauge a dashpot
        inside the gauge whose force the gauge measures, as for the beam and the plate.

    Returns
    -------
    SolidModel
        The assembled matrices and the springs.

    Raises
    ------
    ValueError
        A mesh without an element along x, y or z.
    """
    counts = tuple(int(n) for n in mesh)
    if len(counts) != 3 or min(counts) < 1:
        raise ValueError(f"mesh {counts} needs at least one element along each of x, y, z")
    xs, ys, zs = (o + np.linspace(0.0, s, n + 1)
                  for o, s, n in zip(origin, size, counts, strict=True))
    kb, mm = _solid_matrices(xs, ys, zs, youngs_modulus, poisson, density)
    mm = _with_masses(mm, xs, ys, zs, masses)
    s = np.asarray(springs, dtype=float).reshape(-1, 7)
    kk = kb.copy()
    if len(s):
        r = solid_row(xs, ys, zs, s[:, :6])
        kk += (r.T * s[:, 6]) @ r
    return SolidModel(xs=xs, ys=ys, zs=zs, stiffness=kk, mass=mm, damping=beta * kk,
                      bending_stiffness=kb, springs=tuple(map(tuple, s.tolist())), beta=beta)


def _with_masses(mm: np.ndarray, xs: np.ndarray, ys: np.ndarray, zs: np.ndarray,
                 masses: tuple[tuple[float, float, float, float], ...]) -> np.ndarray:
    """The mass matrix [kg] with point masses (x, y, z [m], m [kg]) rigidly attached."""
    m = np.asarray(masses, dtype=float).reshape(-1, 4)
    if len(m):
        axes = np.tile(np.eye(3), (len(m), 1))
        r = solid_row(xs, ys, zs, np.column_stack([np.repeat(m[:, :3], 3, axis=0), axes]))
        mm = mm + (r.T * np.repeat(m[:, 3], 3)) @ r
    return mm


def clamped_dofs(model: SolidModel, x: float = 0.0) -> np.ndarray:
    """DOFs (all three components) of every node on the face x = x.

    Parameters
    ----------
    model : SolidModel
        The block.
    x : float
        The face's x coordinate [m].

    Returns
    -------
    (3 n_face_nodes,) int array
        The clamped DOFs.

    Raises
    ------
    ValueError
        No node lies on that face.
    """
    nodes = np.flatnonzero(np.isclose(model.nodes[:, 0], x, rtol=0.0,
                                      atol=1e-9 * np.ptp(model.xs)))
    if not len(nodes):
        raise ValueError(f"no node lies on the face x = {x}")
    return (3 * nodes[:, None] + np.arange(3)).ravel()
