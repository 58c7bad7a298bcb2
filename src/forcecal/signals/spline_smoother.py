"""A cubic smoothing spline's linear map over a set of lines, and its penalty of least risk.

The natural cubic spline g that minimises sum_i w_i (y_i - g(x_i))^2 + lam int g''(u)^2 du
(what :func:`scipy.interpolate.make_smoothing_spline` fits) is linear in y: its values at the
lines are S(lam) y, S = (W + lam K)^-1 W, K = Q R^-1 Q^T the roughness penalty as a quadratic
form in those values (the Reinsch form: Q (n, n - 2) and R (n - 2, n - 2) tridiagonal, from the
spacings; Green and Silverman, *Nonparametric Regression and Generalized Linear Models*, 1994,
section 2.1). In the eigenvectors of W^-1/2 K W^-1/2 (the Demmler-Reinsch basis) every
penalty's map is diagonal, 1 / (1 + lam alpha_i): its trace, its residuals and the penalty of
least risk cost O(n) each once the basis is known. scipy's fit gives a spline's values, not
its map, its trace or its risk; ``tests/signals/test_band_smoother.py`` checks the map against it.

The penalty of least risk minimises Mallows' C_p, the unbiased estimate of the spline's mean
squared error when the values' variances are known (the weights their inverses): the weighted
residuals plus 2 tr S, for the real and for the imaginary part of complex values.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["SplineFamily"]

PENALTIES = 400
"""Penalties tried between those that leave every basis vector whole and those that take every
one but the straight line's off, log-spaced (beside none and the straight line itself)."""
NULL = 1e-10
"""Basis vectors whose eigenvalue is within this share of the largest are the penalty's null
space: the weighted straight line."""


@dataclass(frozen=True)
class SplineFamily:
    """Every smoothing spline over lines ``x`` with weights ``w`` (inverse variances).

    Attributes
    ----------
    root_weights : (n,) array
        sqrt(w / scale): the weights over their median, so the basis is the same for weights
        of any size.
    scale : float
        That median (the residuals' weights in the risk are the weights themselves).
    vectors : (n, n) array
        The Demmler-Reinsch basis: the eigenvectors of W^-1/2 K W^-1/2.
    alpha : (n,) array
        Their eigenvalues (0 on the straight line's two).
    """

    root_weights: np.ndarray
    vectors: np.ndarray
    alpha: np.ndarray
    scale: float = 1.0

    @classmethod
    def over(cls, x: np.ndarray, w: np.ndarray) -> SplineFamily:
        """The family over strictly increasing ``x`` (at least 3 lines), weights ``w`` > 0."""
        x = np.asarray(x, float)
        h = np.diff(x)
        n = x.size
        j = np.arange(n - 2)
        q = np.zeros((n, n - 2))
        q[j, j] = 1.0 / h[:-1]
        q[j + 1, j] = -1.0 / h[:-1] - 1.0 / h[1:]
        q[j + 2, j] = 1.0 / h[1:]
        r = (np.diag((h[:-1] + h[1:]) / 3.0) + np.diag(h[1:-1] / 6.0, 1)
             + np.diag(h[1:-1] / 6.0, -1))
        k = q @ np.linalg.solve(r, q.T)
        w = np.asarray(w, float)
        scale = float(np.median(w))
        sw = np.sqrt(w / scale)
        a = k / sw[:, None] / sw[None, :]
        alpha, vectors = np.linalg.eigh(0.5 * (a + a.T))
        alpha = np.where(alpha <= NULL * alpha[-1], 0.0, alpha)
        return cls(root_weights=sw, vectors=vectors, alpha=alpha, scale=scale)

    def gains(self, lam: float) -> np.ndarray:
        """(n,): the map's eigenvalues at penalty ``lam`` (``inf``: the straight line)."""
        if np.isinf(lam):
            return (self.alpha == 0.0).astype(float)
        return 1.0 / (1.0 + lam / self.scale * self.alpha)     # the basis's weights are w / scale

    def matrix(self, lam: float) -> np.ndarray:
        """(n, n): S(lam), the map from the values at the lines to the spline's there."""
        u = self.vectors
        return ((u * self.gains(lam)) @ u.T) * (self.root_weights[None, :]
                                                / self.root_weights[:, None])

    def least_risk(self, y: np.ndarray) -> float:
        """The penalty of least C_p for complex (or real) values ``y`` at the lines: 0 (none)
        or ``inf`` (the straight line) among the candidates."""
        c = self.scale * np.abs(self.vectors.T @ (self.root_weights * y)) ** 2  # Re^2 + Im^2
        parts = 2.0 if np.iscomplexobj(y) else 1.0
        live = self.alpha[self.alpha > 0.0]
        with np.errstate(over="ignore"):    # weights near the float's end: what is finite
            grid = self.scale * np.geomspace(1e-3 / live.max(), 1e3 / live.min(), PENALTIES)
        candidates = np.r_[0.0, grid[np.isfinite(grid) & (grid > 0.0)], np.inf]
        risk = [float(np.sum(c * (1.0 - g) ** 2) + 2.0 * parts * np.sum(g))
                for g in map(self.gains, candidates)]
        return float(candidates[int(np.argmin(risk))])
