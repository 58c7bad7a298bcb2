"""Calibration of the electromagnetic actuator: force against current, air gap and flux.

The observations are pooled from several runs (METHOD.md section 5). For observation ``k`` we
know the coil current ``i_k`` [A], the instantaneous air gap at every pole ``s_{k,p}`` [m], maybe
the flux through one pole ``phi_k`` [Wb], and the reconstructed TOTAL actuator force ``F_k`` [N]
(the sum over the poles, which the reconstruction determines best). A *law* gives the force of
one pole; the model of the total is the sum of the law over the poles.

Every law is fitted by nonlinear least squares on relative residuals
``(F_model - F) / max(|F|, floor)``; laws are compared by BIC and by the error of the predicted
total on held-out runs, and the simplest law that predicts held-out runs as well as the best one
is chosen. The product is a :class:`Calibration` that predicts the total force, with its
standard uncertainty, from (current, gap) or from flux.

Shapes: ``n_obs`` observations, ``n_poles`` poles, ``n_params`` parameters of a law. SI units
throughout.
"""

from __future__ import annotations

import json
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from .errors import DataError, DimensionError, FitError, InputError
from .io.atomic import write_text_atomic

__all__ = [
    "ALL_LAWS",
    "FLUX",
    "K_I0_SFE2",
    "K_I2_S2",
    "K_I2_SFE2",
    "LAWS",
    "MU0",
    "POWER",
    "Calibration",
    "CalibrationData",
    "Candidate",
    "ExtrapolationWarning",
    "HeldOutError",
    "Law",
    "LawFit",
    "Prediction",
    "Selection",
    "check_identifiable",
    "fit_law",
    "get_law",
    "held_out_error",
    "ideal_k",
    "predict",
    "predict_flux",
    "report_text",
    "select_law",
]

MU0 = 4.0e-7 * math.pi
"""Magnetic constant [H/m], taken as the exact pre-2019 value 4e-7 pi (the 2019 SI value
differs by about 1e-10 relative, far below any calibration uncertainty)."""

FLOOR_FRACTION = 0.01
"""The relative residual divides by ``max(|F|, floor)`` with ``floor = FLOOR_FRACTION *
median(|F|)``, so that forces near zero do not dominate the fit."""

GAP_TOLERANCE = 1.0e-3
"""Two static gaps closer than this fraction of the median static gap count as one gap."""

_CALIBRATION_FORMAT = "forcecal-calibration"
_CALIBRATION_VERSION = 1


class ExtrapolationWarning(UserWarning):
    """A prediction was asked for outside the currents, gaps or fluxes of the calibration."""


def ideal_k(turns: float, pole_area: float) -> float:
    """The ideal constant of ``f = K i^2 / s^2`` for a U-core electromagnet.

    ``K = MU0 N^2 A / 4`` for two poles of face area ``A`` and a coil of ``N`` turns, the iron
    taken as infinitely permeable and the fringing neglected; ``MU0 = 4e-7 pi`` H/m.

    Parameters
    ----------
    turns : float
        Number of turns N of the coil [-].
    pole_area : float
        Face area A of one pole [m^2].

    Returns
    -------
    float
        K [N m^2/A^2], the force of ONE pole being ``K i^2 / s^2``.
    """
    if turns <= 0 or pole_area <= 0:
        raise InputError(
            f"ideal K needs positive turns and pole area; got turns={turns}, "
            f"pole_area={pole_area} m^2"
        )
    return MU0 * turns**2 * pole_area / 4.0


# --------------------------------------------------------------------------------------------
# Data


def _as_vector(name: str, value: Any, n: int | None) -> np.ndarray:
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
        Run index of each observation, for held-out validation; None means one group.
    force_floor : float [N] or None
        Floor of the relative-residual denominator; None sets it to
        ``FLOOR_FRACTION * median(|force|)``. :meth:`subset` carries it over so that a subset is
        weighted like the whole campaign.
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
        gaps = np.asarray(self.gaps, dtype=float)
        if gaps.ndim == 1:
            gaps = gaps[:, None]
        if gaps.ndim != 2 or gaps.shape[0] != n or gaps.shape[1] < 1:
            raise DimensionError(
                f"calibration data: 'gaps' has shape {gaps.shape}; expected ({n}, n_poles)"
            )
        if not np.all(np.isfinite(gaps)) or np.any(gaps <= 0):
            bad = int(np.count_nonzero(~(np.isfinite(gaps) & (gaps > 0))))
            raise DataError(f"calibration data: 'gaps' has {bad} values that are not positive")
        force = _as_vector("force", self.force, n)
        static_gap = _as_vector("static_gap", self.static_gap, n)
        if np.any(static_gap <= 0):
            raise DataError("calibration data: 'static_gap' has values that are not positive")
        flux = None if self.flux is None else _as_vector("flux", self.flux, n)
        sigma = None if self.sigma is None else _as_vector("sigma", self.sigma, n)
        if sigma is not None and np.any(sigma <= 0):
            raise DataError("calibration data: 'sigma' has values that are not positive")
        if self.group is None:
            group = np.zeros(n, dtype=int)
        else:
            group = np.asarray(self.group)
            if group.shape != (n,):
                raise DimensionError(
                    f"calibration data: 'group' has shape {group.shape}; expected ({n},)"
                )
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
        return np.maximum(np.abs(self.force), self.force_floor)

    @property
    def weights(self) -> np.ndarray:
        """Denominator of the fitted residual: ``sigma`` if given, else :attr:`scale` [N]."""
        return self.scale if self.sigma is None else self.sigma

    def distinct_static_gaps(self) -> np.ndarray:
        """Sorted distinct static gaps [m]; gaps within ``GAP_TOLERANCE`` relative are one."""
        tol = GAP_TOLERANCE * float(np.median(self.static_gap))
        return _cluster(self.static_gap, tol)

    def subset(self, mask: np.ndarray) -> CalibrationData:
        """The observations selected by a boolean mask or index array, same force floor."""

        def pick(a: np.ndarray | None) -> np.ndarray | None:
            return None if a is None else a[mask]

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


