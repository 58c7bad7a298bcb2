"""Force laws of one pole of the electromagnet (METHOD.md section 5).

A :class:`Law` gives the force of one pole from the coil current and the pole's air gap (or from
the flux through the pole), its derivatives with respect to the parameters, start values guessed
from the data, bounds, and how many distinct static gaps it needs to be identifiable. The model
of the total force is the law summed over the poles.

Shapes: ``n_obs`` observations, ``n_poles`` poles, ``n_params`` parameters of a law. SI units
throughout.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import FitError, InputError
from .data import CalibrationData

__all__ = [
    "ALL_LAWS",
    "FLUX",
    "K_I0_SFE2",
    "K_I2_S2",
    "K_I2_SFE2",
    "LAWS",
    "MU0",
    "POWER",
    "Law",
    "ideal_k",
]

MU0 = 4.0e-7 * math.pi
"""Magnetic constant [H/m], taken as the exact pre-2019 value 4e-7 pi (the 2019 SI value
differs by about 1e-10 relative, far below any calibration uncertainty)."""


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

    Raises
    ------
    InputError
        When ``turns`` or ``pole_area`` is not positive.
    """
    if turns <= 0 or pole_area <= 0:
        raise InputError(
            f"ideal K needs positive turns and pole area; got turns={turns}, "
            f"pole_area={pole_area} m^2"
        )
    return MU0 * turns**2 * pole_area / 4.0


# --------------------------------------------------------------------------------------------
# Start values


def _best_amplitude(bases: np.ndarray, data: CalibrationData) -> tuple[np.ndarray, np.ndarray]:
    """Weighted least-squares amplitude ``c`` of ``F ~ c * basis`` for each row of ``bases``.

    Rows whose basis vanishes get ``c = 0`` and an infinite RSS.

    Parameters
    ----------
    bases : (n_trial, n_obs) array [N per unit amplitude]
        Trial shapes of the total force.
    data : CalibrationData
        The observations.

    Returns
    -------
    c : (n_trial,) array
        Best amplitude of each trial.
    rss : (n_trial,) array
        Weighted residual sum of squares of each trial.
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
    """Trial iron-path offsets for start values, (n,) [m], all keeping ``s + s_fe > 0``."""
    return np.linspace(-0.5 * float(data.gaps.min()), float(np.median(data.static_gap)), n)


def _safe_log(x: np.ndarray) -> np.ndarray:
    """``log(x)`` where ``x > 0``, 0 elsewhere (the factor it multiplies vanishes there)."""
    return np.log(np.where(x > 0, x, 1.0))


# --------------------------------------------------------------------------------------------
# Laws


@dataclass(frozen=True)
class Law:
    """A force law of one pole, with what it needs from the data to be identifiable.

    Attributes
    ----------
    name : str
        Short identifier, used in files and messages.
    formula : str
        The law in plain text.
    param_names : tuple of str
        Names of the parameters, in the order of every parameter vector.
    param_units : tuple of str
        Units of the parameters, in the same order.
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
            The force of every pole at every observation.
        """
        return self._value_and_jacobian(np.asarray(params, dtype=float), i, s, phi)[0]

    def jacobian(
        self, params: np.ndarray, i: np.ndarray, s: np.ndarray, phi: np.ndarray | None = None
    ) -> np.ndarray:
        """Derivatives of :meth:`per_pole` with respect to the parameters.

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
        (n_obs, n_poles, n_params) array [N per parameter unit]
            The derivative of every pole's force with respect to every parameter.
        """
        return self._value_and_jacobian(np.asarray(params, dtype=float), i, s, phi)[1]

    def guess(self, data: CalibrationData) -> np.ndarray:
        """Start parameters estimated from the data.

        A coarse grid over the nonlinear parameters, the amplitude solved by linear least
        squares.

        Parameters
        ----------
        data : CalibrationData
            The observations.

        Returns
        -------
        (n_params,) array
            Start parameters in the order of ``param_names``.
        """
        raise NotImplementedError

    def bounds(self, data: CalibrationData) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of the parameters for the fit.

        Parameters
        ----------
        data : CalibrationData
            The observations (some bounds depend on the smallest gap).

        Returns
        -------
        lo : (n_params,) array
            Lower bounds.
        hi : (n_params,) array
            Upper bounds.
        """
        return np.full(self.n_params, -np.inf), np.full(self.n_params, np.inf)

    def typical(self, params: np.ndarray, data: CalibrationData) -> np.ndarray:
        """Typical magnitude of each parameter, to normalise the fit variables.

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
        return np.abs(params)

    def gap_offset(self, params: np.ndarray) -> float:
        """The offset added to the gap, ``s_fe``.

        Parameters
        ----------
        params : (n_params,) array
            Parameters in the order of ``param_names``.

        Returns
        -------
        float [m]
            ``s_fe``, or 0 when the law has none.
        """
        if "s_fe" in self.param_names:
            return float(params[self.param_names.index("s_fe")])
        return 0.0

    def check_gap_offset(self, params: np.ndarray, gaps: np.ndarray) -> None:
        """Refuse gaps where the law is singular (a gap plus ``s_fe`` not positive).

        Parameters
        ----------
        params : (n_params,) array
            Parameters in the order of ``param_names``.
        gaps : (n, n_poles) array [m]
            Air gap at each pole.

        Raises
        ------
        InputError
            Naming the smallest gap and ``s_fe``.
        """
        sfe = self.gap_offset(params)
        if not self.needs_flux and np.any(gaps + sfe <= 0):
            raise InputError(
                f"law '{self.name}': a gap of {1e3 * float(gaps.min()):.4f} mm plus s_fe = "
                f"{1e3 * sfe:.4f} mm is not positive; the law is singular there"
            )

    def check_fitted(self, params: np.ndarray, data: CalibrationData) -> None:
        """Refuse fitted parameters that the data do not determine (none by default).

        Raises
        ------
        FitError
            In one line, naming the parameter and why.
        """

    def _value_and_jacobian(
        self, p: np.ndarray, i: np.ndarray, s: np.ndarray, phi: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Force of each pole (n_obs, n_poles) and its Jacobian (n_obs, n_poles, n_params)."""
        raise NotImplementedError


