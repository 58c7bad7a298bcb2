"""Vector shapes of a 3-D body: one orthonormal polynomial field per axis.

A body moves in three directions, and every measurement of it (a scan record, a probe) is the
component d . u(x) of the displacement along its direction d, at a *location* (x, y, z, dx, dy,
dz) (:func:`forcecal.rig.locations`). The shape of a harmonic is the vector field

    u(x) = sum over axes a of e_a sum_j p_{a,j} beta_{a,j}(x),

each component on its own 3-D polynomial basis (:mod:`forcecal.model.basis`), orthonormal on the
scan records measured along that axis and of the order their data choose (GCV or BIC). A 3-D
SLDV exports exactly such records, three per point (UFF response directions X, Y, Z).

A scan sees only the body's surface. The polynomials carry the surface motion into the
interior, where the mass is; orders the scanned faces cannot tell apart are not tried (see
:func:`forcecal.model.basis.fit_shape`). An axis no record measures has no shape: its motion counts
as zero and the model says so.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike

from ..errors import DataError, DimensionError
from .basis import PolynomialBasis, ShapeFit, fit_shape

__all__ = ["AXES", "VectorShapeFit", "fit_vector_shape"]

AXES = ("x", "y", "z")
_ALIGNED = 1.0 - 1e-6


def as_locations(locations: ArrayLike) -> np.ndarray:
    """(n, 6) float array of locations (a single (6,) location becomes (1, 6)).

    Parameters
    ----------
    locations : (n, 6) or (6,) array
        Rows (x, y, z [m], dx, dy, dz).

    Returns
    -------
    (n, 6) float array

    Raises
    ------
    DimensionError
        Anything else than rows of six numbers.
    """
    loc = np.atleast_2d(np.asarray(locations, dtype=float))
    if loc.ndim != 2 or loc.shape[1] != 6:
        raise DimensionError(f"a body's shapes take locations (n, 6) = (x, y, z, dx, dy, dz); "
                             f"got shape {np.shape(locations)}")
    return loc


def record_axes(locations: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The axis (0, 1, 2) and sign (+1, -1) of every record's direction.

    Parameters
    ----------
    locations : (n_records, 6) array
        Rows (x, y, z [m], dx, dy, dz); the directions need not be unit vectors.

    Returns
    -------
    axis : (n_records,) int array
        0, 1 or 2 for x, y or z.
    sign : (n_records,) float array
        +1 or -1.

    Raises
    ------
    DataError
        A direction that is not along an axis (the first one is named, counting from 1).
    """
    d = as_locations(locations)[:, 3:]
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    axis = np.argmax(np.abs(d), axis=1)
    along = np.abs(d[np.arange(len(d)), axis])
    if np.any(along < _ALIGNED):
        k = int(np.argmin(along >= _ALIGNED))
        raise DataError(f"record {k + 1} measures along {np.round(d[k], 4).tolist()}, not along "
                        "x, y or z; export the scan's components in the rig's axes")
    return axis, np.sign(d[np.arange(len(d)), axis])


@dataclass(frozen=True)
class VectorBasis:
    """The basis functions e_a beta_{a,j}(x) of the measured axes, evaluable at locations.

    Attributes
    ----------
    axes : tuple of int
        The measured axes (0, 1, 2 for x, y, z), ascending.
    bases : tuple of PolynomialBasis
        One 3-D basis per measured axis.
    """

    axes: tuple[int, ...]
    bases: tuple[PolynomialBasis, ...]

    @property
    def n_funcs(self) -> int:
        """Number of basis functions over all axes."""
        return sum(b.n_funcs for b in self.bases)

    def evaluate(self, locations: np.ndarray) -> np.ndarray:
        """The basis functions seen along each location's direction.

        Parameters
        ----------
        locations : (n, 6) array
            Rows (x, y, z [m], dx, dy, dz).

        Returns
        -------
        (n, n_funcs) array [1]
            d . e_a beta_{a,j}(x) at every location, the axes' functions one after another.
        """
        loc = as_locations(locations)
        return np.hstack([loc[:, 3 + a, None] * b.evaluate(loc[:, :3])
                          for a, b in zip(self.axes, self.bases, strict=True)])