# --------------------------------------------------------------------------------------------
# Laws


def _best_amplitude(bases: np.ndarray, data: CalibrationData) -> tuple[np.ndarray, np.ndarray]:
    """Weighted least-squares amplitude ``c`` of ``F ~ c * basis`` for each row of ``bases``.

    ``bases`` is (n_trial, n_obs); returns ``c`` (n_trial,) and the weighted RSS (n_trial,).
    Rows whose basis vanishes get ``c = 0`` and an infinite RSS.
    """
    w = data.weights
    b = bases / w
    y = data.force / w
    norm2 = np.einsum("mn,mn->m", b, b)
    ok = norm2 > 0
    c = np.zeros(b.shape[0])
    c[ok] = (b[ok] @ y) / norm2[ok]
    rss = np.full(b.shape[0], np.inf)
    rss[ok] = np.sum((c[ok, None] * b[ok] - y) ** 2, axis=1)
    return c, rss


def _sfe_grid(data: CalibrationData, n: int) -> np.ndarray:
    """Trial iron-path offsets for start values [m], all keeping ``s + s_fe > 0``."""
    return np.linspace(-0.5 * float(data.gaps.min()), float(np.median(data.static_gap)), n)


def _safe_log(x: np.ndarray) -> np.ndarray:
    """``log(x)`` where ``x > 0``, 0 elsewhere (the factor it multiplies vanishes there)."""
    return np.log(np.where(x > 0, x, 1.0))