class _KI2S2(Law):
    """``f = K i^2 / s^2``: the ideal magnet, infinitely permeable iron (METHOD eq. 18)."""

    def _value_and_jacobian(
        self, p: np.ndarray, i: np.ndarray, s: np.ndarray, phi: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        basis = (i[:, None] / s) ** 2
        return p[0] * basis, basis[..., None]

    def guess(self, data: CalibrationData) -> np.ndarray:
        basis = np.sum((data.current[:, None] / data.gaps) ** 2, axis=1)
        c, _ = _best_amplitude(basis[None, :], data)
        return np.array([c[0]])


class _KI2SFE2(Law):
    """``f = K i^2 / (s + s_fe)^2``: the iron path and a probe zero offset as an extra gap."""

    def _value_and_jacobian(
        self, p: np.ndarray, i: np.ndarray, s: np.ndarray, phi: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        k, sfe = p
        u = s + sfe
        basis = (i[:, None] / u) ** 2
        f = k * basis
        return f, np.stack([basis, -2.0 * f / u], axis=-1)

    def guess(self, data: CalibrationData) -> np.ndarray:
        sfe = _sfe_grid(data, 41)
        bases = np.sum(
            (data.current[None, :, None] / (data.gaps[None] + sfe[:, None, None])) ** 2, axis=2
        )
        c, rss = _best_amplitude(bases, data)
        j = int(np.argmin(rss))
        return np.array([c[j], sfe[j]])

    def bounds(self, data: CalibrationData) -> tuple[np.ndarray, np.ndarray]:
        return np.array([-np.inf, -0.9 * data.gaps.min()]), np.array([np.inf, np.inf])

    def typical(self, params: np.ndarray, data: CalibrationData) -> np.ndarray:
        return np.array([abs(params[0]), float(np.median(data.static_gap))])


class _KI0SFE2(Law):
    """``f = K (i + i0)^2 / (s + s_fe)^2``: remanence as a current offset."""

    def _value_and_jacobian(
        self, p: np.ndarray, i: np.ndarray, s: np.ndarray, phi: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        k, i0, sfe = p
        u = s + sfe
        ii = (i + i0)[:, None]
        basis = (ii / u) ** 2
        f = k * basis
        return f, np.stack([basis, 2.0 * k * ii / u**2, -2.0 * f / u], axis=-1)

    def guess(self, data: CalibrationData) -> np.ndarray:
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

    def bounds(self, data: CalibrationData) -> tuple[np.ndarray, np.ndarray]:
        lo = np.array([-np.inf, -np.inf, -0.9 * data.gaps.min()])
        return lo, np.full(3, np.inf)

    def typical(self, params: np.ndarray, data: CalibrationData) -> np.ndarray:
        i_rms = float(np.sqrt(np.mean(data.current**2)))
        return np.array([abs(params[0]), i_rms, float(np.median(data.static_gap))])


class _Power(Law):
    """``f = K |i|^a / (s + s_fe)^b``, free exponents (empirical).

    ``s_fe`` is included so that the empirical law contains the others: ``a = b = 2`` gives
    ``k_i2_sfe2`` and, with ``s_fe = 0``, ``k_i2_s2``.
    """

    def _value_and_jacobian(
        self, p: np.ndarray, i: np.ndarray, s: np.ndarray, phi: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        k, a, b, sfe = p
        u = s + sfe
        ai = np.abs(i)[:, None]
        base = ai**a * u ** (-b)
        f = k * base
        return f, np.stack([base, f * _safe_log(ai), -f * np.log(u), -b * f / u], axis=-1)

    def guess(self, data: CalibrationData) -> np.ndarray:
        k, sfe = K_I2_SFE2.guess(data)
        return np.array([k, 2.0, 2.0, sfe])

    def bounds(self, data: CalibrationData) -> tuple[np.ndarray, np.ndarray]:
        lo = np.array([-np.inf, 0.1, 0.1, -0.9 * data.gaps.min()])
        hi = np.array([np.inf, 8.0, 8.0, np.inf])
        return lo, hi

    def typical(self, params: np.ndarray, data: CalibrationData) -> np.ndarray:
        return np.array([abs(params[0]), 1.0, 1.0, float(np.median(data.static_gap))])


KNEE_REACH = 10.0
"""How far beyond the data's largest ``i / s`` the saturating law's knee may lie: beyond it the
data show no saturation and the law is not fitted."""


class _Saturating(Law):
    """``f = K x^2 / (1 + (|x| / x_s)^q)^(2/q)``, ``x = i / (s + s_fe)``: ``k_i2_sfe2`` whose flux
    density is limited softly as the iron saturates.

    ``x`` is the flux density the current would give without saturation, up to a constant
    (``B = mu0 N x / 2`` on a U-core of two poles); the flux density bends over near ``x_s``
    (the iron's knee), with the sharpness ``q``, towards a force that no longer grows with the
    current. For ``x`` well below ``x_s`` it is ``k_i2_sfe2``.
    """

    def _value_and_jacobian(
        self, p: np.ndarray, i: np.ndarray, s: np.ndarray, phi: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        k, sfe, xs, q = p
        g = s + sfe
        x = i[:, None] / g
        ratio = np.abs(x) / xs
        log_ratio = _safe_log(ratio)
        u = np.where(ratio > 0, np.exp(np.clip(q * log_ratio, -700.0, 700.0)), 0.0)
        f = k * x**2 * (1.0 + u) ** (-2.0 / q)
        return f, np.stack([f / k, -2.0 * f / ((1.0 + u) * g), 2.0 * f * u / ((1.0 + u) * xs),
                            f * (2.0 / q**2 * np.log1p(u) - 2.0 / q * u * log_ratio / (1.0 + u))],
                           axis=-1)

    def guess(self, data: CalibrationData) -> np.ndarray:
        k, sfe = K_I2_SFE2.guess(data)
        return np.array([k, sfe, 1.5 * self._x_max(data, sfe), 4.0])

    def bounds(self, data: CalibrationData) -> tuple[np.ndarray, np.ndarray]:
        reach = KNEE_REACH * self._x_max(data, 0.0)
        lo = np.array([-np.inf, -0.9 * data.gaps.min(), 0.0, 2.0])
        return lo, np.array([np.inf, np.inf, reach, 20.0])

    def check_fitted(self, params: np.ndarray, data: CalibrationData) -> None:
        hi = self.bounds(data)[1]
        if params[2] >= 0.99 * hi[2]:
            raise FitError(
                f"law '{self.name}': the data show no saturation (the knee x_s is beyond "
                f"{KNEE_REACH:g} times the largest i / s, {hi[2] / KNEE_REACH:.4g} A/m)")
        if params[3] >= 0.99 * hi[3]:
            raise FitError(
                f"law '{self.name}': the data show no saturation (no knee: its sharpness q "
                f"reaches its bound {hi[3]:g}, a step at the data's largest i / s)")

    @staticmethod
    def _x_max(data: CalibrationData, sfe: float) -> float:
        """The largest ``|i| / (s + s_fe)`` of the data [A/m]."""
        return float(np.max(np.abs(data.current)[:, None] / (data.gaps + sfe)))

    def typical(self, params: np.ndarray, data: CalibrationData) -> np.ndarray:
        return np.array([abs(params[0]), float(np.median(data.static_gap)), abs(params[2]), 1.0])


class _Flux(Law):
    """``f = phi^2 / (MU0 A_eff)``: Maxwell's pull from the flux, independent of the gap.

    Every pole carries the flux ``phi`` measured through one pole, so the total is ``n_poles``
    times the force of one pole.
    """

    def _value_and_jacobian(
        self, p: np.ndarray, i: np.ndarray, s: np.ndarray, phi: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray]:
        if phi is None:
            raise InputError(f"law '{self.name}' needs the flux through a pole")
        area = p[0]
        f = (phi**2 / (MU0 * area))[:, None] * np.ones_like(s)
        return f, (-f / area)[..., None]

    def guess(self, data: CalibrationData) -> np.ndarray:
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

    def bounds(self, data: CalibrationData) -> tuple[np.ndarray, np.ndarray]:
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
SATURATING = _Saturating(
    "k_i2_sfe2_sat",
    "f = K x^2 / (1 + (|x| / x_s)^q)^(2/q), x = i / (s + s_fe)",
    ("K", "s_fe", "x_s", "q"),
    ("N m^2/A^2", "m", "A/m", "-"),
    needs_gaps=2,
    separates="to separate K from s_fe",
)
FLUX = _Flux("flux", "f = phi^2 / (mu0 A_eff)", ("A_eff",), ("m^2",), needs_gaps=0, needs_flux=True)

ALL_LAWS: tuple[Law, ...] = (K_I2_S2, K_I2_SFE2, K_I0_SFE2, POWER, SATURATING, FLUX)
"""Every law, simplest first."""

LAWS: dict[str, Law] = {law.name: law for law in ALL_LAWS}
"""Every law by name."""


def get_law(name: str) -> Law:
    """The law called ``name``.

    Parameters
    ----------
    name : str
        Name of the law (a key of :data:`LAWS`).

    Returns
    -------
    Law
        One of :data:`ALL_LAWS`.

    Raises
    ------
    InputError
        Listing the known names, when there is no such law.
    """
    try:
        return LAWS[name]
    except KeyError:
        raise InputError(f"unknown actuator law '{name}'; known: {', '.join(LAWS)}") from None
