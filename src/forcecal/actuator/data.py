"""The observations a law is fitted to: :class:`CalibrationData`.

Shapes: ``n_obs`` observations, ``n_poles`` poles. SI units throughout.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import DataError, DimensionError

__all__ = ["CalibrationData"]

FLOOR_FRACTION = 0.01
"""The relative residual divides by ``max(|F|, floor)`` with ``floor = FLOOR_FRACTION *
median(|F|)``, so that forces near zero do not dominate the fit."""

GAP_TOLERANCE = 1.0e-3
"""Two static gaps closer than this fraction of the median static gap count as one gap."""


def _as_vector(name: str, value: Any, n: int | None) -> np.ndarray:
    """``value`` as a finite float vector of ``n`` entries (any length when ``n`` is None).

    Parameters
    ----------
    name : str
        Name of the field, for the messages.
    value : array_like
        The values.
    n : int or None
        Required length.

    Returns
    -------
    (n,) array

    Raises
    ------
    DimensionError
        When ``value`` is not a vector of the required length.
    DataError
        When it holds non-finite values.
    """
    arr = np.asarray(value, dtype=float)
    if arr.ndim != 1 or (n is not None and arr.shape[0] != n):
        expected = "(n_obs,)" if n is None else f"({n},)"
        raise DimensionError(
            f"calibration data: '{name}' has shape {arr.shape}; expected {expected}"
        )
    if not np.all(np.isfinite(arr)):
        bad = int(np.count_nonzero(~np.isfinite(arr)))
        raise DataError(f"calibration data: '{name}' has {bad} non-finite values")
    return arr


def _as_gaps(value: Any, n: int) -> np.ndarray:
    """The pole gaps as an (n, n_poles) array of positive values [m] (1-D means one pole)."""
    gaps = np.asarray(value, dtype=float)
    if gaps.ndim == 1:
        gaps = gaps[:, None]
    if gaps.ndim != 2 or gaps.shape[0] != n or gaps.shape[1] < 1:
        raise DimensionError(
            f"calibration data: 'gaps' has shape {gaps.shape}; expected ({n}, n_poles)"
        )
    if not np.all(np.isfinite(gaps)) or np.any(gaps <= 0):
        bad = int(np.count_nonzero(~(np.isfinite(gaps) & (gaps > 0))))
        raise DataError(f"calibration data: 'gaps' has {bad} values that are not positive")
    return gaps


def _as_group(value: Any, n: int) -> np.ndarray:
    """The run index of every observation, (n,); None means one group (all zero)."""
    if value is None:
        return np.zeros(n, dtype=int)
    group = np.asarray(value)
    if group.shape != (n,):
        raise DimensionError(f"calibration data: 'group' has shape {group.shape}; expected ({n},)")
    return group


def _cluster(values: np.ndarray, tol: float) -> np.ndarray:
    """Means of the clusters of sorted ``values`` whose neighbours are closer than ``tol``."""
    v = np.sort(values)
    breaks = np.flatnonzero(np.diff(v) > tol) + 1
    return np.array([c.mean() for c in np.split(v, breaks)])


@dataclass(frozen=True)
class CalibrationData:
    """Observations of the actuator pooled from the runs of a campaign.

    Attributes
    ----------
    current : (n_obs,) array [A]
        Coil current.
    gaps : (n_obs, n_poles) array [m]
        Instantaneous air gap at each pole (static gap minus the structure's displacement there).
        A 1-D array means one pole.
    force : (n_obs,) array [N]
        Measured (reconstructed) TOTAL actuator force, summed over the poles.
    static_gap : (n_obs,) array [m]
        Static gap of the run each observation comes from; the number of distinct values decides
        which laws are identifiable.
    flux : (n_obs,) array [Wb] or None
        Flux through one pole, when measured.
    sigma : (n_obs,) array [N] or None
        Standard uncertainty of ``force``. When given, the relative residuals are weighted by
        the relative uncertainties, i.e. the fit minimises ``sum(((F_model - F) / sigma)^2)``.
    group : (n_obs,) array of int or None
        Run index of each observation, for held-out validation; None means one group (after
        construction it is always an array).
    force_floor : float [N] or None
        Floor of the relative-residual denominator; None sets it to
        ``FLOOR_FRACTION * median(|force|)`` (after construction it is always a float).
        :meth:`subset` carries it over so that a subset is weighted like the whole campaign.
    """

    current: np.ndarray
    gaps: np.ndarray
    force: np.ndarray
    static_gap: np.ndarray
    flux: np.ndarray | None = None
    sigma: np.ndarray | None = None
    group: np.ndarray | None = None
    force_floor: float | None = None

    def __post_init__(self) -> None:
        current = _as_vector("current", self.current, None)
        n = current.shape[0]
        gaps = _as_gaps(self.gaps, n)
        force = _as_vector("force", self.force, n)
        static_gap = _as_vector("static_gap", self.static_gap, n)
        if np.any(static_gap <= 0):
            raise DataError("calibration data: 'static_gap' has values that are not positive")
        flux = None if self.flux is None else _as_vector("flux", self.flux, n)
        sigma = None if self.sigma is None else _as_vector("sigma", self.sigma, n)
        if sigma is not None and np.any(sigma <= 0):
            raise DataError("calibration data: 'sigma' has values that are not positive")
        group = _as_group(self.group, n)
        if n == 0:
            raise DataError("calibration data: no observations")
        floor = self.force_floor
        if floor is None:
            floor = FLOOR_FRACTION * float(np.median(np.abs(force)))
        if not floor > 0:
            raise DataError(
                "calibration data: the median |force| is zero; there is nothing to calibrate"
            )
        for name, value in (
            ("current", current),
            ("gaps", gaps),
            ("force", force),
            ("static_gap", static_gap),
            ("flux", flux),
            ("sigma", sigma),
            ("group", group),
            ("force_floor", float(floor)),
        ):
            object.__setattr__(self, name, value)

    @property
    def n_obs(self) -> int:
        """Number of observations."""
        return int(self.current.shape[0])

    @property
    def n_poles(self) -> int:
        """Number of poles."""
        return int(self.gaps.shape[1])

    @property
    def scale(self) -> np.ndarray:
        """Denominator of the relative residual, ``max(|F|, floor)``, shape (n_obs,) [N]."""
        assert self.force_floor is not None  # set by __post_init__
        return np.maximum(np.abs(self.force), self.force_floor)

    def relative_residual(self, model: np.ndarray) -> np.ndarray:
        """``(model - force) / scale`` at every observation [-]: a law's relative residual."""
        return (np.asarray(model) - self.force) / self.scale

    @property
    def weights(self) -> np.ndarray:
        """Denominator of the fitted residual: ``sigma`` if given, else :attr:`scale` [N]."""
        return self.scale if self.sigma is None else self.sigma

    def distinct_static_gaps(self) -> np.ndarray:
        """Sorted distinct static gaps [m]; gaps within ``GAP_TOLERANCE`` relative are one.

        Returns
        -------
        (n_gaps,) array [m]
            The mean of every cluster of static gaps, ascending.
        """
        tol = GAP_TOLERANCE * float(np.median(self.static_gap))
        return _cluster(self.static_gap, tol)

    def subset(self, mask: np.ndarray) -> CalibrationData:
        """The observations selected by a boolean mask or index array, same force floor.

        Parameters
        ----------
        mask : (n_obs,) array of bool, or array of int
            The observations to keep.

        Returns
        -------
        CalibrationData
            The selected observations.
        """

        def pick(a: np.ndarray | None) -> np.ndarray | None:
            return None if a is None else a[mask]

        assert self.group is not None  # set by __post_init__

        return CalibrationData(
            current=self.current[mask],
            gaps=self.gaps[mask],
            force=self.force[mask],
            static_gap=self.static_gap[mask],
            flux=pick(self.flux),
            sigma=pick(self.sigma),
            group=self.group[mask],
            force_floor=self.force_floor,
        )