@dataclass(frozen=True)
class Law:
    """A force law of one pole, with what it needs from the data to be identifiable.

    Attributes
    ----------
    name : str
        Short identifier, used in files and messages.
    formula : str
        The law in plain text.
    param_names, param_units : tuple of str
        Names and units of the parameters, in the order of every parameter vector.
    needs_gaps : int
        Minimum number of distinct static gaps for the parameters to be identifiable.
    needs_flux : bool
        True when the law predicts from the flux rather than from (current, gap).
    separates : str
        What the distinct gaps are needed for, for the refusal message.
    """

    name: str
    formula: str
    param_names: tuple[str, ...]
    param_units: tuple[str, ...]
    needs_gaps: int
    needs_flux: bool = False
    separates: str = ""

    @property
    def n_params(self) -> int:
        """Number of parameters."""
        return len(self.param_names)

    def per_pole(
        self, params: np.ndarray, i: np.ndarray, s: np.ndarray, phi: np.ndarray | None = None
    ) -> np.ndarray:
        """Force of each pole.

        Parameters
        ----------
        params : (n_params,) array
            Parameters in the order of ``param_names``.
        i : (n_obs,) array [A]
            Coil current.
        s : (n_obs, n_poles) array [m]
            Air gap at each pole.
        phi : (n_obs,) array [Wb] or None
            Flux through one pole (flux law only).

        Returns
        -------
        (n_obs, n_poles) array [N]
        """
        return self._value_and_jacobian(np.asarray(params, dtype=float), i, s, phi)[0]

    def jacobian(
        self, params: np.ndarray, i: np.ndarray, s: np.ndarray, phi: np.ndarray | None = None
    ) -> np.ndarray:
        """Derivatives of :meth:`per_pole` with respect to the parameters, (n_obs, n_poles,
        n_params) [N per parameter unit]."""
        return self._value_and_jacobian(np.asarray(params, dtype=float), i, s, phi)[1]

    def guess(self, data: CalibrationData) -> np.ndarray:
        """Start parameters (n_params,) estimated from the data (a coarse grid over the
        nonlinear parameters, the amplitude solved by linear least squares)."""
        raise NotImplementedError

    def bounds(self, data: CalibrationData) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of the parameters for the fit, each (n_params,)."""
        return np.full(self.n_params, -np.inf), np.full(self.n_params, np.inf)

    def typical(self, params: np.ndarray, data: CalibrationData) -> np.ndarray:
        """Typical magnitude of each parameter (n_params,), to normalise the fit variables."""
        return np.abs(params)

    def gap_offset(self, params: np.ndarray) -> float:
        """The offset added to the gap, ``s_fe`` [m] (0 when the law has none)."""
        if "s_fe" in self.param_names:
            return float(params[self.param_names.index("s_fe")])
        return 0.0

    def _value_and_jacobian(
        self, p: np.ndarray, i: np.ndarray, s: np.ndarray, phi: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError


class _KI2S2(Law):
    """``f = K i^2 / s^2``: the ideal magnet, infinitely permeable iron (METHOD eq. 18)."""

    def _value_and_jacobian(self, p, i, s, phi):
        basis = (i[:, None] / s) ** 2
        return p[0] * basis, basis[..., None]

    def guess(self, data):
        basis = np.sum((data.current[:, None] / data.gaps) ** 2, axis=1)
        c, _ = _best_amplitude(basis[None, :], data)
        return np.array([c[0]])


class _KI2SFE2(Law):
    """``f = K i^2 / (s + s_fe)^2``: the iron path and a probe zero offset as an extra gap."""

    def _value_and_jacobian(self, p, i, s, phi):
        k, sfe = p
        u = s + sfe
        basis = (i[:, None] / u) ** 2
        f = k * basis
        return f, np.stack([basis, -2.0 * f / u], axis=-1)

    def guess(self, data):
        sfe = _sfe_grid(data, 41)
        bases = np.sum(
            (data.current[None, :, None] / (data.gaps[None] + sfe[:, None, None])) ** 2, axis=2
        )
        c, rss = _best_amplitude(bases, data)
        j = int(np.argmin(rss))
        return np.array([c[j], sfe[j]])

    def bounds(self, data):
        return np.array([-np.inf, -0.9 * data.gaps.min()]), np.array([np.inf, np.inf])

    def typical(self, params, data):
        return np.array([abs(params[0]), float(np.median(data.static_gap))])


class _KI0SFE2(Law):
    """``f = K (i + i0)^2 / (s + s_fe)^2``: remanence as a current offset."""

    def _value_and_jacobian(self, p, i, s, phi):
        k, i0, sfe = p
        u = s + sfe
        ii = (i + i0)[:, None]
        basis = (ii / u) ** 2
        f = k * basis
        return f, np.stack([basis, 2.0 * k * ii / u**2, -2.0 * f / u], axis=-1)

    def guess(self, data):
        sfe = _sfe_grid(data, 21)
        i_max = float(np.max(np.abs(data.current)))
        i0 = np.linspace(-0.3, 0.3, 13) * i_max
        ii = data.current[None, None, :, None] + i0[:, None, None, None]
        uu = data.gaps[None, None] + sfe[None, :, None, None]
        bases = np.sum((ii / uu) ** 2, axis=3).reshape(-1, data.n_obs)
        c, rss = _best_amplitude(bases, data)
        j = int(np.argmin(rss))
        a, b = np.unravel_index(j, (i0.size, sfe.size))
        return np.array([c[j], i0[a], sfe[b]])

    def bounds(self, data):
        lo = np.array([-np.inf, -np.inf, -0.9 * data.gaps.min()])
        return lo, np.full(3, np.inf)

    def typical(self, params, data):
        i_rms = float(np.sqrt(np.mean(data.current**2)))
        return np.array([abs(params[0]), i_rms, float(np.median(data.static_gap))])


class _Power(Law):
    """``f = K |i|^a / (s + s_fe)^b``, free exponents (empirical).

    ``s_fe`` is included so that the empirical law contains the others: ``a = b = 2`` gives
    ``k_i2_sfe2`` and, with ``s_fe = 0``, ``k_i2_s2``.
    """

    def _value_and_jacobian(self, p, i, s, phi):
        k, a, b, sfe = p
        u = s + sfe
        ai = np.abs(i)[:, None]
        base = ai**a * u ** (-b)
        f = k * base
        return f, np.stack([base, f * _safe_log(ai), -f * np.log(u), -b * f / u], axis=-1)

    def guess(self, data):
        k, sfe = K_I2_SFE2.guess(data)
        return np.array([k, 2.0, 2.0, sfe])

    def bounds(self, data):
        lo = np.array([-np.inf, 0.1, 0.1, -0.9 * data.gaps.min()])
        hi = np.array([np.inf, 8.0, 8.0, np.inf])
        return lo, hi

    def typical(self, params, data):
        return np.array([abs(params[0]), 1.0, 1.0, float(np.median(data.static_gap))])


class _Flux(Law):
    """``f = phi^2 / (MU0 A_eff)``: Maxwell's pull from the flux, independent of the gap.

    Every pole carries the flux ``phi`` measured through one pole, so the total is ``n_poles``
    times the force of one pole.
    """

    def _value_and_jacobian(self, p, i, s, phi):
        if phi is None:
            raise InputError(f"law '{self.name}' needs the flux through a pole")
        area = p[0]
        f = (phi**2 / (MU0 * area))[:, None] * np.ones_like(s)
        return f, (-f / area)[..., None]

    def guess(self, data):
        if data.flux is None:
            raise FitError(f"law '{self.name}' needs the flux through a pole; the data have none")
        basis = data.n_poles * data.flux**2 / MU0
        c, _ = _best_amplitude(basis[None, :], data)
        if not c[0] > 0:
            raise FitError(
                f"law '{self.name}': the forces are not positive where the flux is, so no "
                "positive effective area fits them"
            )
        return np.array([1.0 / c[0]])

    def bounds(self, data):
        return np.array([0.0]), np.array([np.inf])


K_I2_S2 = _KI2S2("k_i2_s2", "f = K i^2 / s^2", ("K",), ("N m^2/A^2",), needs_gaps=1)
K_I2_SFE2 = _KI2SFE2(
    "k_i2_sfe2",
    "f = K i^2 / (s + s_fe)^2",
    ("K", "s_fe"),
    ("N m^2/A^2", "m"),
    needs_gaps=2,
    separates="to separate K from s_fe",
)
K_I0_SFE2 = _KI0SFE2(
    "k_i0_sfe2",
    "f = K (i + i0)^2 / (s + s_fe)^2",
    ("K", "i0", "s_fe"),
    ("N m^2/A^2", "A", "m"),
    needs_gaps=2,
    separates="to separate K from s_fe",
)
POWER = _Power(
    "power",
    "f = K |i|^a / (s + s_fe)^b",
    ("K", "a", "b", "s_fe"),
    ("N m^b/A^a", "-", "-", "m"),
    needs_gaps=3,
    separates="to separate K, b and s_fe",
)
FLUX = _Flux("flux", "f = phi^2 / (mu0 A_eff)", ("A_eff",), ("m^2",), needs_gaps=0, needs_flux=True)

ALL_LAWS: tuple[Law, ...] = (K_I2_S2, K_I2_SFE2, K_I0_SFE2, POWER, FLUX)
"""Every law, simplest first."""

LAWS: dict[str, Law] = {law.name: law for law in ALL_LAWS}


def get_law(name: str) -> Law:
    """The law called ``name``; InputError listing the known names otherwise."""
    try:
        return LAWS[name]
    except KeyError:
        raise InputError(f"unknown actuator law '{name}'; known: {', '.join(LAWS)}") from None


# --------------------------------------------------------------------------------------------
# Fitting


def _total(law: Law, params: np.ndarray, data: CalibrationData) -> np.ndarray:
    """Model of the total force (n_obs,) [N]."""
    return law.per_pole(params, data.current, data.gaps, data.flux).sum(axis=1)


def _format_gaps(gaps: np.ndarray) -> str:
    return ", ".join(f"{1e3 * g:.3f}" for g in gaps) + " mm"


def check_identifiable(law: Law, data: CalibrationData) -> None:
    """Raise FitError, in one line, when ``data`` cannot identify the parameters of ``law``.

    Checks the flux (flux law), the number of distinct static gaps (``law.needs_gaps``; two
    suffice in principle to separate K from s_fe, but the two are strongly correlated and
    METHOD.md section 5 asks a campaign for at least three) and the number of observations.
    """
    if law.needs_flux and data.flux is None:
        raise FitError(f"law '{law.name}' needs the flux through a pole; the campaign has none")
    gaps = data.distinct_static_gaps()
    if gaps.size < law.needs_gaps:
        raise FitError(
            f"law '{law.name}' needs at least {law.needs_gaps} distinct static gaps "
            f"{law.separates}; the campaign has {gaps.size} ({_format_gaps(gaps)})"
        )
    if data.n_obs <= law.n_params:
        raise FitError(
            f"law '{law.name}' has {law.n_params} parameters; the campaign has only "
            f"{data.n_obs} observations"
        )


@dataclass(frozen=True)
class LawFit:
    """The result of fitting one law.

    Attributes
    ----------
    law : Law
    params : (n_params,) array
        Fitted parameters, units as ``law.param_units``.
    covariance : (n_params, n_params) array
        Parameter covariance, ``s^2 (J^T J)^-1`` with ``s^2`` the residual variance.
    stderr : (n_params,) array
        Standard uncertainties, the square roots of the covariance diagonal.
    correlation : (n_params, n_params) array
    residuals : (n_obs,) array [-]
        Relative residuals ``(F_model - F) / max(|F|, floor)``.
    rss : float
        Sum of squares of the fitted (weighted) residuals.
    aic, bic : float
        Gaussian information criteria, ``n ln(rss/n) + 2 p`` and ``n ln(rss/n) + p ln n``.
    rms_residual : float [-]
        RMS relative residual.
    n_obs, n_poles : int
    current_range : (float, float) [A]
        Smallest and largest current fitted.
    gap_range : (float, float) [m]
        Smallest and largest pole gap fitted.
    flux_range : (float, float) [Wb] or None
        Smallest and largest flux fitted, when measured.
    nfev : int
        Number of model evaluations.
    """

    law: Law
    params: np.ndarray
    covariance: np.ndarray
    stderr: np.ndarray
    correlation: np.ndarray
    residuals: np.ndarray
    rss: float
    aic: float
    bic: float
    rms_residual: float
    n_obs: int
    n_poles: int
    current_range: tuple[float, float]
    gap_range: tuple[float, float]
    flux_range: tuple[float, float] | None
    nfev: int

    @property
    def params_dict(self) -> dict[str, float]:
        """Parameters by name."""
        return {n: float(v) for n, v in zip(self.law.param_names, self.params, strict=True)}

    def total(self, data: CalibrationData) -> np.ndarray:
        """The fitted model's total force for ``data``, (n_obs,) [N]."""
        _check_gap_offset(self.law, self.params, data.gaps)
        return _total(self.law, self.params, data)


