"""Laws seen through AC-coupled gauges: :class:`ACOnlyLaw`.

AC-coupled (piezoelectric) gauges do not measure the DC force. :class:`ACOnlyLaw` wraps a law
and removes the per-run mean of the modelled total force, so that the law's parameters are
fitted to the harmonics alone and still predict the full force, DC included.

Shapes: ``n_obs`` observations, ``n_poles`` poles, ``n_params`` parameters of a law. SI units
throughout.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import FitError
from .data import CalibrationData
from .laws import Law

__all__ = ["DEFAULT_SAMPLES_PER_PERIOD", "ACOnlyLaw"]

DEFAULT_SAMPLES_PER_PERIOD = 64
"""Calibration samples a campaign takes from each run, evenly over one period of its fitted
series; the default run block of :class:`ACOnlyLaw`."""


@dataclass(frozen=True, kw_only=True)
class ACOnlyLaw(Law):
    """A law seen through AC-coupled gauges: the per-run mean of the modelled force removed.

    The observations must come in contiguous blocks of ``block`` samples, one block per run,
    spread evenly over one period (as :func:`forcecal.campaign.calibration_data` builds them),
    so that the block mean is the run's DC. The wrapper has the base law's name, parameters and
    identifiability, so a fit of it is a calibration of the base law: the fitted parameters
    predict the whole force, DC included, although only its harmonics were seen.

    Attributes
    ----------
    base : Law
        The law of the whole force.
    block : int
        Samples per run.
    """

    base: Law
    block: int = DEFAULT_SAMPLES_PER_PERIOD

    @classmethod
    def wrap(cls, base: Law, block: int = DEFAULT_SAMPLES_PER_PERIOD) -> ACOnlyLaw:
        """The AC-only view of a law.

        Parameters
        ----------
        base : Law
            The law of the whole force.
        block : int
            Samples per run.

        Returns
        -------
        ACOnlyLaw
        """
        return cls(
            name=base.name,
            formula=f"{base.formula} (AC part of each run)",
            param_names=base.param_names,
            param_units=base.param_units,
            needs_gaps=base.needs_gaps,
            needs_flux=base.needs_flux,
            separates=base.separates,
            base=base,
            block=block,
        )

    def _demean(self, a: np.ndarray) -> np.ndarray:
        """``a`` (n_obs, ...) with the mean of every block of ``block`` rows removed."""
        n = a.shape[0]
        if n % self.block:
            raise FitError(
                f"law '{self.name}' (AC only): {n} observations are not whole runs of "
                f"{self.block} samples; AC-only calibration validates by leaving out whole runs"
            )
        blocks = a.reshape(n // self.block, self.block, *a.shape[1:])
        return (blocks - blocks.mean(axis=1, keepdims=True)).reshape(a.shape)

    def _value_and_jacobian(
        self, p: np.ndarray, i: np.ndarray, s: np.ndarray, phi: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        f, jac = self.base._value_and_jacobian(p, i, s, phi)
        return self._demean(f), self._demean(jac)

    def _rescaled(self, p: np.ndarray, data: CalibrationData) -> tuple[np.ndarray, float]:
        """Parameters with the amplitude that best fits the AC force, and their weighted RSS."""
        model = self.per_pole(p, data.current, data.gaps, data.flux).sum(axis=1)
        w = data.weights
        b, y = model / w, data.force / w
        norm2 = float(b @ b)
        if not norm2 > 0:
            return p, math.inf
        c = float(b @ y) / norm2
        q = p.copy()
        if "K" in self.param_names:
            q[self.param_names.index("K")] *= c
        elif "A_eff" in self.param_names and c > 0:
            q[self.param_names.index("A_eff")] /= c
        else:
            return p, math.inf
        return q, float(np.sum((c * b - y) ** 2))

    def _grids(self, data: CalibrationData) -> list[tuple[int, np.ndarray]]:
        """``(parameter index, trial values)`` of the nonlinear parameters for the start."""
        grids: list[tuple[int, np.ndarray]] = []
        if "s_fe" in self.param_names:
            lo = -0.5 * float(data.gaps.min())
            grids.append(
                (
                    self.param_names.index("s_fe"),
                    np.linspace(lo, float(np.median(data.static_gap)), 41),
                )
            )
        if "i0" in self.param_names:
            i_max = float(np.max(np.abs(data.current)))
            grids.append((self.param_names.index("i0"), np.linspace(-0.3, 0.3, 13) * i_max))
        return grids

    def guess(self, data: CalibrationData) -> np.ndarray:
        """Start parameters: the base law's, refined on the AC force by a grid search.

        The amplitude (K, or A_eff) is solved by linear least squares on the AC force; ``s_fe``
        and ``i0``, when the law has them, are searched coordinate-wise on a grid, twice over.

        Parameters
        ----------
        data : CalibrationData
            The observations, in blocks of ``block`` samples.

        Returns
        -------
        (n_params,) array
            Start parameters in the order of ``param_names``.

        Raises
        ------
        FitError
            For the flux law, when the data have no flux.
        """
        if self.needs_flux:  # the base guess assumes a positive DC force; start from 1 m^2
            if data.flux is None:
                raise FitError(f"law '{self.name}' needs the flux through a pole; none given")
            p0 = np.ones(self.n_params)
        else:
            p0 = np.asarray(self.base.guess(data), dtype=float)
        grids = self._grids(data)
        best, best_rss = self._rescaled(p0, data)
        for _ in range(2):  # coordinate-wise grid search, twice over
            for k, grid in grids:
                for value in grid:
                    p = best.copy()
                    p[k] = value
                    q, rss = self._rescaled(p, data)
                    if rss < best_rss:
                        best, best_rss = q, rss
        return best

    def bounds(self, data: CalibrationData) -> tuple[np.ndarray, np.ndarray]:
        """The base law's bounds (see :meth:`forcecal.actuator.Law.bounds`).

        Parameters
        ----------
        data : CalibrationData
            The observations.

        Returns
        -------
        lo : (n_params,) array
            Lower bounds.
        hi : (n_params,) array
            Upper bounds.
        """
        return self.base.bounds(data)

    def check_fitted(self, params: np.ndarray, data: CalibrationData) -> None:
        """The base law's refusal of parameters the data do not determine (see
        :meth:`forcecal.actuator.Law.check_fitted`).

        Raises
        ------
        FitError
            As the base law raises it.
        """
        self.base.check_fitted(params, data)

    def typical(self, params: np.ndarray, data: CalibrationData) -> np.ndarray:
        """The base law's typical magnitudes (see :meth:`forcecal.actuator.Law.typical`).

        Parameters
        ----------
        params : (n_params,) array
            Start parameters.
        data : CalibrationData
            The observations.

        Returns
        -------
        (n_params,) array
            Positive magnitudes, units as ``param_units``.
        """
        return self.base.typical(params, data)
