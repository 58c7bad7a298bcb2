"""Mass coupling of relaxation shapes and deflection shapes (METHOD.md eq. 6).

m_r[phi] = integral(rho psi_r phi) + sum_k m_k psi_r(x_k) phi(x_k), by Gauss-Legendre
quadrature along a beam, over a plate's outline cut into triangles (each integrated by a
collapsed Gauss rule), or through a body's blocks (a tensor Gauss rule), exact for the
polynomial shapes of :mod:`forcecal.basis` up to the quadrature's degree, plus the lumped
masses. On a body both psi_r and phi are vector fields: the product is their dot product, so
every quadrature point enters three times, once per axis, as a location (x, e_x), (x, e_y),
(x, e_z).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .relaxation import relaxation_shapes
from .rig import Rig

__all__ = ["block_quadrature", "mass_coupling", "mass_weights", "polygon_quadrature",
           "triangulate"]

_N_QUAD = 64
_N_TRI = 12
_N_BLOCK = 12


def mass_weights(rig: Rig, n_quad: int = _N_QUAD) -> tuple[np.ndarray, np.ndarray]:
    """Points and mass-weighted relaxation shapes that turn any shape into its couplings.

    Returns
    -------
    points : (n_q,) or (n_q, 2) array [m], quadrature nodes then the lumped masses' positions;
        on a body (n_q, 6) locations, each node and mass along x, y and z
    weights : (n_gauges, n_q) array [kg]: m_r[phi] = weights[r] @ phi(points)
    """
    st = rig.structure
    mm = np.array([m.mass for m in st.masses])
    if st.kind == "body":
        qp, qw = block_quadrature(st.blocks, _N_BLOCK)
        pts = np.vstack([qp, np.array([[m.x, m.y, m.z] for m in st.masses]).reshape(-1, 3)])
        w = np.concatenate([qw * st.density, mm])
        locs = np.vstack([np.column_stack([pts, np.tile(e, (len(pts), 1))]) for e in np.eye(3)])
        return locs, relaxation_shapes(rig, locs) * np.tile(w, 3)[None, :]
    if st.kind == "beam":
        xi, wi = np.polynomial.legendre.leggauss(n_quad)
        x = 0.5 * st.length * (xi + 1.0)
        w = 0.5 * st.length * wi * st.mass_per_length
        pts = np.concatenate([x, [m.x for m in st.masses]])
        weights = relaxation_shapes(rig, pts) * np.concatenate([w, mm])[None, :]
        return pts, weights
    qp, qw = polygon_quadrature(np.asarray(st.outline, dtype=float), _N_TRI)
    pts = np.vstack([qp, np.array([[m.x, m.y] for m in st.masses]).reshape(-1, 2)])
    weights = relaxation_shapes(rig, pts) * np.concatenate([qw * st.mass_per_area, mm])[None, :]
    return pts, weights


def triangulate(polygon: np.ndarray) -> np.ndarray:
    """Ear-clipping triangulation of a simple polygon.

    Parameters
    ----------
    polygon : (n_vertices, 2) array [m], either orientation

    Returns
    -------
    (n_vertices - 2, 3, 2) array of triangles [m]
    """
    v = [tuple(p) for p in np.asarray(polygon, dtype=float)]
    x, y = np.array(v).T
    if 0.5 * (np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))) < 0:
        v = v[::-1]                                            # counter-clockwise

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    def inside(p, a, b, c):
        return cross(a, b, p) >= 0 and cross(b, c, p) >= 0 and cross(c, a, p) >= 0

    triangles = []
    while len(v) > 3:
        for i in range(len(v)):
            a, b, c = v[i - 1], v[i], v[(i + 1) % len(v)]
            if cross(a, b, c) <= 0:
                continue                                        # reflex corner
            if any(inside(p, a, b, c) for p in v if p not in (a, b, c)):
                continue
            triangles.append((a, b, c))
            del v[i]
            break
        else:
            raise ValueError("the outline is not a simple polygon")
    triangles.append(tuple(v))
    return np.array(triangles)


def polygon_quadrature(polygon: np.ndarray, n: int = _N_TRI) -> tuple[np.ndarray, np.ndarray]:
    """Points and weights integrating over a polygon (exact for degree <= 2 n - 2).

    Each triangle of :func:`triangulate` is mapped from the unit square by the collapsed
    (Duffy) map, with an n x n Gauss-Legendre rule.

    Returns
    -------
    points : (n_q, 2) [m]; weights : (n_q,) [m^2]
    """
    g, w = np.polynomial.legendre.leggauss(n)
    g = 0.5 * (g + 1.0)
    w = 0.5 * w
    uu, vv = np.meshgrid(g, g, indexing="ij")
    ww = np.outer(w, w)
    # unit triangle (0,0), (1,0), (0,1): s = u, t = v (1 - u), Jacobian (1 - u)
    s = uu.ravel()
    t = (vv * (1 - uu)).ravel()
    jw = (ww * (1 - uu)).ravel()
    pts, wts = [], []
    for a, b, c in triangulate(polygon):
        e1, e2 = b - a, c - a
        area2 = abs(e1[0] * e2[1] - e1[1] * e2[0])
        pts.append(a + np.outer(s, e1) + np.outer(t, e2))
        wts.append(jw * area2)
    return np.vstack(pts), np.concatenate(wts)


def block_quadrature(blocks, n: int = _N_BLOCK) -> tuple[np.ndarray, np.ndarray]:
    """Points and weights integrating over a union of axis-aligned boxes (an n x n x n
    Gauss-Legendre rule in each, exact for degree <= 2 n - 1 along each axis).

    Parameters
    ----------
    blocks : ((x0, y0, z0), (x1, y1, z1)) corners of each box [m]

    Returns
    -------
    points : (n_q, 3) [m]; weights : (n_q,) [m^3]
    """
    g, w = np.polynomial.legendre.leggauss(n)
    g, w = 0.5 * (g + 1.0), 0.5 * w
    pts, wts = [], []
    for lo, hi in blocks:
        lo, size = np.asarray(lo, dtype=float), np.subtract(hi, lo)
        axes = [lo[a] + size[a] * g for a in range(3)]
        pts.append(np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3))
        wts.append(np.einsum("i,j,k->ijk", w, w, w).ravel() * float(np.prod(size)))
    return np.vstack(pts), np.concatenate(wts)


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