def _check_gap_offset(law: Law, params: np.ndarray, gaps: np.ndarray) -> None:
    sfe = law.gap_offset(params)
    if not law.needs_flux and np.any(gaps + sfe <= 0):
        raise InputError(
            f"law '{law.name}': a gap of {1e3 * float(gaps.min()):.4f} mm plus s_fe = "
            f"{1e3 * sfe:.4f} mm is not positive; the law is singular there"
        )


def fit_law(law: Law, data: CalibrationData) -> LawFit:
    """Fit a law to the total force by nonlinear least squares on relative residuals.

    The residual of observation k is ``(F_model_k - F_k) / w_k`` with ``w_k = max(|F_k|, floor)``
    (or ``sigma_k`` when the data carry uncertainties); the model of the total is the law summed
    over the poles. The fit runs on parameters normalised by their typical magnitude, with
    ``scipy.optimize.least_squares`` (trust region, analytic Jacobian, ``x_scale='jac'``).

    Parameters
    ----------
    law : Law
    data : CalibrationData

    Returns
    -------
    LawFit

    Raises
    ------
    FitError
        When the data cannot identify the law (too few distinct static gaps, no flux for the flux
        law, too few observations, parameters the data cannot separate) or the fit fails.
    """
    check_identifiable(law, data)
    p0 = np.asarray(law.guess(data), dtype=float)
    scale = np.asarray(law.typical(p0, data), dtype=float)
    if not np.all(np.isfinite(p0)) or not np.all(scale > 0):
        raise FitError(f"law '{law.name}': no usable start values from the data ({p0})")
    lo, hi = law.bounds(data)
    lo_x, hi_x = lo / scale, hi / scale
    margin = 1e-6 * np.maximum(np.abs(p0 / scale), 1.0)
    x0 = np.clip(p0 / scale, lo_x + margin, hi_x - margin)
    w = data.weights

    def residual(x: np.ndarray) -> np.ndarray:
        return (_total(law, x * scale, data) - data.force) / w

    def jacobian(x: np.ndarray) -> np.ndarray:
        jac = law.jacobian(x * scale, data.current, data.gaps, data.flux).sum(axis=1)
        return jac / w[:, None] * scale

    sol = least_squares(
        residual,
        x0,
        jac=jacobian,
        bounds=(lo_x, hi_x),
        method="trf",
        x_scale="jac",
        ftol=1e-14,
        xtol=1e-14,
        gtol=1e-14,
        max_nfev=200 * law.n_params,
    )
    if sol.status <= 0:
        raise FitError(f"law '{law.name}': the fit did not converge ({sol.message})")
    params = sol.x * scale
    jac = jacobian(sol.x)
    col = np.linalg.norm(jac, axis=0)
    if not np.all(col > 0):
        raise FitError(
            f"law '{law.name}': the data do not constrain "
            + ", ".join(n for n, c in zip(law.param_names, col, strict=True) if not c > 0)
        )
    _, sv, vt = np.linalg.svd(jac / col, full_matrices=False)
    if sv[-1] < 1e-10 * sv[0]:
        raise FitError(
            f"law '{law.name}': the data cannot separate its parameters "
            f"(condition number {sv[0] / sv[-1]:.1e})"
        )
    r = residual(sol.x)
    n, p = data.n_obs, law.n_params
    rss = float(r @ r)
    cov_x = (vt.T / sv**2) @ vt / np.outer(col, col) * (rss / (n - p))
    cov = cov_x * np.outer(scale, scale)
    stderr = np.sqrt(np.diag(cov))
    norm = np.outer(stderr, stderr)
    corr = np.divide(cov, norm, out=np.zeros_like(cov), where=norm > 0)
    np.fill_diagonal(corr, 1.0)
    rel = (_total(law, params, data) - data.force) / data.scale
    log_l = n * math.log(max(rss, np.finfo(float).tiny) / n)
    flux_range = None
    if data.flux is not None:
        flux_range = (float(data.flux.min()), float(data.flux.max()))
    return LawFit(
        law=law,
        params=params,
        covariance=cov,
        stderr=stderr,
        correlation=corr,
        residuals=rel,
        rss=rss,
        aic=log_l + 2 * p,
        bic=log_l + p * math.log(n),
        rms_residual=float(np.sqrt(np.mean(rel**2))),
        n_obs=n,
        n_poles=data.n_poles,
        current_range=(float(data.current.min()), float(data.current.max())),
        gap_range=(float(data.gaps.min()), float(data.gaps.max())),
        flux_range=flux_range,
        nfev=int(sol.nfev),
    )