@dataclass(frozen=True)
class VectorShapeFit:
    """A harmonic's vector shape: one :class:`ShapeFit` per measured axis.

    It offers what the estimator uses of a scalar :class:`ShapeFit` (``evaluate``, ``std``,
    ``basis``, ``coefficients``, ``coefficient_covariance``, ``order``, ``criterion``,
    ``residual_std``), with locations in place of points.

    Attributes
    ----------
    axes : tuple of int
        The measured axes (0, 1, 2 for x, y, z), ascending.
    components : tuple of ShapeFit
        One scalar fit per measured axis, over the records along it.
    """

    axes: tuple[int, ...]
    components: tuple[ShapeFit, ...]

    @cached_property
    def basis(self) -> VectorBasis:
        """The components' bases as one :class:`VectorBasis`."""
        return VectorBasis(self.axes, tuple(c.basis for c in self.components))

    @cached_property
    def coefficients(self) -> np.ndarray:
        """(n_funcs,) complex [m]: the components' coefficients one after another."""
        return np.concatenate([c.coefficients for c in self.components])

    @cached_property
    def fitted_basis(self) -> VectorBasis:
        """The components' bases of their chosen orders (:attr:`basis` may hold more)."""
        return VectorBasis(self.axes, tuple(c.fitted_basis for c in self.components))

    @cached_property
    def fitted_coefficients(self) -> np.ndarray:
        """The coefficients of :attr:`fitted_basis`."""
        return np.concatenate([c.fitted_coefficients for c in self.components])

    @cached_property
    def coefficient_covariance(self) -> np.ndarray:
        """Block diagonal: the axes are fitted to separate records."""
        from scipy.linalg import block_diag  # on use: `import forcecal` stays light

        return block_diag(*[c.coefficient_covariance for c in self.components])

    @property
    def order(self) -> int:
        """The largest order of the components (max total degree + 1)."""
        return max(c.order for c in self.components)

    @property
    def orders_by_axis(self) -> dict[str, int]:
        """The order of each measured axis, by axis name."""
        return {AXES[a]: c.order for a, c in zip(self.axes, self.components, strict=True)}

    @property
    def criterion(self) -> str:
        """How the orders were chosen ("gcv", "bic" or "fixed")."""
        return self.components[0].criterion

    @property
    def residual_std(self) -> float:
        """The largest residual standard deviation of the components [m]."""
        return max(c.residual_std for c in self.components)

    def evaluate(self, locations: np.ndarray) -> np.ndarray:
        """d . u(x) at locations.

        Parameters
        ----------
        locations : (n, 6) array
            Rows (x, y, z [m], dx, dy, dz).

        Returns
        -------
        (n,) complex array [unit of the values]
        """
        return self.fitted_basis.evaluate(locations) @ self.fitted_coefficients

    def std(self, locations: np.ndarray) -> np.ndarray:
        """Standard uncertainty of Re (and of Im) of d . u(x) at locations.

        Parameters
        ----------
        locations : (n, 6) array
            Rows (x, y, z [m], dx, dy, dz).

        Returns
        -------
        (n,) array [unit of the values]
        """
        b = self.basis.evaluate(locations)
        return np.sqrt(np.einsum("kr,rs,ks->k", b, self.coefficient_covariance, b))


def fit_vector_shape(locations: np.ndarray, values: np.ndarray, extent: ArrayLike,
                     criterion: str = "gcv", weights: np.ndarray | None = None,
                     min_order: int = 1) -> VectorShapeFit:
    """Fit each measured axis of a vector shape over the scan records along it.

    Parameters
    ----------
    locations : (n_records, 6) array
        Where and along which axis each record measured: (x, y, z [m], dx, dy, dz).
    values : (n_records,) complex array [m]
        The harmonic's phasor of each record.
    extent : ((x_min, x_max), (y_min, y_max), (z_min, z_max)) [m]
        The body's bounding box.
    criterion : {"gcv", "bic"}
        How each component's order is chosen.
    weights : (n_records,) array, optional
        Positive relative weights (inverse variances); default 1.
    min_order : int
        Lowest order tried for each component (capped at the largest its records support).

    Returns
    -------
    VectorShapeFit
        One :class:`~forcecal.model.basis.ShapeFit` per measured axis.

    Raises
    ------
    DataError
        A record not along an axis, or no record at all.
    DimensionError
        Values that do not match the locations.
    """
    loc = as_locations(locations)
    vals = np.asarray(values)
    if vals.shape != (len(loc),):
        raise DimensionError(f"values must be ({len(loc)},); got shape {vals.shape}")
    w = np.ones(len(loc)) if weights is None else np.asarray(weights, dtype=float)
    axis, sign = record_axes(loc)
    axes, fits = [], []
    for a in range(3):
        sel = axis == a
        if not np.any(sel):
            continue
        fits.append(fit_shape(loc[sel, :3], vals[sel] * sign[sel], extent,
                              criterion=criterion, weights=w[sel], min_order=min_order))
        axes.append(a)
    return VectorShapeFit(tuple(axes), tuple(fits))
