"""Smooth spatial shapes fitted over scan points (METHOD.md section 3, step 2).

A shape phi(x) over the structure is expanded on polynomials beta_r orthonormal on the scan
points in the discrete (optionally weighted) inner product <f, g> = sum_k w_k f(x_k) g(x_k),
so that B^T W B = I with B[k, r] = beta_r(x_k). They are built from the Legendre Vandermonde
matrix V of the coordinates mapped affinely to [-1, 1] over the structure's extent (not the
range of the scan points) and the triangular factor of its QR factorization,
sqrt(W) V = Q R: beta(x) = V(x) R^-1, which can be evaluated anywhere (sensors, gauges,
quadrature nodes), not only at the scan points. In 2-D the Vandermonde holds the products
P_i(u) P_j(v) of total degree i + j < order, ordered by total degree, so the basis of a lower
order is always the leading columns of a higher one.

``order`` counts polynomial degrees: order p holds every polynomial of (total) degree below p,
p functions in 1-D and p (p + 1) / 2 in 2-D; order 1 is the constant (rigid translation),
order 2 adds the rigid rotations. Complex shapes (harmonic phasors) are fitted with Re and Im
sharing one order, since they describe one physical shape, chosen by generalized
cross-validation or BIC.

The basis itself (raw functions, orthonormalization) lives in the private module
``_orthonormal_basis``; its public names are re-exported here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike

from ..errors import DataError, DimensionError
from ._orthonormal_basis import (
    PolynomialBasis,
    as_domain,
    as_points,
    as_weights,
    n_functions,
    orthonormal_basis,
)

__all__ = ["ShapeFit", "fit_shape"]

#: Default cap on the order tried by :func:`fit_shape`.
_MAX_ORDER = 20
#: In 3-D, the order tried before the faces' distinguishable functions are counted.
_MAX_ORDER_3D = 12


@dataclass(frozen=True)
class ShapeFit:
    """A shape fitted over the scan points on an orthonormal polynomial basis.

    Attributes
    ----------
    basis : PolynomialBasis
        The basis of the chosen order, extended to the highest order whose Akaike weight is
        not negligible (:func:`order_weights`).
    coefficients : (n_funcs,) or (n_funcs, k) array [unit of the values]
        Expansion coefficients p_r, complex when the values are complex; zero for the
        functions beyond the chosen order (the basis holds them for the covariance).
    order : int
        The chosen order (max total degree + 1): the shape is evaluated on the basis's
        functions up to it.
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
        The covariance of the real part of each column of coefficients, and equally of the
        imaginary part: sigma^2 I (the basis is orthonormal on the weighted points) when the
        order is fixed; otherwise mixed over the orders' weights, each order's own
        sigma_p^2 I and its coefficients' difference from the chosen ones
        (:func:`_averaged_covariance`).
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
            Where to evaluate the shape.

        Returns
        -------
        (n_points,) or (n_points, k) array [unit of the values]
            The shape, complex when the values were.
        """
        return self.fitted_basis.evaluate(points) @ self.fitted_coefficients

    @cached_property
    def fitted_basis(self) -> PolynomialBasis:
        """The basis of the chosen order (:attr:`basis` may hold more functions)."""
        if self.basis.functions_up_to(self.order) == self.basis.n_funcs:
            return self.basis
        return self.basis.truncate(self.order)

    @property
    def fitted_coefficients(self) -> np.ndarray:
        """The coefficients of :attr:`fitted_basis`."""
        return self.coefficients[: self.basis.functions_up_to(self.order)]

    def std(self, points: np.ndarray) -> np.ndarray:
        """Standard uncertainty of Re (and of Im) of the fitted shape at points.

        Parameters
        ----------
        points : (n_points,) or (n_points, n_dim) array [m]
            Where to evaluate the uncertainty.

        Returns
        -------
        (n_points,) array [unit of the values]
            sqrt(b(x)^T C b(x)), C the coefficient covariance.
        """
        b = self.basis.evaluate(points)
        return np.sqrt(np.einsum("kr,rs,ks->k", b, self.coefficient_covariance, b))


def _real_columns(values: np.ndarray) -> np.ndarray:
    """(n, k) real or complex -> (n, m) real: Re columns, then Im columns if complex."""
    if np.iscomplexobj(values):
        return np.concatenate([values.real, values.imag], axis=1)
    return values


def _default_max_order(n_points: int, n_dim: int) -> int:
    """Largest order (at most ``_MAX_ORDER``) with at most n_points // 3 functions."""
    order = 1
    while order < _MAX_ORDER and n_functions(order + 1, n_dim) <= n_points // 3:
        order += 1
    return order