# --------------------------------------------------------------------------------------------
# Held-out validation and selection


@dataclass(frozen=True)
class HeldOutError:
    """RMS relative error of the predicted total on held-out data.

    Attributes
    ----------
    rms : float [-]
        RMS over the held-out groups of ``per_group``.
    labels : (n_groups,) array
        The held-out group labels (run indices), or fold numbers for k-fold.
    per_group : (n_groups,) array [-]
        RMS relative error of the predicted total on each held-out group.
    scheme : str
        ``"leave-one-group-out"`` or ``"k-fold"``.
    """

    rms: float
    labels: np.ndarray
    per_group: np.ndarray
    scheme: str

    def __float__(self) -> float:
        return self.rms


N_FOLDS = 5
"""Folds of the k-fold scheme used when the campaign has fewer than three groups."""


def held_out_error(law: Law, data: CalibrationData) -> HeldOutError:
    """Error of the law's prediction on data left out of the fit.

    With three groups (runs) or more, each group is left out in turn (leave-one-group-out);
    otherwise the observations are split into ``N_FOLDS`` interleaved folds (every
    ``N_FOLDS``-th sample), so that every training set keeps every static gap. For each held-out
    set the law is fitted on the rest and the RMS relative error ``(F_pred - F) / max(|F|,
    floor)`` of the predicted total is taken.

    Returns
    -------
    HeldOutError
        Its ``rms`` (also ``float(result)``) is the RMS over the held-out sets [-].

    Raises
    ------
    FitError
        When the law is not identifiable from the data, or from a training set.
    """
    check_identifiable(law, data)
    labels = np.unique(data.group)
    if labels.size >= 3:
        scheme = "leave-one-group-out"
        masks = [data.group == g for g in labels]
    else:
        scheme = "k-fold"
        k = min(N_FOLDS, data.n_obs)
        labels = np.arange(k)
        masks = [np.arange(data.n_obs) % k == j for j in range(k)]
    errors = np.empty(len(masks))
    for j, (label, test) in enumerate(zip(labels, masks, strict=True)):
        try:
            fit = fit_law(law, data.subset(~test))
            held = data.subset(test)
            pred = fit.total(held)
        except (FitError, InputError) as exc:
            raise FitError(f"held-out set {label} ({scheme}): {exc}") from exc
        errors[j] = np.sqrt(np.mean(((pred - held.force) / held.scale) ** 2))
    return HeldOutError(
        rms=float(np.sqrt(np.mean(errors**2))), labels=labels, per_group=errors, scheme=scheme
    )


