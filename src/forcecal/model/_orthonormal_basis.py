"""The spatial basis itself: raw function families on the structure's extent, orthonormalized
on the scan points (the construction is described in :mod:`forcecal.model.basis`, which re-exports
the public names and fits shapes on the basis).

The raw functions are Legendre polynomials of the coordinates mapped affinely to [-1, 1] over
the extent (the black box), or the rigid motions plus the bending modes of the structure pinned
around its extent.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.polynomial import legendre
from numpy.typing import ArrayLike

from ..errors import ConditioningError, DataError, DimensionError

__all__ = ["FAMILIES", "n_functions"]

#: Smallest |R_ii| / max |R_ii| of the Vandermonde QR accepted as full rank.
_RANK_TOL = 1e-10

FAMILIES = ("legendre", "modes")
"""Raw function families: Legendre polynomials (the black box) or mode shapes."""


def n_functions(order: int, n_dim: int) -> int:
    """Number of basis functions of a given order (max total degree + 1) in 1-D, 2-D or 3-D.

    Parameters
    ----------
    order : int
        Max total degree + 1.
    n_dim : int
        Number of coordinates, 1, 2 or 3.

    Returns
    -------
    int
        p in 1-D, p (p + 1) / 2 in 2-D, p (p + 1) (p + 2) / 6 in 3-D for order p.

    Raises
    ------
    DimensionError
        ``n_dim`` is not 1, 2 or 3.
    """
    if n_dim == 1:
        return order
    if n_dim == 2:
        return order * (order + 1) // 2
    if n_dim == 3:
        return order * (order + 1) * (order + 2) // 6
    raise DimensionError(f"n_dim must be 1, 2 or 3; got {n_dim}")


def as_domain(extent: ArrayLike) -> np.ndarray:
    """(n_dim, 2) float array [m] of an extent; DimensionError or DataError when malformed."""
    dom = np.asarray(extent, dtype=float)
    if dom.shape == (2,):
        dom = dom[None, :]
    if dom.ndim != 2 or dom.shape[1] != 2 or dom.shape[0] not in (1, 2, 3):
        raise DimensionError(
            "extent must be (x_min, x_max) or ((x_min, x_max), (y_min, y_max)[, (z_min, z_max)])"
            f" [m]; got shape {dom.shape}"
        )
    if not np.all(np.isfinite(dom)) or np.any(dom[:, 1] <= dom[:, 0]):
        raise DataError(f"extent {dom.tolist()} must have finite bounds with min < max [m]")
    return dom


def as_points(points: ArrayLike, n_dim: int | None = None) -> np.ndarray:
    """(n_points, n_dim) float array [m] of finite points, of ``n_dim`` coordinates if given."""
    pts = np.asarray(points, dtype=float)
    if pts.ndim == 0:
        pts = pts.reshape(1, 1)
    elif pts.ndim == 1:
        pts = pts[:, None]
    if pts.ndim != 2 or pts.shape[1] not in (1, 2, 3):
        raise DimensionError(
            f"points must be (n_points,) or (n_points, n_dim) with n_dim 1, 2 or 3; "
            f"got shape {np.shape(points)}"
        )
    if n_dim is not None and pts.shape[1] != n_dim:
        raise DimensionError(f"points have {pts.shape[1]} coordinate(s); the basis is {n_dim}-D")
    if not np.all(np.isfinite(pts)):
        raise DataError("points contain non-finite coordinates")
    return pts


def legendre_vandermonde(points: ArrayLike, extent: ArrayLike, order: int) -> np.ndarray:
    """Legendre Vandermonde matrix on the extent mapped to [-1, 1].

    Parameters
    ----------
    points : (n_points,) or (n_points, n_dim) array [m]
        Where the polynomials are evaluated.
    extent : (x_min, x_max) or ((x_min, x_max), (y_min, y_max)[, (z_min, z_max)]) [m]
        The structure's extent, mapped to [-1, 1].
    order : int
        Max total degree + 1.

    Returns
    -------
    (n_points, n_functions(order, n_dim)) array [1]
        1-D: P_0(u) .. P_{order-1}(u). 2-D: P_i(u) P_j(v) by total degree d = i + j, and
        within a degree by decreasing i. 3-D: P_i(u) P_j(v) P_k(w) by total degree, then by
        decreasing i, then decreasing j.

    Raises
    ------
    DimensionError
        Malformed points or extent, or an order below 1.
    DataError
        Non-finite points or an empty extent.
    """
    dom = as_domain(extent)
    pts = as_points(points, dom.shape[0])
    if order < 1:
        raise DimensionError(f"order must be >= 1; got {order}")
    u = 2.0 * (pts - dom[:, 0]) / (dom[:, 1] - dom[:, 0]) - 1.0
    if dom.shape[0] == 1:
        return legendre.legvander(u[:, 0], order - 1)
    pu = legendre.legvander(u[:, 0], order - 1)
    pv = legendre.legvander(u[:, 1], order - 1)
    if dom.shape[0] == 2:
        cols = [pu[:, d - j] * pv[:, j] for d in range(order) for j in range(d + 1)]
    else:
        pw = legendre.legvander(u[:, 2], order - 1)
        cols = [pu[:, i] * pv[:, j] * pw[:, d - i - j]
                for d in range(order) for i in range(d, -1, -1) for j in range(d - i, -1, -1)]
    return np.stack(cols, axis=1)


def modal_functions(points: ArrayLike, extent: ArrayLike, order: int) -> np.ndarray:
    """Rigid motions plus the bending modes of the structure pinned around its extent.

    1-D: 1, u, sin(k pi xi) for k = 1 .. order - 2 (xi in [0, 1] over the extent): the modes of a
    uniform beam pinned at both ends of the extent (exact for a uniform beam on gauges at its
    ends; an approximation with lumped masses or inner gauges, as every modal basis is).
    2-D: 1, u, v, then sin(k pi xi) sin(l pi eta) in the order of the simply supported plate's
    frequencies (k/a)^2 + (l/b)^2. Counts match :func:`n_functions`, and lower orders are the
    leading columns, as for the polynomials.

    Parameters
    ----------
    points : (n_points,) or (n_points, n_dim) array [m]
        Where the functions are evaluated, n_dim 1 or 2.
    extent : (x_min, x_max) or ((x_min, x_max), (y_min, y_max)) [m]
        The structure's extent.
    order : int
        Max total degree + 1 of the polynomials whose count the functions match.

    Returns
    -------
    (n_points, n_functions(order, n_dim)) array [1]
        The functions, rigid motions first.

    Raises
    ------
    DimensionError
        Malformed points or extent, an order below 1, or a 3-D extent.
    """
    dom = as_domain(extent)
    pts = as_points(points, dom.shape[0])
    if order < 1:
        raise DimensionError(f"order must be >= 1; got {order}")
    if dom.shape[0] == 3:
        raise DimensionError("the mode-shape basis serves beams and plates; a body's shapes "
                             "use the polynomials")
    xi = (pts - dom[:, 0]) / (dom[:, 1] - dom[:, 0])
    n_dim = dom.shape[0]
    total = n_functions(order, n_dim)
    cols = [np.ones(len(pts))] + [2 * xi[:, d] - 1 for d in range(n_dim)]
    if n_dim == 1:
        cols += [np.sin(k * np.pi * xi[:, 0]) for k in range(1, total)]
    else:
        size = dom[:, 1] - dom[:, 0]
        kl = sorted(((k, l) for k in range(1, total + 1) for l in range(1, total + 1)),
                    key=lambda p: ((p[0] / size[0]) ** 2 + (p[1] / size[1]) ** 2, p))
        cols += [np.sin(k * np.pi * xi[:, 0]) * np.sin(l * np.pi * xi[:, 1]) for k, l in kl]
    return np.stack(cols[:total], axis=1)


def raw_functions(points: ArrayLike, extent: ArrayLike, order: int,
                  family: str = "legendre") -> np.ndarray:
    """The raw functions of a family before orthonormalization (see :data:`FAMILIES`).

    Parameters
    ----------
    points : (n_points,) or (n_points, n_dim) array [m]
        Where the functions are evaluated.
    extent : (x_min, x_max) or ((x_min, x_max), (y_min, y_max)[, (z_min, z_max)]) [m]
        The structure's extent.
    order : int
        Max total degree + 1.
    family : {"legendre", "modes"}
        :func:`legendre_vandermonde` or :func:`modal_functions`.

    Returns
    -------
    (n_points, n_functions(order, n_dim)) array [1]
        The raw functions at the points.

    Raises
    ------
    DimensionError
        An unknown family, or what the family's function raises.
    """
    if family not in FAMILIES:
        raise DimensionError(f"basis family '{family}' is unknown (choose from "
                             f"{', '.join(FAMILIES)})")
    pts = np.ascontiguousarray(points, dtype=float)
    dom = np.ascontiguousarray(extent, dtype=float)
    n_dim = 1 if dom.ndim == 1 else dom.shape[0]
    if dom.ndim > 2 or order < 1 or pts.shape[0] * n_functions(order, n_dim) > CACHED_VALUES:
        return _raw(pts, extent, order, family)
    return _remembered(pts.tobytes(), pts.shape, dom.tobytes(), dom.shape, int(order), family)


CACHED_VALUES = 1 << 16
"""Raw functions of at most this many values (points x functions; 512 kB) are kept
(:func:`_remembered`, 64 of them): the quadrature nodes, probes and gauges at which every
shape of a model, every harmonic and every type-B move evaluates its basis again (a
calibration evaluated one set 20 000 times)."""


@lru_cache(maxsize=64)
def _remembered(points: bytes, shape: tuple[int, ...], extent: bytes,
                extent_shape: tuple[int, ...], order: int, family: str) -> np.ndarray:
    """:func:`_raw` of points and an extent given by their bytes, read-only."""
    out = _raw(np.frombuffer(points).reshape(shape), np.frombuffer(extent).reshape(extent_shape),
               order, family)
    out.flags.writeable = False
    return out


def _raw(points: np.ndarray, extent: ArrayLike, order: int, family: str) -> np.ndarray:
    if family == "legendre":
        return legendre_vandermonde(points, extent, order)
    return modal_functions(points, extent, order)


@dataclass(frozen=True)
class PolynomialBasis:
    """Polynomials orthonormal on a set of scan points, evaluable anywhere.

    Attributes
    ----------
    order : int
        Max total degree + 1 (see :mod:`forcecal.model.basis`).
    domain : (n_dim, 2) array [m]
        Extent mapped to [-1, 1]: [[x_min, x_max]] or [[x_min, x_max], [y_min, y_max]].
    coefficients : (n_funcs, n_funcs) upper-triangular array [1]
        R^-1: column r holds the Legendre coefficients of beta_r, so that
        beta(x) = legendre_vandermonde(x)[:, columns] @ coefficients.
    family : {"legendre", "modes"}
        The raw functions (see :func:`raw_functions`).
    columns : (n_funcs,) int array or None
        The raw functions kept (None: all). In 3-D, points on a body's faces cannot tell some
        polynomials apart (a product of the faces' equations vanishes on all of them); such a
        function adds nothing the earlier ones do not already give at the points, and is left
        out, so the interior takes the least varying extension (within a degree the
        functions varying least along z come first).
    """

    order: int
    domain: np.ndarray
    coefficients: np.ndarray
    family: str = "legendre"
    columns: np.ndarray | None = None

    @property
    def n_dim(self) -> int:
        """Number of coordinates, 1, 2 or 3."""
        return self.domain.shape[0]

    @property
    def n_funcs(self) -> int:
        """Number of basis functions."""
        return self.coefficients.shape[1]

    def evaluate(self, points: np.ndarray) -> np.ndarray:
        """Basis functions at arbitrary points.

        Parameters
        ----------
        points : (n_points,) or (n_points, n_dim) array [m]
            Where to evaluate them (anywhere, not only at the scan points).

        Returns
        -------
        (n_points, n_funcs) array [1]
            beta_r(x_k) in row k, column r.
        """
        raw = raw_functions(points, self.domain, self.order, self.family)
        if self.columns is not None:
            raw = raw[:, self.columns]
        return raw @ self.coefficients

    def functions_up_to(self, order: int) -> int:
        """How many of the basis functions have an order up to ``order`` (max degree + 1)."""
        n = n_functions(order, self.n_dim)
        return n if self.columns is None else int(np.count_nonzero(self.columns < n))

    def truncate(self, order: int) -> PolynomialBasis:
        """The nested basis of a lower order (its leading functions).

        Parameters
        ----------
        order : int
            The lower order, 1 .. ``self.order``.

        Returns
        -------
        PolynomialBasis
            The leading :meth:`functions_up_to` ``order`` functions.

        Raises
        ------
        DimensionError
            ``order`` outside 1 .. ``self.order``.
        """
        if not 1 <= order <= self.order:
            raise DimensionError(f"order must be in 1..{self.order}; got {order}")
        n = self.functions_up_to(order)
        cols = None if self.columns is None else self.columns[:n].copy()
        return PolynomialBasis(order, self.domain, self.coefficients[:n, :n].copy(), self.family,
                               cols)


def as_weights(weights: ArrayLike | None, n_points: int) -> np.ndarray:
    """(n_points,) positive finite weights, ones when ``weights`` is None."""
    if weights is None:
        return np.ones(n_points)
    w = np.asarray(weights, dtype=float)
    if w.shape != (n_points,):
        raise DimensionError(f"weights must be ({n_points},); got shape {w.shape}")
    if not np.all(np.isfinite(w)) or np.any(w <= 0):
        raise DataError("weights must be finite and positive")
    return w


def _check_inside(pts: np.ndarray, dom: np.ndarray) -> None:
    """DataError naming the first of the points (n, n_dim) [m] outside the extent [m]."""
    tol = 1e-9 * (dom[:, 1] - dom[:, 0])
    outside = np.any((pts < dom[:, 0] - tol) | (pts > dom[:, 1] + tol), axis=1)
    if outside.any():
        k = int(np.argmax(outside))
        raise DataError(
            f"{int(outside.sum())} scan point(s) lie outside the extent {dom.tolist()} [m], "
            f"first point {k} at {pts[k].tolist()}; check the units of the points and extent"
        )


def _inverse_triangular(r: np.ndarray) -> np.ndarray:
    """R^-1 of an upper-triangular R."""
    from scipy.linalg import solve_triangular  # on use: `import forcecal` stays light

    return solve_triangular(r, np.eye(r.shape[0]))


def orthonormal_basis(
    points: np.ndarray, extent: ArrayLike, order: int, weights: np.ndarray | None = None,
    family: str = "legendre",
) -> PolynomialBasis:
    """Polynomial basis orthonormal on the scan points.

    Parameters
    ----------
    points : (n_points,) or (n_points, n_dim) array [m]
        Scan points, inside the extent.
    extent : (x_min, x_max) or ((x_min, x_max), (y_min, y_max)[, (z_min, z_max)]) [m]
        The structure's extent (e.g. (0, L) for a beam), mapped to [-1, 1].
    order : int
        Max total degree + 1.
    weights : (n_points,) array, optional
        Positive weights of the inner product (default 1).
    family : {"legendre", "modes"}
        The raw functions (see :func:`raw_functions`).

    Returns
    -------
    PolynomialBasis
        B = basis.evaluate(points) satisfies B^T diag(weights) B = I.

    Raises
    ------
    ConditioningError
        The points cannot support that many functions (too few or degenerate points).
    DataError
        A point outside the extent, or weights that are not finite and positive.
    """
    dom = as_domain(extent)
    pts = as_points(points, dom.shape[0])
    _check_inside(pts, dom)
    n_funcs = n_functions(order, dom.shape[0])
    if n_funcs > pts.shape[0] and dom.shape[0] < 3:       # 3-D: counted after deflation
        raise ConditioningError(
            f"a basis of order {order} has {n_funcs} functions; {pts.shape[0]} points cannot "
            "support it"
        )
    sw = np.sqrt(as_weights(weights, pts.shape[0]))[:, None]
    v = sw * raw_functions(pts, dom, order, family)
    columns = None
    if dom.shape[0] == 3:
        columns = _distinguishable(v)
        v = v[:, columns]
    r_inv = _orthonormalizing_factor(v, order, n_funcs)
    return PolynomialBasis(order=int(order), domain=dom, coefficients=np.triu(r_inv),
                           family=family, columns=columns)


def _orthonormalizing_factor(v: np.ndarray, order: int, n_funcs: int) -> np.ndarray:
    """R^-1 such that v R^-1 has orthonormal columns, for the weighted raw functions v (n, P).

    QR twice ("twice is enough"): the second pass makes v R^-1 orthonormal to rounding. Sign
    convention: positive diagonal of R (beta_0 is a positive constant). ConditioningError
    when v is numerically rank deficient.
    """
    _, r1 = np.linalg.qr(v)
    d = np.abs(np.diag(r1))
    if d.min() <= _RANK_TOL * d.max():
        raise ConditioningError(
            f"the {v.shape[0]} scan points cannot support a basis of order {order} "
            f"({n_funcs} functions): the Vandermonde matrix is numerically rank deficient "
            f"(|R_ii| ratio {d.min() / d.max():.1e}); lower the order or add points"
        )
    r1_inv = _inverse_triangular(r1)
    _, r2 = np.linalg.qr(v @ r1_inv)
    r_inv = r1_inv @ _inverse_triangular(r2)
    return r_inv * np.sign(np.diag(r_inv))


_NEW_TOL = 1e-4
"""Smallest part of a unit-norm column, orthogonal to the kept ones, that counts as new."""


def _distinguishable(v: np.ndarray) -> np.ndarray:
    """Indices of the columns of v that are not (numerically) combinations of earlier ones.

    Columns are scaled to unit norm, then Gram-Schmidt in their own order measures what each
    adds to the kept ones: less than ``_NEW_TOL`` means nothing new.
    """
    norms = np.linalg.norm(v, axis=0)
    keep = norms > 0
    vn = v / np.where(keep, norms, 1.0)
    kept: list[int] = []
    q = np.zeros((v.shape[0], 0))
    for j in np.flatnonzero(keep):
        c = vn[:, j] - q @ (q.T @ vn[:, j])
        c = c - q @ (q.T @ c)                               # twice is enough
        size = float(np.linalg.norm(c))
        if size > _NEW_TOL:
            q = np.column_stack([q, c / size])
            kept.append(int(j))
    return np.array(kept, dtype=int)