def fit_shape(
    points: np.ndarray,
    values: np.ndarray,
    extent: ArrayLike,
    max_order: int | None = None,
    criterion: str = "gcv",
    weights: np.ndarray | None = None,
    order: int | None = None,
    family: str = "legendre",
    min_order: int = 1,
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
    extent : (x_min, x_max) or ((x_min, x_max), (y_min, y_max)[, (z_min, z_max)]) [m]
        The structure's extent, mapped to [-1, 1].
    max_order : int, optional
        Largest order tried. Default: the largest order with at most n_points // 3 functions,
        capped at 20 (in 3-D: with at most n_points // 3 functions the faces tell apart).
    criterion : {"gcv", "bic"}
        How the order is chosen (see above).
    weights : (n_points,) array, optional
        Positive weights (inverse variances up to a common factor).
    order : int, optional
        Use this order instead of selecting one (``criterion`` becomes "fixed").
    family : {"legendre", "modes"}
        The raw functions (see :func:`raw_functions`).
    min_order : int
        Lowest order tried (capped at the largest): a weak harmonic's shape is given at
        least the order of a strong one of the same scan, which noise would otherwise hide
        (see :func:`forcecal.model.spatial.build_spatial_model`).

    Returns
    -------
    ShapeFit
        The coefficients of the chosen order, with the scores of every order tried. Its
        covariance carries the choice of order: the coefficients of every order whose Akaike
        (or Schwarz) weight is not negligible are part of the basis, those beyond the chosen
        order with a zero coefficient (:func:`order_weights`).

    Raises
    ------
    DataError
        Non-finite values, an unknown criterion, or an order that leaves no residual degree
        of freedom.
    DimensionError
        Values and points that do not agree.
    ConditioningError
        The points cannot support the largest order tried.
    """
    if criterion not in ("gcv", "bic"):
        raise DataError(f"criterion must be 'gcv' or 'bic'; got '{criterion}'")
    dom = as_domain(extent)
    n_dim = dom.shape[0]
    pts = as_points(points, n_dim)
    n = pts.shape[0]
    vals, y = _shape_values(values, n)
    w = as_weights(weights, n)
    orders, criterion_used = _orders_to_try(order, max_order, criterion, n, n_dim)
    full = orthonormal_basis(pts, dom, int(orders[-1]), w, family=family)
    if n_dim == 3 and order is None and max_order is None:
        full, orders = _body_orders(full, orders, n)
    if order is None:
        orders = orders[orders >= min(int(min_order), int(orders[-1]))]
    sw = np.sqrt(w)[:, None]
    b = full.evaluate(pts) * sw  # (n, P), orthonormal columns
    n_funcs = np.array([full.functions_up_to(int(p)) for p in orders])
    rss, score = _order_scores(b, y * sw, orders, n_funcs, criterion_used)
    i_best = int(np.argmin(score))
    p_best = int(orders[i_best])
    k_best = int(n_funcs[i_best])
    sigma = math.sqrt(rss[i_best] / (y.shape[1] * (n - k_best)))
    weights_p = (np.ones(1) if criterion_used == "fixed"
                 else order_weights(rss, n_funcs, n * y.shape[1], y.shape[1], criterion_used))
    top = max(int(np.flatnonzero(weights_p)[-1]), i_best)
    k_top = int(n_funcs[top])
    coef = _coefficients(b[:, :k_top], vals, sw)
    chosen = coef.copy()
    chosen[k_best:] = 0.0
    sigmas = np.sqrt(rss / (y.shape[1] * (n - n_funcs)))
    return ShapeFit(
        basis=full.truncate(int(orders[top])),
        coefficients=chosen,
        order=p_best,
        orders=orders,
        score=score,
        criterion=criterion_used,
        residual_std=sigma,
        coefficient_covariance=_averaged_covariance(coef, n_funcs[: top + 1], k_best,
                                                    weights_p[: top + 1], sigmas[: top + 1]),
    )


def column_fits(fit: ShapeFit, points: np.ndarray, values: np.ndarray,
                weights: np.ndarray | None = None) -> tuple[ShapeFit, ...]:
    """Every column of a real stack fitted by :func:`fit_shape` as a shape of its own, with its
    own residual and covariance.

    The stack's fit shares one order, one order weighting and one residual level among its
    columns, which is right for columns of one shape (Re and Im, harmonics). Columns of unlike
    content (a span's patterns: some smooth, some left rough by junk the smooth basis cannot
    take) are each known to their own residual: the pooled level gives a smooth column the
    rough ones' misfit. Each column keeps the stack's basis, chosen order and order weights
    (:func:`order_weights` over the stack), with its own sigma_p and coefficients' differences
    in :func:`_averaged_covariance`.

    Parameters
    ----------
    fit : ShapeFit
        The stack's fit, of real (n_points, k) ``values`` at ``points`` with ``weights``.
    points, values, weights
        As given to :func:`fit_shape`.

    Returns
    -------
    tuple of k ShapeFit
    """
    y = np.asarray(values, dtype=float).reshape(len(points), -1)
    n, m = y.shape
    sw = np.sqrt(as_weights(weights, n))[:, None]
    b = fit.basis.evaluate(as_points(points, fit.basis.n_dim)) * sw  # orthonormal columns
    orders = fit.orders[fit.orders <= fit.basis.order]
    n_funcs = np.array([fit.basis.functions_up_to(int(p)) for p in orders])
    k_best = fit.basis.functions_up_to(fit.order)
    coef = b.T @ (y * sw)                                           # (n_funcs, m)
    rss = np.array([np.sum((y * sw - b[:, :k] @ coef[:k]) ** 2, axis=0) for k in n_funcs])
    weights_p = (np.ones(1) if fit.criterion == "fixed"
                 else order_weights(rss.sum(axis=1), n_funcs, n * m, m, fit.criterion))
    sigmas = np.sqrt(rss / (n - n_funcs)[:, None])                  # (n_orders, m)
    best = int(np.flatnonzero(n_funcs == k_best)[0])
    return tuple(replace(
        fit, coefficients=fit.coefficients[:, j], residual_std=float(sigmas[best, j]),
        coefficient_covariance=_averaged_covariance(coef[:, j], n_funcs, k_best, weights_p,
                                                    sigmas[:, j]))
        for j in range(m))


def order_weights(rss: np.ndarray, n_funcs: np.ndarray, n_obs: int, m: int,
                  criterion: str) -> np.ndarray:
    """Akaike weights of the orders tried (Schwarz weights when the order is chosen by BIC):
    w_p proportional to exp(-IC_p / 2), IC_p = n_obs ln(RSS_p / n_obs) + c p_funcs m with
    c = 2 (AIC) or ln(n_obs) (BIC); weights below 1e-2 of the largest are set to zero and the
    rest renormalized.

    Parameters
    ----------
    rss : (n_orders,) array
        Weighted residual sum of squares of every order.
    n_funcs : (n_orders,) int array
        Functions of every order.
    n_obs : int
        Real observations (points x real columns).
    m : int
        Real columns.
    criterion : {"gcv", "bic"}

    Returns
    -------
    (n_orders,) array summing to 1
    """
    floor = max(float(np.max(rss)) * (64.0 * np.finfo(float).eps) ** 2, np.finfo(float).tiny)
    penalty = math.log(n_obs) if criterion == "bic" else 2.0
    ic = n_obs * np.log(np.maximum(rss, floor) / n_obs) + penalty * n_funcs * m
    w = np.exp(-(ic - ic.min()) / 2)
    w[w < 1e-2 * w.max()] = 0.0
    out: np.ndarray = w / w.sum()
    return out


def _averaged_covariance(coef: np.ndarray, n_funcs: np.ndarray, k_best: int,
                         weights: np.ndarray, sigmas: np.ndarray) -> np.ndarray:
    """Covariance of the chosen order's coefficients (zero beyond its functions) that also
    carries the choice of order: the mixture over the orders tried of each order's own
    covariance sigma_p^2 I (the basis is orthonormal on the weighted points) and its
    difference from the chosen coefficients, d_p d_p^H (Burnham and Anderson's unconditional
    variance). The difference is complex; its Re(d d^H) / 2 serves the real part and the
    imaginary part alike, so that the expected |error|^2 of the complex shape is kept."""
    k_top = coef.shape[0]
    c = coef.reshape(k_top, -1)
    cov = np.zeros((k_top, k_top))
    for k, wp, sp in zip(n_funcs, weights, sigmas, strict=True):
        if wp == 0.0:
            continue
        d = np.zeros_like(c)
        lo, hi = sorted((int(k), k_best))
        d[lo:hi] = c[lo:hi] if k > k_best else -c[lo:hi]
        outer = (d @ d.conj().T).real / ((2 if np.iscomplexobj(c) else 1) * c.shape[1])
        cov[: int(k), : int(k)] += wp * sp**2 * np.eye(int(k))
        cov += wp * outer
    return 0.5 * (cov + cov.T)


def _shape_values(values: ArrayLike, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The values as a float or complex array, and the (n, m) real columns they observe.

    Columns identically zero (e.g. the Im part of a real shape) carry no observation and are
    left out of the columns, unless every column is zero.
    """
    vals = np.asarray(values)
    if vals.ndim not in (1, 2) or vals.shape[0] != n:
        raise DimensionError(
            f"values must be ({n},) or ({n}, k) for {n} points; got shape {vals.shape}"
        )
    if not np.all(np.isfinite(vals)):
        raise DataError(f"values contain {int((~np.isfinite(vals)).sum())} non-finite entries")
    vals = vals.astype(complex if np.iscomplexobj(vals) else float)
    y = _real_columns(vals.reshape(n, -1))
    y = y[:, np.any(y != 0.0, axis=0)] if np.any(y != 0.0) else y[:, :1]
    return vals, y


def _orders_to_try(order: int | None, max_order: int | None, criterion: str, n: int,
                   n_dim: int) -> tuple[np.ndarray, str]:
    """(orders, criterion used): the one order asked for ("fixed"), else 1 .. the top order.

    Raises DataError when the top order leaves no residual degree of freedom (counted in
    1-D and 2-D; a body's count comes after deflation, in :func:`_order_scores`).
    """
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
    return orders, criterion_used


def _body_orders(full: PolynomialBasis, orders: np.ndarray,
                 n: int) -> tuple[PolynomialBasis, np.ndarray]:
    """The basis and orders a body's scan of ``n`` records supports.

    A body's faces tell fewer functions apart than the order's count: the largest order is the
    one whose distinguishable functions stay within a third of the points.
    """
    counts = np.array([full.functions_up_to(int(p)) for p in orders])
    top = max(int(np.count_nonzero(counts <= max(n // 3, 1))), 1)
    orders = orders[:top]
    return full.truncate(int(orders[-1])), orders


def _order_scores(b: np.ndarray, yw: np.ndarray, orders: np.ndarray, n_funcs: np.ndarray,
                  criterion: str) -> tuple[np.ndarray, np.ndarray]:
    """(RSS, score) of every order, from the weighted basis ``b`` (n, P) with orthonormal
    columns and the weighted real columns ``yw`` (n, m) (see :func:`fit_shape`).

    RSS below the rounding level of the data counts as that level in the score.
    """
    n, m = yw.shape
    c_all = b.T @ yw
    floor = max((64.0 * np.finfo(float).eps) ** 2 * float(np.sum(yw**2)), np.finfo(float).tiny)
    if n_funcs[-1] >= n:
        raise DataError(f"order {int(orders[-1])} has {n_funcs[-1]} functions; {n} scan points "
                        "leave no residual degree of freedom (lower max_order)")
    rss = np.empty(orders.size)
    for i, k in enumerate(n_funcs):
        resid = yw - b[:, :k] @ c_all[:k]
        rss[i] = float(np.sum(resid**2))
    rss_eff = np.maximum(rss, floor)
    n_obs = n * m
    if criterion == "bic":
        score = n_obs * np.log(rss_eff / n_obs) + n_funcs * m * math.log(n_obs)
    else:
        score = (rss_eff / n_obs) / (1.0 - n_funcs / n) ** 2
    return rss, score


def _coefficients(bb: np.ndarray, vals: np.ndarray, sw: np.ndarray) -> np.ndarray:
    """Weighted least-squares coefficients of the values on the weighted basis ``bb``:
    (k,) or (k, n_columns) like the values, Re and Im fitted separately."""
    n = bb.shape[0]
    coef_real = np.linalg.lstsq(bb, vals.reshape(n, -1).real * sw, rcond=None)[0]
    coef = coef_real
    if np.iscomplexobj(vals):
        coef = coef_real + 1j * np.linalg.lstsq(bb, vals.reshape(n, -1).imag * sw, rcond=None)[0]
    return coef[:, 0] if vals.ndim == 1 else coef


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
        Where the values are given.
    values : (n_points,) or (n_points, k) array, real or complex [any unit]
        The values to project.
    basis : PolynomialBasis
        The basis whose span the values are projected onto.
    weights : (n_points,) array, optional
        Positive weights of the inner product (default 1).

    Returns
    -------
    array like ``values``
        The projected values at the points, B (B^T W B)^-1 B^T W values.

    Raises
    ------
    DimensionError
        Values that do not match the points.
    """
    b = basis.evaluate(points)
    vals = np.asarray(values)
    if vals.shape[0] != b.shape[0] or vals.ndim not in (1, 2):
        raise DimensionError(
            f"values must be ({b.shape[0]},) or ({b.shape[0]}, k); got shape {vals.shape}"
        )
    sw = np.sqrt(as_weights(weights, b.shape[0]))
    coef = np.linalg.lstsq(b * sw[:, None], (vals.T * sw).T, rcond=None)[0]
    return b @ coef


def shape_similarity(shape_a: np.ndarray, shape_b: np.ndarray) -> float:
    """Modal assurance criterion of two (complex) shapes sampled at the same points.

    MAC = |a^H b|^2 / ((a^H a) (b^H b)): 1 for the same shape up to a complex factor, 0 for
    orthogonal shapes.

    Parameters
    ----------
    shape_a : (n_points,) array, real or complex [any unit]
        The first shape.
    shape_b : (n_points,) array, real or complex [any unit]
        The second shape, at the same points.

    Returns
    -------
    float [1]
        The MAC, in [0, 1].

    Raises
    ------
    DimensionError
        Shapes of different sizes.
    DataError
        A zero shape.
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