@dataclass(frozen=True)
class Candidate:
    """One fitted law of a selection, with its scores."""

    fit: LawFit
    held_out: HeldOutError

    @property
    def name(self) -> str:
        """Name of the law."""
        return self.fit.law.name

    @property
    def n_params(self) -> int:
        """Number of parameters of the law."""
        return self.fit.law.n_params

    def row(self) -> dict[str, Any]:
        """The JSON-ready summary: name, formula, parameters, uncertainties and scores."""
        law = self.fit.law
        return {
            "law": law.name,
            "formula": law.formula,
            "params": self.fit.params_dict,
            "stderr": {
                n: _finite_or_none(v) for n, v in zip(law.param_names, self.fit.stderr, strict=True)
            },
            "aic": _finite_or_none(self.fit.aic),
            "bic": _finite_or_none(self.fit.bic),
            "held_out": _finite_or_none(self.held_out.rms),
            "rms_residual": _finite_or_none(self.fit.rms_residual),
        }


def _finite_or_none(x: float) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


@dataclass(frozen=True)
class Selection:
    """The laws fitted to a campaign and the one chosen.

    Attributes
    ----------
    candidates : tuple of Candidate
        Every law that could be fitted and validated, in the order tried.
    skipped : tuple of (str, str)
        ``(law name, reason)`` for every law left out (not identifiable, fit failed).
    chosen : str
        Name of the chosen law.
    reason : str
        Why it was chosen.
    tolerance : float [-]
        Held-out error margin within which a simpler law is preferred.
    """

    candidates: tuple[Candidate, ...]
    skipped: tuple[tuple[str, str], ...]
    chosen: str
    reason: str
    tolerance: float

    @property
    def best(self) -> Candidate:
        """The chosen candidate."""
        return next(c for c in self.candidates if c.name == self.chosen)

    def calibration(self) -> Calibration:
        """The calibration of the chosen law, carrying the table of every candidate."""
        rows = [c.row() for c in self.candidates]
        rows += [{"law": name, "skipped": why} for name, why in self.skipped]
        return Calibration.from_fit(self.best.fit, candidates=tuple(rows))


HELD_OUT_ABS_TOL = 1.0e-4
"""Absolute held-out error margin (relative force units) for preferring a simpler law."""
HELD_OUT_REL_TOL = 0.10
"""Relative held-out error margin for preferring a simpler law."""


def select_law(data: CalibrationData, laws: Sequence[Law] = ALL_LAWS) -> Selection:
    """Fit every identifiable law and choose the simplest one that predicts held-out runs well.

    Each law is fitted (:func:`fit_law`) and validated (:func:`held_out_error`). The chosen law
    is the one with the fewest parameters whose held-out error is within ``max(HELD_OUT_ABS_TOL,
    HELD_OUT_REL_TOL * best)`` of the best held-out error; ties go to the lowest BIC.

    Raises
    ------
    FitError
        When no law can be fitted; the message gives each law's reason.
    """
    candidates: list[Candidate] = []
    skipped: list[tuple[str, str]] = []
    for law in laws:
        try:
            fit = fit_law(law, data)
            held = held_out_error(law, data)
        except FitError as exc:
            skipped.append((law.name, str(exc)))
            continue
        candidates.append(Candidate(fit=fit, held_out=held))
    if not candidates:
        raise FitError("no actuator law can be fitted: " + "; ".join(why for _, why in skipped))
    best = min(candidates, key=lambda c: c.held_out.rms)
    tol = max(HELD_OUT_ABS_TOL, HELD_OUT_REL_TOL * best.held_out.rms)
    good = [c for c in candidates if c.held_out.rms <= best.held_out.rms + tol]
    chosen = min(good, key=lambda c: (c.n_params, c.fit.bic))
    reason = (
        f"'{chosen.name}' is the simplest law ({chosen.n_params} parameter"
        f"{'s' if chosen.n_params > 1 else ''}) whose held-out "
        f"error {100 * chosen.held_out.rms:.3f} % is within {100 * tol:.3f} % of the best "
        f"({100 * best.held_out.rms:.3f} %, '{best.name}')"
    )
    return Selection(
        candidates=tuple(candidates),
        skipped=tuple(skipped),
        chosen=chosen.name,
        reason=reason,
        tolerance=tol,
    )


def report_text(selection: Selection, k_ideal: float | None = None) -> str:
    """A plain-text table of the candidates of a selection.

    Parameters
    ----------
    selection : Selection
    k_ideal : float or None [N m^2/A^2]
        The ideal K (:func:`ideal_k`), printed beside the fitted K when given.

    Returns
    -------
    str
        Lines separated by newlines, ending with a newline.
    """
    head = f"{'law':<11} {'n_par':>5} {'rms res %':>10} {'held-out %':>11} {'AIC':>11} {'BIC':>11}"
    lines = ["Actuator law selection", head, "-" * len(head)]
    for c in selection.candidates:
        mark = "  <- chosen" if c.name == selection.chosen else ""
        lines.append(
            f"{c.name:<11} {c.n_params:>5d} {100 * c.fit.rms_residual:>10.4f} "
            f"{100 * c.held_out.rms:>11.4f} {c.fit.aic:>11.1f} {c.fit.bic:>11.1f}{mark}"
        )
    lines.append("")
    for c in selection.candidates:
        law = c.fit.law
        parts = [
            f"{n} = {v:.6g} +/- {e:.2g} {u}"
            for n, v, e, u in zip(
                law.param_names, c.fit.params, c.fit.stderr, law.param_units, strict=True
            )
        ]
        lines.append(f"{c.name}: {law.formula}; " + "; ".join(parts))
    for name, why in selection.skipped:
        lines.append(f"{name}: skipped, {why}")
    if k_ideal is not None:
        lines.append(f"ideal K = mu0 N^2 A / 4 = {k_ideal:.6g} N m^2/A^2")
    lines.append(f"chosen: {selection.reason}")
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------------------------
# Calibration and prediction


