"""Smooth spatial shapes fitted over scan points (METHOD.md section 3, step 2).

A shape phi(x) over the structure is expanded on polynomials beta_r that are orthonormal on the
scan points in the discrete (optionally weighted) inner product

    <f, g> = sum_k w_k f(x_k) g(x_k),          so that   B^T W B = I,

with B[k, r] = beta_r(x_k). They are built from the Legendre Vandermonde matrix V of the
coordinates mapped affinely to [-1, 1] over the structure's extent (not the range of the
scan points) and the triangular factor of its QR factorization, sqrt(W) V = Q R:

    beta(x) = V(x) R^-1,

which can be evaluated anywhere (sensors, gauges, quadrature nodes), not only at the scan
points. In 2-D the Vandermonde holds the products P_i(u) P_j(v) of total degree i + j < order,
ordered by total degree, so the basis of a lower order is always the leading columns of a
higher one.

``order`` counts polynomial degrees: order p holds every polynomial of (total) degree below p,
that is p functions in 1-D and p (p + 1) / 2 in 2-D. Order 1 is the constant (rigid
translation), order 2 adds the rigid rotations.

Complex shapes (harmonic phasors) are fitted with Re and Im sharing the same order, since they
describe one physical shape; the order is chosen by generalized cross-validation or BIC.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.polynomial import legendre
from scipy.linalg import solve_triangular

from .errors import ConditioningError, DataError, DimensionError

__all__ = [
    "PolynomialBasis",
    "ShapeFit",
    "fit_shape",
    "legendre_vandermonde",
    "modal_functions",
    "n_functions",
    "orthonormal_basis",
    "project",
    "raw_functions",
    "shape_similarity",
]

#: Smallest |R_ii| / max |R_ii| of the Vandermonde QR accepted as full rank.
_RANK_TOL = 1e-10
#: Default cap on the order tried by :func:`fit_shape`.
_MAX_ORDER = 20
#: In 3-D, the order tried before the faces' distinguishable functions are counted.
_MAX_ORDER_3D = 12


def n_functions(order: int, n_dim: int) -> int:
    """Number of basis functions of a given order (max total degree + 1) in 1-D, 2-D or 3-D."""
    if n_dim == 1:
        return order
    if n_dim == 2:
        return order * (order + 1) // 2
    if n_dim == 3:
        return order * (order + 1) * (order + 2) // 6
    raise DimensionError(f"n_dim must be 1, 2 or 3; got {n_dim}")


def _as_domain(extent: object) -> np.ndarray:
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


def _as_points(points: object, n_dim: int | None = None) -> np.ndarray:
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


def legendre_vandermonde(points: np.ndarray, extent: object, order: int) -> np.ndarray:
    """Legendre Vandermonde matrix on the extent mapped to [-1, 1].

    Parameters
    ----------
    points : (n_points,) or (n_points, n_dim) array [m]
    extent : (x_min, x_max) or ((x_min, x_max), (y_min, y_max)) [m]
    order : int
        Max total degree + 1.

    Returns
    -------
    (n_points, n_functions(order, n_dim)) array [1]
        1-D: P_0(u) .. P_{order-1}(u). 2-D: P_i(u) P_j(v) by total degree d = i + j, and
        within a degree by decreasing i. 3-D: P_i(u) P_j(v) P_k(w) by total degree, then by
        decreasing i, then decreasing j.
    """
    dom = _as_domain(extent)
    pts = _as_points(points, dom.shape[0])
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


FAMILIES = ("legendre", "modes")
"""Raw function families: Legendre polynomials (the black box) or mode shapes."""


def modal_functions(points: np.ndarray, extent: object, order: int) -> np.ndarray:
    """Rigid motions plus the bending modes of the structure pinned around its extent.

    1-D: 1, u, sin(k pi xi) for k = 1 .. order - 2 (xi in [0, 1] over the extent): the modes of a
    uniform beam pinned at both ends of the extent (exact for a uniform beam on gauges at its
    ends; an approximation with lumped masses or inner gauges, as every modal basis is).
    2-D: 1, u, v, then sin(k pi xi) sin(l pi eta) in the order of the simply supported plate's
    frequencies (k/a)^2 + (l/b)^2. Counts match :func:`n_functions`, and lower orders are the
    leading columns, as for the polynomials.

    Returns
    -------
    (n_points, n_functions(order, n_dim)) array [1]
    """
    dom = _as_domain(extent)
    pts = _as_points(points, dom.shape[0])
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


def raw_functions(points: np.ndarray, extent: object, order: int,
                  family: str = "legendre") -> np.ndarray:
    """The raw functions of a family before orthonormalization (see :data:`FAMILIES`)."""
    if family == "legendre":
        return legendre_vandermonde(points, extent, order)
    if family == "modes":
        return modal_functions(points, extent, order)
    raise DimensionError(f"basis family '{family}' is unknown (choose from {', '.join(FAMILIES)})")


@dataclass(frozen=True)
class PolynomialBasis:
    """Polynomials orthonormal on a set of scan points, evaluable anywhere.

    Attributes
    ----------
    order : int
        Max total degree + 1 (see the module docstring).
    domain : (n_dim, 2) array [m]
        Extent mapped to [-1, 1]: [[x_min, x_max]] or [[x_min, x_max], [y_min, y_max]].
    coefficients : (n_funcs, n_funcs) upper-triangular array [1]
        R^-1: column r holds the Legendre coefficients of beta_r, so that
        beta(x) = legendre_vandermonde(x)[:, columns] @ coefficients.
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
        """Number of coordinates, 1 or 2."""
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

        Returns
        -------
        (n_points, n_funcs) array [1]
        """
        raw = raw_functions(points, self.domain, self.order, self.family)
        if self.columns is not None:
            raw = raw[:, self.columns]
        return raw @ self.coefficients

    def functions_up_to(self, order: int) -> int:
        """How many of the basis functions have an order up to ``order``."""
        n = n_functions(order, self.n_dim)
        return n if self.columns is None else int(np.count_nonzero(self.columns < n))

    def truncate(self, order: int) -> PolynomialBasis:
        """The nested basis of a lower order (its leading functions)."""
        if not 1 <= order <= self.order:
            raise DimensionError(f"order must be in 1..{self.order}; got {order}")
        n = self.functions_up_to(order)
        cols = None if self.columns is None else self.columns[:n].copy()
        return PolynomialBasis(order, self.domain, self.coefficients[:n, :n].copy(), self.family,
                               cols)


def _as_weights(weights: object, n_points: int) -> np.ndarray:
    if weights is None:
        return np.ones(n_points)
    w = np.asarray(weights, dtype=float)
    if w.shape != (n_points,):
        raise DimensionError(f"weights must be ({n_points},); got shape {w.shape}")
    if not np.all(np.isfinite(w)) or np.any(w <= 0):
        raise DataError("weights must be finite and positive")
    return w


def _check_inside(pts: np.ndarray, dom: np.ndarray) -> None:
    tol = 1e-9 * (dom[:, 1] - dom[:, 0])
    outside = np.any((pts < dom[:, 0] - tol) | (pts > dom[:, 1] + tol), axis=1)
    if outside.any():
        k = int(np.argmax(outside))
        raise DataError(
            f"{int(outside.sum())} scan point(s) lie outside the extent {dom.tolist()} [m], "
            f"first point {k} at {pts[k].tolist()}; check the units of the points and extent"
        )


def _inverse_triangular(r: np.ndarray) -> np.ndarray:
    return solve_triangular(r, np.eye(r.shape[0]))


def orthonormal_basis(
    points: np.ndarray, extent: object, order: int, weights: np.ndarray | None = None,
    family: str = "legendre",
) -> PolynomialBasis:
    """Polynomial basis orthonormal on the scan points.

    Parameters
    ----------
    points : (n_points,) or (n_points, n_dim) array [m]
        Scan points, inside the extent.
    extent : (x_min, x_max) or ((x_min, x_max), (y_min, y_max)) [m]
        The structure's extent (e.g. (0, L) for a beam), mapped to [-1, 1].
    order : int
        Max total degree + 1.
    weights : (n_points,) array, optional
        Positive weights of the inner product (default 1).

    Returns
    -------
    PolynomialBasis
        B = basis.evaluate(points) satisfies B^T diag(weights) B = I.

    Raises
    ------
    ConditioningError
        The points cannot support that many functions (too few or degenerate points).
    """
    dom = _as_domain(extent)
    pts = _as_points(points, dom.shape[0])
    _check_inside(pts, dom)
    n_funcs = n_functions(order, dom.shape[0])
    if n_funcs > pts.shape[0] and dom.shape[0] < 3:       # 3-D: counted after deflation
        raise ConditioningError(
            f"a basis of order {order} has {n_funcs} functions; {pts.shape[0]} points cannot "
            "support it"
        )
    sw = np.sqrt(_as_weights(weights, pts.shape[0]))[:, None]
    v = sw * raw_functions(pts, dom, order, family)
    columns = None
    if dom.shape[0] == 3:
        columns = _distinguishable(v)
        v = v[:, columns]
    # QR twice ("twice is enough"): the second pass makes V R^-1 orthonormal to rounding
    _, r1 = np.linalg.qr(v)
    d = np.abs(np.diag(r1))
    if d.min() <= _RANK_TOL * d.max():
        raise ConditioningError(
            f"the {pts.shape[0]} scan points cannot support a basis of order {order} "
            f"({n_funcs} functions): the Vandermonde matrix is numerically rank deficient "
            f"(|R_ii| ratio {d.min() / d.max():.1e}); lower the order or add points"
        )
    r1_inv = _inverse_triangular(r1)
    _, r2 = np.linalg.qr(v @ r1_inv)
    r_inv = r1_inv @ _inverse_triangular(r2)
    # unique sign convention: positive diagonal of R (beta_0 is a positive constant)
    r_inv = r_inv * np.sign(np.diag(r_inv))
    return PolynomialBasis(order=int(order), domain=dom, coefficients=np.triu(r_inv),
                           family=family, columns=columns)


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


@dataclass(frozen=True)
class ShapeFit:
    """A shape fitted over the scan points on an orthonormal polynomial basis.

    Attributes
    ----------
    basis : PolynomialBasis
        The basis of the chosen order.
    coefficients : (n_funcs,) or (n_funcs, k) array [unit of the values]
        Expansion coefficients p_r, complex when the values are complex.
    order : int
        The chosen order (max total degree + 1).
    orders : (n_orders,) int array
        The orders tried.
    score : (n_orders,) array
        The selection criterion for every order tried (smaller is better).
    criterion : str
        "gcv", "bic" or "fixed".
    residual_std : float [unit of the values]
        Standard deviation of a residual of unit weight, pooled over Re, Im and all columns:
        sqrt(RSS_w / (m (n_points - n_funcs))) for m real columns.
    coefficient_covariance : (n_funcs, n_funcs) array [unit of the values ^2]
        sigma^2 (B^T W B)^-1: the covariance of the real part of each column of coefficients,
        and equally of the imaginary part.
    """

    basis: PolynomialBasis
    coefficients: np.ndarray
    order: int
    orders: np.ndarray
    score: np.ndarray
    criterion: str
    residual_std: float
    coefficient_covariance: np.ndarray

    def evaluate(self, points: np.ndarray) -> np.ndarray:
        """Fitted shape at arbitrary points.

        Parameters
        ----------
        points : (n_points,) or (n_points, n_dim) array [m]

        Returns
        -------
        (n_points,) or (n_points, k) array [unit of the values]
        """
        return self.basis.evaluate(points) @ self.coefficients

    def std(self, points: np.ndarray) -> np.ndarray:
        """Standard uncertainty of Re (and of Im) of the fitted shape at points.

        Parameters
        ----------
        points : (n_points,) or (n_points, n_dim) array [m]

        Returns
        -------
        (n_points,) array [unit of the values]
        """
        b = self.basis.evaluate(points)
        return np.sqrt(np.einsum("kr,rs,ks->k", b, self.coefficient_covariance, b))


def _real_columns(values: np.ndarray) -> np.ndarray:
    """(n, k) real or complex -> (n, m) real: Re columns, then Im columns if complex."""
    if np.iscomplexobj(values):
        return np.concatenate([values.real, values.imag], axis=1)
    return values


def _default_max_order(n_points: int, n_dim: int) -> int:
    order = 1
    while order < _MAX_ORDER and n_functions(order + 1, n_dim) <= n_points // 3:
        order += 1
    return order


def fit_shape(
    points: np.ndarray,
    values: np.ndarray,
    extent: object,
    max_order: int | None = None,
    criterion: str = "gcv",
    weights: np.ndarray | None = None,
    order: int | None = None,
    family: str = "legendre",
) -> ShapeFit:
    """Fit a smooth shape over scan points, choosing the order from the data.

    Every order p = 1 .. max_order is fitted by weighted least squares on the orthonormal basis
    (nested, so one basis of the largest order serves all). Re and Im, and all columns of a
    stack, share the order. With n points, p functions, m real columns and weighted residual
    sum of squares RSS:

    - GCV(p) = (RSS / (n m)) / (1 - p / n)^2 (generalized cross-validation of a linear
      smoother of trace p);
    - BIC(p) = n m ln(RSS / (n m)) + p m ln(n m).

    RSS below the rounding level of the data is treated as that level, so that data an order
    represents exactly select that order, not a higher one.

    Parameters
    ----------
    points : (n_points,) or (n_points, n_dim) array [m]
        Scan points.
    values : (n_points,) or (n_points, k) array, real or complex [any unit]
        Shape values at the points (e.g. harmonic phasors H_n(x_k)).
    extent : (x_min, x_max) or ((x_min, x_max), (y_min, y_max)) [m]
        The structure's extent, mapped to [-1, 1].
    max_order : int, optional
        Largest order tried. Default: the largest order with at most n_points // 3 functions,
        capped at 20.
    criterion : {"gcv", "bic"}
    weights : (n_points,) array, optional
        Positive weights (inverse variances up to a common factor).
    order : int, optional
        Use this order instead of selecting one (``criterion`` becomes "fixed").
    family : {"legendre", "modes"}
        The raw functions (see :func:`raw_functions`).

    Returns
    -------
    ShapeFit

    Raises
    ------
    DataError
        Non-finite values, or an order that leaves no residual degree of freedom.
    DimensionError
        Values and points that do not agree.
    """
    if criterion not in ("gcv", "bic"):
        raise DataError(f"criterion must be 'gcv' or 'bic'; got '{criterion}'")
    dom = _as_domain(extent)
    n_dim = dom.shape[0]
    pts = _as_points(points, n_dim)
    n = pts.shape[0]
    vals = np.asarray(values)
    if vals.ndim not in (1, 2) or vals.shape[0] != n:
        raise DimensionError(
            f"values must be ({n},) or ({n}, k) for {n} points; got shape {vals.shape}"
        )
    if not np.all(np.isfinite(vals)):
        raise DataError(f"values contain {int((~np.isfinite(vals)).sum())} non-finite entries")
    is_complex = np.iscomplexobj(vals)
    vals = vals.astype(complex if is_complex else float)
    y = _real_columns(vals.reshape(n, -1))
    # columns identically zero (e.g. the Im part of a real shape) carry no observation
    y = y[:, np.any(y != 0.0, axis=0)] if np.any(y != 0.0) else y[:, :1]
    m = y.shape[1]
    w = _as_weights(weights, n)

    if order is not None:
        orders = np.array([int(order)])
        criterion_used = "fixed"
    else:
        top = _default_max_order(n, n_dim) if max_order is None else int(max_order)
        if n_dim == 3 and max_order is None:
            top = _MAX_ORDER_3D
        if top < 1:
            raise DataError(f"max_order must be >= 1; got {top}")
        orders = np.arange(1, top + 1)
        criterion_used = criterion
    top_funcs = n_functions(int(orders[-1]), n_dim) if n_dim < 3 else 0
    if top_funcs >= n:
        raise DataError(
            f"order {int(orders[-1])} has {top_funcs} functions; {n} scan points leave no "
            "residual degree of freedom (lower max_order)"
        )

    full = orthonormal_basis(pts, dom, int(orders[-1]), w, family=family)
    if n_dim == 3 and order is None and max_order is None:
        # a body's faces tell fewer functions apart than the order's count: the largest order
        # is the one whose distinguishable functions stay within a third of the points
        counts = np.array([full.functions_up_to(int(p)) for p in orders])
        top = max(int(np.count_nonzero(counts <= max(n // 3, 1))), 1)
        orders = orders[:top]
        full = full.truncate(int(orders[-1]))
    sw = np.sqrt(w)[:, None]
    b = full.evaluate(pts) * sw  # (n, P), orthonormal columns
    yw = y * sw
    c_all = b.T @ yw
    floor = max((64.0 * np.finfo(float).eps) ** 2 * float(np.sum(yw**2)), np.finfo(float).tiny)
    n_funcs = np.array([full.functions_up_to(int(p)) for p in orders])
    if n_funcs[-1] >= n:
        raise DataError(f"order {int(orders[-1])} has {n_funcs[-1]} functions; {n} scan points "
                        "leave no residual degree of freedom (lower max_order)")
    rss = np.empty(orders.size)
    for i, k in enumerate(n_funcs):
        resid = yw - b[:, :k] @ c_all[:k]
        rss[i] = float(np.sum(resid**2))
    rss_eff = np.maximum(rss, floor)
    n_obs = n * m
    if criterion_used == "bic":
        score = n_obs * np.log(rss_eff / n_obs) + n_funcs * m * math.log(n_obs)
    else:
        score = (rss_eff / n_obs) / (1.0 - n_funcs / n) ** 2
    i_best = int(np.argmin(score))
    p_best = int(orders[i_best])
    k_best = int(n_funcs[i_best])

    basis = full.truncate(p_best)
    bb = b[:, :k_best]
    coef_real = np.linalg.lstsq(bb, vals.reshape(n, -1).real * sw, rcond=None)[0]
    coef = coef_real
    if is_complex:
        coef = coef_real + 1j * np.linalg.lstsq(bb, vals.reshape(n, -1).imag * sw, rcond=None)[0]
    if vals.ndim == 1:
        coef = coef[:, 0]
    sigma = math.sqrt(rss[i_best] / (m * (n - k_best)))
    gram = bb.T @ bb
    cov = sigma**2 * np.linalg.inv(gram)
    return ShapeFit(
        basis=basis,
        coefficients=coef,
        order=p_best,
        orders=orders,
        score=score,
        criterion=criterion_used,
        residual_std=sigma,
        coefficient_covariance=0.5 * (cov + cov.T),
    )


def project(
    points: np.ndarray,
    values: np.ndarray,
    basis: PolynomialBasis,
    weights: np.ndarray | None = None,
) -> np.ndarray:
    """Weighted least-squares projection of values onto the span of a basis.

    The basis need not be orthonormal on these points.

    Parameters
    ----------
    points : (n_points,) or (n_points, n_dim) array [m]
    values : (n_points,) or (n_points, k) array, real or complex [any unit]
    basis : PolynomialBasis
    weights : (n_points,) array, optional

    Returns
    -------
    array like ``values``
        The projected values at the points, B (B^T W B)^-1 B^T W values.
    """
    b = basis.evaluate(points)
    vals = np.asarray(values)
    if vals.shape[0] != b.shape[0] or vals.ndim not in (1, 2):
        raise DimensionError(
            f"values must be ({b.shape[0]},) or ({b.shape[0]}, k); got shape {vals.shape}"
        )
    sw = np.sqrt(_as_weights(weights, b.shape[0]))
    coef = np.linalg.lstsq(b * sw[:, None], (vals.T * sw).T, rcond=None)[0]
    return b @ coef


def shape_similarity(shape_a: np.ndarray, shape_b: np.ndarray) -> float:
    """Modal assurance criterion of two (complex) shapes sampled at the same points.

    MAC = |a^H b|^2 / ((a^H a) (b^H b)): 1 for the same shape up to a complex factor, 0 for
    orthogonal shapes.

    Parameters
    ----------
    shape_a, shape_b : (n_points,) arrays, real or complex [any unit]

    Returns
    -------
    float [1]
    """
    a = np.asarray(shape_a).ravel()
    b = np.asarray(shape_b).ravel()
    if a.shape != b.shape:
        raise DimensionError(f"shapes have {a.size} and {b.size} values; expected equal")
    na = float(np.vdot(a, a).real)
    nb = float(np.vdot(b, b).real)
    if na == 0.0 or nb == 0.0:
        raise DataError("the MAC of a zero shape is undefined")
    return float(abs(np.vdot(a, b)) ** 2 / (na * nb))
