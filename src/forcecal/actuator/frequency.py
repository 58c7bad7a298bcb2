"""The actuator's law over frequency: eddy currents in the core lower and delay the force.

The magnetising current ``i_m`` follows the coil current through the core's response
``H(s; tau)`` (:mod:`.frequency_models`: first order, ``tau di_m/dt + i_m = i``, or half
order, a solid core), and the total force is ``f = K i_m^2 sum_p 1 / (s_p + s_fe)^2`` (the law
``k_i2_sfe2`` with ``i_m`` for ``i``). A steady run at f0 whose current has phasors I_n has
``I_m,n = H(j n 2 pi f0) I_n``. Small-signal, at a fixed gap, the force's component at f over
i^2's is ``H(j 2 pi f)``: ``K(f) = K |H|``, lagging by ``-angle(H)`` (METHOD.md section 5).

A stepped-sine campaign gives one :class:`SteadyRecord` per run: the current, the gaps and the
reconstructed total force at ``n`` instants over exactly one period of the run's fundamental
(:meth:`SteadyRecord.from_samples`), with the standard uncertainty of the force's harmonic
phasors. :func:`forcecal.actuator.frequency_fit.fit_frequency_law` fits them into a
:class:`FrequencyLaw`: K, s_fe and tau with their covariance, the calibrated frequency range
and a table of :class:`FrequencyStep`, the non-parametric K(f) and lag(f) at every step. A
calibration file carries the law as its ``frequency_law`` (:meth:`FrequencyLaw.to_json`).

Shapes: ``n`` instants per run, ``n_poles`` poles, ``H+1`` harmonics 0..H. SI units
throughout (lags in degrees where the name says ``deg``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import DimensionError, InputError
from ..schema.calibration_file import check_frequency_law
from .frequency_models import FREQUENCY_MODELS, frequency_model
from .gaps import fourier_series

__all__ = ["FrequencyLaw", "SteadyRecord"]

FREQUENCY_PARAM_NAMES = ("K", "s_fe", "tau")
"""The parameters of a :class:`FrequencyLaw`, in the order of its covariance."""
FREQUENCY_PARAM_UNITS = ("N m^2/A^2", "m", "s")
_TWO_PI = 2.0 * math.pi
MATCHED = 13.8
"""The chi-square of a step's gain and lag against the law (2 degrees of freedom) beyond which
the law does not match that step: chance exceeds it at a 1e-3 rate."""


@dataclass(frozen=True)
class SteadyRecord:
    """One steady run of a stepped-sine campaign: one period of its current, gaps and force.

    Attributes
    ----------
    f0 : float [Hz]
        The run's (refined) fundamental.
    current : (n,) array [A]
        Coil current at ``n`` instants spread evenly over exactly one period.
    gaps : (n, n_poles) array [m]
        Air gap at every pole at those instants ((n,) means one pole).
    force : (n,) array [N]
        Reconstructed total actuator force at those instants.
    force_std : (H+1,) array [N] or None
        Standard uncertainty of the force's phasors F_0..F_H (Re and Im each; the DC real).
        A scalar is the same for every harmonic; its length sets H. White noise of standard
        deviation sigma on each of the ``n`` instants gives ``sigma sqrt(2 / n)``
        (``sigma / sqrt(n)`` for the DC). ``inf``: the harmonic is not measured (the
        reconstruction holds none there) and does not enter the fit. None: the scatter of the
        fit sets the level.
    n_harmonics : int or None
        H, the force harmonics fitted; None takes ``len(force_std) - 1``, else the highest
        harmonic of the force or the current above round-off (a Fourier series of H harmonics
        gives H).
    name : str
        The run, for the messages.
    shared : tuple of (str, (n,) array, (n, n_poles) array)
        Errors this run shares with others, each per standard uncertainty: its name (runs'
        errors with one name are one error), and its change of the force and of the gaps at
        the ``n`` instants. :func:`forcecal.actuator.frequency_fit.fit_frequency_law` adds
        them to the parameters' covariance.
    """

    f0: float
    current: np.ndarray
    gaps: np.ndarray
    force: np.ndarray
    force_std: np.ndarray | float | None = None
    n_harmonics: int | None = None
    name: str = ""
    shared: tuple[tuple[str, np.ndarray, np.ndarray], ...] = ()

    def __post_init__(self) -> None:
        what = f"record '{self.name}'" if self.name else "record"
        i = np.asarray(self.current, dtype=float)
        f = np.asarray(self.force, dtype=float)
        g = np.asarray(self.gaps, dtype=float)
        g = g[:, None] if g.ndim == 1 else g
        n = i.size
        if i.shape != (n,) or f.shape != (n,) or g.ndim != 2 or g.shape[0] != n or n < 4:
            raise DimensionError(f"{what}: current {i.shape}, gaps {g.shape}, force {f.shape}; "
                                 "expected (n,), (n, n_poles), (n,) with n >= 4")
        if not (math.isfinite(self.f0) and self.f0 > 0):
            raise InputError(f"{what}: fundamental f0 = {self.f0!r} Hz is not a positive number")
        if not (np.all(np.isfinite(i)) and np.all(np.isfinite(f)) and np.all(np.isfinite(g))):
            raise InputError(f"{what}: current, gaps and force must be finite")
        if np.any(g <= 0):
            raise InputError(f"{what}: gaps must be positive lengths [m]")
        h_max = (n - 1) // 2
        h = self.n_harmonics
        std = None if self.force_std is None else np.atleast_1d(
            np.asarray(self.force_std, dtype=float))
        if h is None:
            h = std.size - 1 if std is not None and std.size > 1 else _highest_harmonic(i, f)
        if not 0 <= int(h) <= h_max:
            raise InputError(f"{what}: {h} harmonics cannot be resolved from {n} instants "
                             f"(at most {h_max})")
        h = int(h)
        if std is not None:
            if std.size == 1:
                std = np.full(h + 1, float(std[0]))
            if (std.shape != (h + 1,) or np.any(np.isnan(std)) or np.any(std <= 0)
                    or not np.any(np.isfinite(std))):
                raise InputError(f"{what}: force_std must hold {h + 1} positive values, finite "
                                 f"or inf where a harmonic is not measured (harmonics 0..{h}), "
                                 f"found {std.shape}")
        shared = []
        for label, df, dg in self.shared:
            df, dg = np.asarray(df, dtype=float), np.asarray(dg, dtype=float)
            dg = dg[:, None] if dg.ndim == 1 else dg
            if df.shape != (n,) or dg.shape != g.shape or not (
                    np.all(np.isfinite(df)) and np.all(np.isfinite(dg))):
                raise InputError(f"{what}: shared error '{label}' must give finite changes of "
                                 f"the force {(n,)} and the gaps {g.shape}")
            shared.append((str(label), df, dg))
        for key, value in (("current", i), ("gaps", g), ("force", f), ("force_std", std),
                           ("n_harmonics", h), ("f0", float(self.f0)),
                           ("shared", tuple(shared))):
            object.__setattr__(self, key, value)

    @classmethod
    def from_samples(cls, samples: Any, f0: float | None = None,
                     force_std: Any = None, name: str = "") -> SteadyRecord:
        """The record of one run's calibration samples.

        Parameters
        ----------
        samples : CalibrationSamples
            Or any object with ``time``, ``current``, ``gaps``, ``force`` (and ``noise``).
        f0 : float or None [Hz]
            The run's fundamental; None reads it off the instants (``n`` spread over one
            period).
        force_std : float, (H+1,) array or None [N]
            The force phasors' uncertainty; None takes the run's independent force noise
            (``samples.noise``: the estimate's budget and the probes' noise through the
            coordinates, their effect on the force; ``inf`` at the harmonics the estimate
            does not hold) when described. The errors the run
            shares with others (the tare's, the scan shapes', the rig's type-B) come from
            ``samples.noise`` too.
        name : str
            The run.

        Returns
        -------
        SteadyRecord
        """
        t = np.asarray(samples.time, dtype=float)
        if f0 is None:
            if t.size < 2 or not t[-1] > t[0]:
                raise InputError(f"record '{name}': no fundamental and no increasing instants")
            f0 = (t.size - 1) / (t.size * float(t[-1] - t[0]))
        noise = getattr(samples, "noise", None)
        if force_std is None and noise is not None:
            force_std = _noise_std(noise)
        shared: tuple[tuple[str, np.ndarray, np.ndarray], ...] = ()
        if noise is not None:
            shared = tuple(
                (e.name, fourier_series(e.total, f0, t),
                 -fourier_series(e.motion, f0, t).T)          # the gap is s_0 - w
                for e in (*getattr(noise, "shared", ()), *getattr(noise, "type_b", ())))
        return cls(f0=float(f0), current=samples.current, gaps=samples.gaps,
                   force=samples.force, force_std=force_std, name=name, shared=shared)

    @property
    def n(self) -> int:
        """Number of instants."""
        return int(np.size(self.current))

    @property
    def harmonics(self) -> int:
        """H, the force harmonics fitted."""
        return int(self.n_harmonics or 0)

    @property
    def static_gap(self) -> float:
        """The mean gap over the period and the poles [m]."""
        return float(np.mean(self.gaps))


def _highest_harmonic(*signals: np.ndarray) -> int:
    """The highest harmonic of the signals (one period each) above round-off."""
    h = 0
    for x in signals:
        c = np.abs(np.fft.rfft(x)[: (x.size - 1) // 2 + 1])
        above = np.flatnonzero(c[1:] > 1e-9 * max(float(c.max()), 1e-300))
        h = max(h, int(above[-1]) + 1 if above.size else 0)
    return h


def _noise_std(noise: Any) -> np.ndarray | None:
    """(H+1,) [N]: a run's independent noise of the total force's phasors (RunNoise), ``inf``
    at the harmonics its estimate does not hold (``noise.estimated``: set to zero, not
    measured); None when a harmonic it holds has no noise stated."""
    parts = [np.asarray(s, dtype=float) for s in noise.force_std.values()]
    if not parts:
        return None
    var = np.sum([p**2 for p in parts], axis=0)
    for c in getattr(noise, "coordinates", ()):
        if int(c.harmonic) < var.size:
            var[int(c.harmonic)] += float(np.real(np.conj(c.force) @ c.cov @ c.force))
    held = getattr(noise, "estimated", None)
    held = np.ones(var.size, dtype=bool) if held is None else np.asarray(held, dtype=bool)
    if not np.all(var[held] > 0):
        return None
    return np.where(held, np.sqrt(var), np.inf)


# --------------------------------------------------------------------------------------------
# the result


@dataclass(frozen=True)
class FrequencyStep:
    """The non-parametric response at one frequency step.

    Attributes
    ----------
    frequency : float [Hz]
        Mean fundamental of the step's runs.
    n_runs : int
        Runs of the step.
    gain, gain_std : float [-]
        ``K(f) / K``, the gain of the magnetising current's fundamental, and its standard
        uncertainty.
    k, k_std : float [N m^2/A^2]
        ``K(f)`` and its standard uncertainty.
    lag_deg, lag_deg_std : float [deg]
        The force's lag behind i^2 at f, and its standard uncertainty.
    """

    frequency: float
    n_runs: int
    gain: float
    gain_std: float
    k: float
    k_std: float
    lag_deg: float
    lag_deg_std: float


def _as_array(frequency: Any) -> np.ndarray:
    f = np.asarray(frequency, dtype=float)
    if not np.all(np.isfinite(f)) or np.any(f < 0):
        raise InputError(f"frequency must be finite and not negative [Hz]; found {frequency!r}")
    return f


@dataclass(frozen=True, eq=False)
class FrequencyLaw:
    """The actuator's law over frequency: ``K(f) = K |H(j 2 pi f)|``, lagging by
    ``-angle(H)``, ``H`` its ``model``'s (first order: ``K / sqrt(1 + (2 pi f tau)^2)``).

    Attributes
    ----------
    k : float [N m^2/A^2]
        K at zero frequency, per pole (``f = K i_m^2 / (s + s_fe)^2``).
    s_fe : float [m]
        Iron-path offset of the gap.
    tau : float [s]
        Time constant of the magnetising current's lag (first order), or the core's
        diffusion time ``sigma mu d^2`` (half order).
    covariance : (3, 3) array
        Covariance of (K, s_fe, tau).
    n_poles : int
        Poles the total force sums over.
    frequency_range : (float, float) [Hz]
        The fundamentals fitted.
    current_range, gap_range : (float, float) [A], [m]
        The currents and gaps fitted.
    steps : tuple of FrequencyStep
        The non-parametric response per frequency step, by frequency.
    chi2 : float or None
        Chi-square of the global fit (the weighted residuals).
    dof : int
        Its degrees of freedom (harmonic values minus parameters).
    covariance_scale : float
        The factor ``c`` applied to ``(J^T J)^-1`` (see
        :func:`~forcecal.actuator.frequency_fit.fit_frequency_law`).
    model : str
        The core's response, a name of :data:`.frequency_models.FREQUENCY_MODELS`:
        ``"first-order"`` or ``"half-order"``.
    candidates : tuple of dict
        Every model tried, with its parameters and scores (held-out error, AIC, BIC), as the
        calibration file's ``frequency_law.selection.candidates``; empty when one model was
        fitted.
    reason : str
        Why ``model`` was chosen (empty when one model was fitted).
    """

    k: float
    s_fe: float
    tau: float
    covariance: np.ndarray
    n_poles: int
    frequency_range: tuple[float, float]
    current_range: tuple[float, float]
    gap_range: tuple[float, float]
    steps: tuple[FrequencyStep, ...] = ()
    chi2: float | None = None
    dof: int = 0
    covariance_scale: float = 1.0
    model: str = "first-order"
    candidates: tuple[dict[str, Any], ...] = ()
    reason: str = ""

    def __post_init__(self) -> None:
        frequency_model(self.model)
        cov = np.asarray(self.covariance, dtype=float)
        if cov.shape != (3, 3) or not np.all(np.isfinite(cov)):
            raise DimensionError(f"frequency law: covariance {cov.shape}; expected finite (3, 3)")
        if not all(math.isfinite(v) for v in (self.k, self.s_fe, self.tau)):
            raise InputError("frequency law: K, s_fe and tau must be finite")
        object.__setattr__(self, "covariance", cov)
        object.__setattr__(self, "steps", tuple(self.steps))
        object.__setattr__(self, "candidates", tuple(self.candidates))

    @property
    def params(self) -> np.ndarray:
        """(K, s_fe, tau)."""
        return np.array([self.k, self.s_fe, self.tau])

    @property
    def stderr(self) -> np.ndarray:
        """Standard uncertainties of (K, s_fe, tau)."""
        return np.sqrt(np.diag(self.covariance))

    def __repr__(self) -> str:
        """One line: the parameters with their standard uncertainties and the range."""
        text = ", ".join(f"{n} = {v:.6g} ± {e:.2g} {u}" for n, v, e, u in zip(
            FREQUENCY_PARAM_NAMES, self.params, self.stderr, FREQUENCY_PARAM_UNITS, strict=True))
        lo, hi = self.frequency_range
        return (f"FrequencyLaw({self.model}: {text}; {lo:.4g} to {hi:.4g} Hz, "
                f"{len(self.steps)} steps)")

    def _gain(self, frequency: Any) -> tuple[np.ndarray, np.ndarray]:
        """``|H|`` and its derivative with respect to tau at ``frequency`` [Hz]."""
        h, dh = FREQUENCY_MODELS[self.model].response(_TWO_PI * _as_array(frequency), self.tau)
        g = np.abs(h)
        return g, (h.real * dh.real + h.imag * dh.imag) / g

    def gain(self, frequency: Any) -> tuple[np.ndarray, np.ndarray]:
        """``K(f) / K = |H(j 2 pi f)|`` (first order: ``1 / sqrt(1 + (2 pi f tau)^2)``) and its
        standard uncertainty (tau's).

        Parameters
        ----------
        frequency : float or array [Hz]

        Returns
        -------
        gain, std : arrays shaped as ``frequency`` [-]
        """
        g, dg = self._gain(frequency)
        return g, np.abs(dg) * self.stderr[2]

    def k_at(self, frequency: Any) -> tuple[np.ndarray, np.ndarray]:
        """``K(f)`` [N m^2/A^2] and its standard uncertainty (K's and tau's, correlated).

        Parameters
        ----------
        frequency : float or array [Hz]

        Returns
        -------
        k, std : arrays shaped as ``frequency``
        """
        g, dg = self._gain(frequency)
        grad = np.stack([g, np.zeros_like(g), self.k * dg], -1)
        var = np.einsum("...p,pq,...q->...", grad, self.covariance, grad)
        return self.k * g, np.sqrt(np.maximum(var, 0.0))

    def lag_deg(self, frequency: Any) -> tuple[np.ndarray, np.ndarray]:
        """The force's lag behind i^2, ``-angle(H)`` [deg] (first order:
        ``atan(2 pi f tau)``), and its standard uncertainty.

        Parameters
        ----------
        frequency : float or array [Hz]

        Returns
        -------
        lag, std : arrays shaped as ``frequency`` [deg]
        """
        h, dh = FREQUENCY_MODELS[self.model].response(_TWO_PI * _as_array(frequency), self.tau)
        std = np.abs((dh / np.where(h == 0, 1.0, h)).imag) * self.stderr[2]
        return -np.degrees(np.angle(h)), np.degrees(std)

    def departures(self) -> list[tuple[FrequencyStep, float, float, float]]:
        """Every step the law does not match within their uncertainties: (step, the law's
        K(f) / K less the step's [-], its lag less the step's [deg], the chi-square of both
        against :data:`MATCHED`), each difference over the step's and the law's uncertainty
        added (the law's from tau's, which the steps do not share)."""
        out = []
        for st in self.steps:
            g, g_std = self.gain(st.frequency)
            lag, lag_std = self.lag_deg(st.frequency)
            dg, dl = float(g) - st.gain, float(lag) - st.lag_deg
            chi2 = (dg**2 / (st.gain_std**2 + float(g_std) ** 2 + 1e-300)
                    + dl**2 / (st.lag_deg_std**2 + float(lag_std) ** 2 + 1e-300))
            if chi2 > MATCHED:
                out.append((st, dg, dl, chi2))
        return out

    def forces(self, current: np.ndarray, gaps: np.ndarray, frequency: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The force with K replaced by K(f): ``K(f) i^2 / (s + s_fe)^2`` at each pole.

        Parameters
        ----------
        current : (n,) array [A]
        gaps : (n, n_poles) array [m]
        frequency : (n,) array [Hz]

        Returns
        -------
        total : (n,) array [N]
        per_pole : (n, n_poles) array [N]
        std : (n,) array [N]
            Of ``total``, from the covariance of (K, s_fe, tau) (delta method).
        """
        if np.any(gaps + self.s_fe <= 0):
            raise InputError(f"frequency law: a gap of {1e3 * float(gaps.min()):.4f} mm plus "
                             f"s_fe = {1e3 * self.s_fe:.4f} mm is not positive")
        g, dg = self._gain(frequency)
        u = gaps + self.s_fe
        basis = current[:, None] ** 2 / u**2
        per_pole = self.k * g[:, None] * basis
        b = basis.sum(axis=1)
        grad = np.stack([g * b, -2.0 * self.k * g * np.sum(basis / u, axis=1),
                         self.k * dg * b], axis=-1)
        var = np.einsum("np,pq,nq->n", grad, self.covariance, grad)
        return per_pole.sum(axis=1), per_pole, np.sqrt(np.maximum(var, 0.0))

    def periodic_force(self, current: Any, gaps: Any, f0: float) -> np.ndarray:
        """The total force of a steady run, lag included, at its instants over one period.

        Parameters
        ----------
        current : (n,) array [A]
            Coil current at ``n`` instants spread evenly over one period.
        gaps : (n, n_poles) array [m]
            Air gap at every pole at those instants.
        f0 : float [Hz]
            The fundamental.

        Returns
        -------
        (n,) array [N]
        """
        rec = SteadyRecord(f0=f0, current=current, gaps=gaps, force=np.zeros(np.size(current)),
                           n_harmonics=0)
        spectrum = np.fft.rfft(rec.current)
        h, _ = FREQUENCY_MODELS[self.model].response(
            _TWO_PI * rec.f0 * np.arange(spectrum.size), self.tau)
        im = np.fft.irfft(spectrum * h, n=rec.n)
        return np.asarray(self.k * im**2 * np.sum((rec.gaps + self.s_fe) ** -2.0, axis=1))

    def to_json(self) -> dict[str, Any]:
        """The law as a JSON-ready dict (the ``frequency_law`` of a calibration file).

        Returns
        -------
        dict
            What :meth:`from_json` reads back exactly.
        """
        names = FREQUENCY_PARAM_NAMES
        selection = {} if not self.candidates else {
            "selection": {"reason": self.reason, "candidates": [dict(c) for c in self.candidates]}}
        return {
            "model": FREQUENCY_MODELS[self.model].formula, "frequency_model": self.model,
            **selection,
            "param_names": list(names), "param_units": list(FREQUENCY_PARAM_UNITS),
            "params": dict(zip(names, map(float, self.params), strict=True)),
            "stderr": dict(zip(names, map(float, self.stderr), strict=True)),
            "covariance": self.covariance.tolist(), "n_poles": self.n_poles,
            "frequency_range": list(self.frequency_range),
            "current_range": list(self.current_range), "gap_range": list(self.gap_range),
            "chi2": self.chi2, "dof": self.dof, "covariance_scale": self.covariance_scale,
            "steps": [{key: getattr(s, key) for key in _STEP_KEYS} for s in self.steps],
        }

    @classmethod
    def from_json(cls, obj: Any, source: str = "<dict>") -> FrequencyLaw:
        """Read the law :meth:`to_json` wrote.

        Parameters
        ----------
        obj : dict
            The decoded object.
        source : str
            The calibration file, for the messages.

        Returns
        -------
        FrequencyLaw

        Raises
        ------
        InputError
            Naming ``source`` and the key at fault (``frequency_law.params.tau``), checked
            against the file's schema (:mod:`forcecal.schema.calibration_file`).

        Notes
        -----
        A file without ``frequency_model`` (written before there was a choice) is first
        order.
        """
        law = check_frequency_law(obj, source)
        p = law.params
        steps = tuple(FrequencyStep(*(getattr(s, k) for k in _STEP_KEYS)) for s in law.steps)
        sel = law.selection
        return cls(
            k=p.K, s_fe=p.s_fe, tau=p.tau, covariance=np.array(law.covariance), steps=steps,
            n_poles=law.n_poles, chi2=law.chi2, dof=law.dof,
            covariance_scale=law.covariance_scale, model=law.frequency_model,
            candidates=() if sel is None else tuple(
                c.model_dump(exclude_unset=True) for c in sel.candidates),
            reason="" if sel is None else sel.reason,
            frequency_range=(law.frequency_range[0], law.frequency_range[1]),
            current_range=(law.current_range[0], law.current_range[1]),
            gap_range=(law.gap_range[0], law.gap_range[1]))


_STEP_KEYS = ("frequency", "n_runs", "gain", "gain_std", "k", "k_std", "lag_deg",
              "lag_deg_std")