def _pair(value: Any, what: str) -> tuple[float, float]:
    arr = np.asarray(value, dtype=float)
    if arr.shape != (2,) or not np.all(np.isfinite(arr)):
        raise InputError(f"{what} must be two finite numbers [lo, hi]; found {value!r}")
    return float(arr[0]), float(arr[1])


@dataclass(frozen=True, eq=False)
class Calibration:
    """A calibrated actuator law: what predicts force from (current, gap) or from flux.

    Attributes
    ----------
    law : str
        Name of the law (see :data:`LAWS`).
    params : (n_params,) array
        Parameters, units as the law's ``param_units``.
    covariance : (n_params, n_params) array
    n_poles : int
    current_range : (float, float) [A]
        Currents the law was fitted on; predictions outside warn.
    gap_range : (float, float) [m]
        Pole gaps the law was fitted on; predictions outside warn.
    flux_range : (float, float) [Wb] or None
        Fluxes the law was fitted on, when measured.
    candidates : tuple of dict
        The selection table (one JSON-ready row per law, skipped laws with their reason).
    """

    law: str
    params: np.ndarray
    covariance: np.ndarray
    n_poles: int
    current_range: tuple[float, float]
    gap_range: tuple[float, float]
    flux_range: tuple[float, float] | None = None
    candidates: tuple[dict[str, Any], ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        law = get_law(self.law)
        params = np.asarray(self.params, dtype=float)
        cov = np.asarray(self.covariance, dtype=float)
        p = law.n_params
        if params.shape != (p,) or cov.shape != (p, p):
            raise DimensionError(
                f"calibration '{self.law}': params {params.shape} and covariance {cov.shape}; "
                f"expected ({p},) and ({p}, {p})"
            )
        if not (np.all(np.isfinite(params)) and np.all(np.isfinite(cov))):
            raise InputError(f"calibration '{self.law}': parameters or covariance not finite")
        if int(self.n_poles) < 1:
            raise InputError(f"calibration '{self.law}': n_poles = {self.n_poles} < 1")
        object.__setattr__(self, "params", params)
        object.__setattr__(self, "covariance", cov)
        object.__setattr__(self, "n_poles", int(self.n_poles))
        object.__setattr__(self, "candidates", tuple(self.candidates))

    @classmethod
    def from_fit(cls, fit: LawFit, candidates: tuple[dict[str, Any], ...] = ()) -> Calibration:
        """The calibration of a fitted law."""
        return cls(
            law=fit.law.name,
            params=fit.params.copy(),
            covariance=fit.covariance.copy(),
            n_poles=fit.n_poles,
            current_range=fit.current_range,
            gap_range=fit.gap_range,
            flux_range=fit.flux_range,
            candidates=candidates,
        )

    @property
    def law_object(self) -> Law:
        """The :class:`Law` called :attr:`law`."""
        return get_law(self.law)

    @property
    def stderr(self) -> np.ndarray:
        """Standard uncertainties of the parameters (n_params,)."""
        return np.sqrt(np.diag(self.covariance))

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready dict; :meth:`from_json` reads it back exactly."""
        law = self.law_object
        return {
            "format": _CALIBRATION_FORMAT,
            "version": _CALIBRATION_VERSION,
            "law": law.name,
            "formula": law.formula,
            "param_names": list(law.param_names),
            "param_units": list(law.param_units),
            "params": {n: float(v) for n, v in zip(law.param_names, self.params, strict=True)},
            "stderr": {n: float(v) for n, v in zip(law.param_names, self.stderr, strict=True)},
            "covariance": self.covariance.tolist(),
            "n_poles": self.n_poles,
            "current_range": list(self.current_range),
            "gap_range": list(self.gap_range),
            "flux_range": None if self.flux_range is None else list(self.flux_range),
            "candidates": [dict(row) for row in self.candidates],
        }

    @classmethod
    def from_json(cls, obj: dict[str, Any], source: str = "<dict>") -> Calibration:
        """Read a calibration from :meth:`to_json`'s dict.

        Raises
        ------
        InputError
            Naming ``source`` and the key at fault.
        """
        if not isinstance(obj, dict):
            raise InputError(f"calibration '{source}': expected a JSON object")
        for key in ("law", "params", "covariance", "n_poles", "current_range", "gap_range"):
            if key not in obj:
                raise InputError(f"calibration '{source}': missing key '{key}'")
        try:
            law = get_law(obj["law"])
            params = obj["params"]
            if not isinstance(params, dict):
                raise InputError("key 'params' must map parameter names to values")
            missing = [n for n in law.param_names if n not in params]
            if missing:
                raise InputError(f"key 'params' lacks {', '.join(missing)} for law '{law.name}'")
            flux_range = obj.get("flux_range")
            return cls(
                law=law.name,
                params=np.array([float(params[n]) for n in law.param_names]),
                covariance=np.array(obj["covariance"], dtype=float),
                n_poles=int(obj["n_poles"]),
                current_range=_pair(obj["current_range"], "key 'current_range'"),
                gap_range=_pair(obj["gap_range"], "key 'gap_range'"),
                flux_range=None if flux_range is None else _pair(flux_range, "key 'flux_range'"),
                candidates=tuple(dict(row) for row in obj.get("candidates", [])),
            )
        except (InputError, DimensionError, TypeError, ValueError) as exc:
            raise InputError(f"calibration '{source}': {exc}") from exc

    def save(self, path: str | Path) -> Path:
        """Write the calibration as JSON, atomically; returns the path."""
        text = json.dumps(self.to_json(), indent=2, allow_nan=False)
        return write_text_atomic(path, text + "\n")

    @classmethod
    def load(cls, path: str | Path) -> Calibration:
        """Read a calibration written by :meth:`save`.

        Raises
        ------
        InputError
            Naming the file, when it is missing, not JSON, or lacks a key.
        """
        path = Path(path)
        try:
            text = path.read_text(encoding="utf-8")
        except FileNotFoundError:
            raise InputError(f"calibration file '{path}' not found") from None
        except (OSError, UnicodeDecodeError) as exc:
            raise InputError(f"calibration file '{path}' cannot be read: {exc}") from None
        try:
            obj = json.loads(text)
        except json.JSONDecodeError as exc:
            raise InputError(
                f"calibration file '{path}' is not valid JSON: {exc.msg} at line {exc.lineno}"
            ) from None
        return cls.from_json(obj, source=str(path))


@dataclass(frozen=True)
class Prediction:
    """Predicted actuator force.

    Attributes
    ----------
    total : (n,) array [N]
        Total force, summed over the poles.
    per_pole : (n, n_poles) array [N]
        Force of each pole.
    std : (n,) array [N]
        Standard uncertainty of ``total`` from the parameter covariance (delta method).
    """

    total: np.ndarray
    per_pole: np.ndarray
    std: np.ndarray


def _warn_outside(
    values: np.ndarray, bounds: tuple[float, float], what: str, unit: str, factor: float
) -> None:
    lo, hi = bounds
    slack = 1e-9 * max(abs(lo), abs(hi))
    vmin, vmax = float(values.min()), float(values.max())
    if vmin < lo - slack or vmax > hi + slack:
        warnings.warn(
            f"{what} from {factor * vmin:.4g} to {factor * vmax:.4g} {unit} lies outside the "
            f"calibrated range {factor * lo:.4g} to {factor * hi:.4g} {unit}; extrapolating",
            ExtrapolationWarning,
            stacklevel=3,
        )


def _propagate(
    law: Law, cal: Calibration, i: np.ndarray, s: np.ndarray, phi: np.ndarray | None
) -> Prediction:
    per_pole, jac = law._value_and_jacobian(cal.params, i, s, phi)
    grad = jac.sum(axis=1)
    var = np.einsum("np,pq,nq->n", grad, cal.covariance, grad)
    return Prediction(
        total=per_pole.sum(axis=1), per_pole=per_pole, std=np.sqrt(np.maximum(var, 0.0))
    )


def predict(calibration: Calibration, current: Any, gaps: Any) -> Prediction:
    """Total and per-pole force from coil current and air gaps, with its uncertainty.

    Parameters
    ----------
    calibration : Calibration
        A calibration of a (current, gap) law.
    current : float or (n,) array [A]
    gaps : float, (n_poles,), (n, 1) or (n, n_poles) array [m]
        Air gap at each pole; a scalar means every pole at that gap.

    Returns
    -------
    Prediction
        Arrays over the n predictions; ``std`` propagates the parameter covariance through the
        gradient of the total (delta method).

    Warns
    -----
    ExtrapolationWarning
        When a current or gap lies outside the calibrated range.
    """
    law = calibration.law_object
    if law.needs_flux:
        raise InputError(f"calibration law '{law.name}' predicts from flux; use predict_flux")
    i = np.atleast_1d(np.asarray(current, dtype=float))
    g = np.asarray(gaps, dtype=float)
    if i.ndim != 1:
        raise DimensionError(f"current has shape {i.shape}; expected a scalar or (n,)")
    n = max(i.size, g.shape[0] if g.ndim == 2 else 1)
    try:
        i = np.broadcast_to(i, (n,))
        s = np.broadcast_to(g, (n, calibration.n_poles))
    except ValueError:
        raise DimensionError(
            f"current {i.shape} and gaps {g.shape} do not fit {calibration.n_poles} poles; "
            "expected gaps as a scalar, (n_poles,), (n, 1) or (n, n_poles)"
        ) from None
    if not (np.all(np.isfinite(i)) and np.all(np.isfinite(s))):
        raise InputError("current and gaps must be finite")
    _check_gap_offset(law, calibration.params, s)
    _warn_outside(i, calibration.current_range, "current", "A", 1.0)
    _warn_outside(s, calibration.gap_range, "gap", "mm", 1e3)
    return _propagate(law, calibration, i, s, None)


def predict_flux(calibration: Calibration, flux: Any) -> Prediction:
    """Total and per-pole force from the flux through one pole, for the flux law.

    Parameters
    ----------
    calibration : Calibration
        A calibration of the flux law.
    flux : float or (n,) array [Wb]

    Returns
    -------
    Prediction
        ``total = n_poles * per-pole``; ``std`` by the delta method.

    Warns
    -----
    ExtrapolationWarning
        When a flux lies outside the calibrated range.
    """
    law = calibration.law_object
    if not law.needs_flux:
        raise InputError(f"calibration law '{law.name}' predicts from current and gap; use predict")
    phi = np.atleast_1d(np.asarray(flux, dtype=float))
    if phi.ndim != 1 or not np.all(np.isfinite(phi)):
        raise InputError(f"flux must be finite, a scalar or (n,); got shape {phi.shape}")
    if calibration.flux_range is not None:
        _warn_outside(phi, calibration.flux_range, "flux", "Wb", 1.0)
    s = np.ones((phi.size, calibration.n_poles))
    return _propagate(law, calibration, np.zeros(phi.size), s, phi)
