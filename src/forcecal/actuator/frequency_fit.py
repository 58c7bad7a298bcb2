"""Fitting the actuator's law over frequency: :func:`fit_frequency_law` (METHOD.md section 5).

The model is :mod:`forcecal.actuator.frequency`'s: ``I_m = H(s; tau) I`` with the core's
response ``H`` (:mod:`.frequency_models`: first or half order) and
``f = K i_m^2 sum_p 1 / (s_p + s_fe)^2``. The instants of a run are a Fourier series of a few
phasors, not independent observations, so K, s_fe and tau are fitted over all runs at once to
the force's harmonic phasors, each weighted by its standard uncertainty; their covariance
counts harmonic values, not instants, and adds the errors runs share. Every model is fitted
and scored on frequency steps left out of its fit, and one is chosen
(:mod:`.frequency_selection`). A second fit frees the gain and the lag of the magnetising
current's fundamental per frequency step: the non-parametric K(f) and lag(f). The fit, its
uncertainty, the choice and the steps are told in :func:`fit_frequency_law`'s notes.

Shapes: ``n`` instants per run, ``n_poles`` poles, ``H+1`` harmonics 0..H, ``R`` runs. SI
units throughout.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from ..errors import DimensionError, FitError, InputError
from .data import GAP_TOLERANCE
from .frequency import FrequencyLaw, FrequencyStep, SteadyRecord
from .frequency_models import FREQUENCY_MODELS, FrequencyModel, frequency_model
from .frequency_selection import ModelScore, candidate_rows, choose_model

__all__ = ["STEP_TOLERANCE", "fit_frequency_law"]

STEP_TOLERANCE = 0.01
"""Runs whose fundamentals differ by less than this fraction are one frequency step."""
_TWO_PI = 2.0 * math.pi


# --------------------------------------------------------------------------------------------
# the model of a stack of runs sharing the number of instants


@dataclass(frozen=True)
class _Stack:
    """Runs with the same number of instants ``n``, as arrays over the runs (R of them)."""

    index: np.ndarray     # (R,) the runs' positions among the records
    f0: np.ndarray        # (R,) [Hz]
    current: np.ndarray   # (R, n//2 + 1) complex: rfft of the current
    gaps: np.ndarray      # (R, n, n_poles) [m]
    force: np.ndarray     # (R, H+1) complex [N]: the measured phasors
    weight: np.ndarray    # (R, H+1) [1/N]: 1 / std, 0 beyond a run's own H or not measured

    @property
    def bins(self) -> np.ndarray:
        """(R, n//2 + 1) [rad/s]: the angular frequency of every DFT bin of every run."""
        return _TWO_PI * self.f0[:, None] * np.arange(self.current.shape[1])

    def real(self, z: np.ndarray) -> np.ndarray:
        """Weighted Re of every harmonic then Im of harmonics >= 1, as one real vector; ``z``
        is (R, H+1) or (R, p, H+1) (then (m, p))."""
        w = self.weight if z.ndim == 2 else self.weight[:, None, :]
        zw = z * w
        if z.ndim == 2:
            return np.concatenate([zw.real.ravel(), zw[:, 1:].imag.ravel()])
        p = z.shape[1]
        re = zw.real.transpose(0, 2, 1).reshape(-1, p)
        im = zw[:, :, 1:].imag.transpose(0, 2, 1).reshape(-1, p)
        return np.concatenate([re, im])


def _phasors(x: np.ndarray, h: int) -> np.ndarray:
    """One-sided phasors 0..h over the last axis of samples spanning one period."""
    c = np.fft.rfft(x, axis=-1)[..., : h + 1] / x.shape[-1]
    c[..., 1:] *= 2.0
    return c


def _model(st: _Stack, k: float, s_fe: float, filt: np.ndarray,
           dfilt: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Modelled force phasors (R, H+1) and their derivatives (R, p, H+1) with respect to K,
    s_fe and every filter parameter; ``filt`` (R, n//2 + 1) takes I_n to I_m,n."""
    n, h = st.gaps.shape[1], st.force.shape[1] - 1
    im = np.fft.irfft(st.current * filt, n=n)
    u = st.gaps + s_fe
    q = np.sum(u**-2.0, axis=-1)
    cols = [im**2 * q, -2.0 * k * im**2 * np.sum(u**-3.0, axis=-1)]
    cols += [2.0 * k * im * q * np.fft.irfft(st.current * d, n=n) for d in dfilt]
    return _phasors(k * im**2 * q, h), _phasors(np.stack(cols, axis=1), h)


def _lag_filter(st: _Stack, model: FrequencyModel, tau: float
                ) -> tuple[np.ndarray, np.ndarray]:
    """The core's response at every bin and its derivative with respect to tau."""
    return model.response(st.bins, tau)


def _n_values(records: Sequence[SteadyRecord], weighted: bool) -> int:
    """The harmonic values the records give the fit: the DC and Re and Im of every harmonic
    1..H, each where measured (``force_std`` finite) when weighted."""
    if not weighted:
        return sum(2 * r.harmonics + 1 for r in records)
    measured = [np.isfinite(np.asarray(r.force_std, dtype=float)) for r in records]
    return sum(int(m[0]) + 2 * int(np.sum(m[1:])) for m in measured)


def _stacks(records: Sequence[SteadyRecord], weighted: bool) -> list[_Stack]:
    """The records grouped by their number of instants."""
    out = []
    for n in sorted({r.n for r in records}):
        idx = np.array([k for k, r in enumerate(records) if r.n == n])
        h_max = max(records[k].harmonics for k in idx)
        force = np.zeros((idx.size, h_max + 1), dtype=np.complex128)
        weight = np.zeros((idx.size, h_max + 1))
        for row, k in enumerate(idx):
            r = records[k]
            h = r.harmonics
            force[row, : h + 1] = _phasors(r.force, h)
            std = r.force_std if weighted else np.r_[1.0 / math.sqrt(2.0), np.ones(h)]
            weight[row, : h + 1] = 1.0 / np.asarray(std)
        out.append(_Stack(
            index=idx, f0=np.array([records[k].f0 for k in idx]),
            current=np.fft.rfft(np.stack([records[k].current for k in idx]), axis=-1),
            gaps=np.stack([records[k].gaps for k in idx]), force=force, weight=weight))
    return out


@dataclass(frozen=True)
class _Fit:
    """A weighted least-squares fit: parameters, covariance, chi-square, dof, scale."""

    x: np.ndarray
    cov: np.ndarray
    chi2: float
    dof: int
    scale: float


def _solve(fun: Any, x0: np.ndarray, scale: np.ndarray, lo: np.ndarray, weighted: bool,
           n_obs: int, what: str) -> _Fit:
    """Nonlinear least squares of ``fun(x) -> (residuals, jacobian)`` and the covariance."""
    memo: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}

    def both(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        key = x.tobytes()
        if key not in memo:
            memo.clear()
            memo[key] = fun(x)
        return memo[key]

    with np.errstate(all="ignore"):
        res = least_squares(lambda x: both(x)[0], x0, jac=lambda x: both(x)[1],
                            bounds=(lo, np.full(x0.size, np.inf)), x_scale=scale,
                            method="trf", xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=400)
    r, jac = both(res.x)
    if res.status <= 0 or not np.all(np.isfinite(r)):
        raise FitError(f"{what}: the fit did not converge ({res.message})")
    dof = n_obs - x0.size
    if dof <= 0:
        raise FitError(f"{what}: {x0.size} parameters from only {n_obs} harmonic values")
    _, sv, vt = np.linalg.svd(jac * scale, full_matrices=False)
    if not sv[-1] > 1e-10 * sv[0]:
        raise FitError(f"{what}: the parameters are not identifiable from these runs")
    chi2 = float(r @ r)
    c = max(1.0, chi2 / dof) if weighted else chi2 / dof
    cov = (scale[:, None] * (vt.T / sv**2) @ vt) * scale[None, :] * c
    return _Fit(x=res.x, cov=cov, chi2=chi2, dof=dof, scale=c)


def _steps(f0: np.ndarray, tol: float) -> np.ndarray:
    """Step label per run: sorted fundamentals within ``tol`` relative of the previous share."""
    order = np.argsort(f0)
    labels = np.empty(f0.size, dtype=int)
    step = 0
    for j, k in enumerate(order):
        if j and f0[k] > f0[order[j - 1]] * (1.0 + tol):
            step += 1
        labels[k] = step
    return labels


# --------------------------------------------------------------------------------------------
# the fit


def _records(records: Iterable[Any]) -> list[SteadyRecord]:
    """SteadyRecords, CalibrationSamples read with :meth:`SteadyRecord.from_samples`."""
    out = [r if isinstance(r, SteadyRecord) else SteadyRecord.from_samples(r, name=f"run {k}")
           for k, r in enumerate(records)]
    if not out:
        raise InputError("no records to fit a frequency law to")
    if len({r.gaps.shape[1] for r in out}) > 1:
        raise DimensionError("records with different numbers of poles")
    given = [r.force_std is not None for r in out]
    if any(given) and not all(given):
        bare = ", ".join(r.name or str(k) for k, r in enumerate(out) if r.force_std is None)
        raise InputError(f"records {bare} give no force uncertainty while the others do; give "
                         "every record's or none")
    return out


def _check_campaign(recs: list[SteadyRecord], steps: np.ndarray) -> None:
    """FitError when the campaign cannot separate K, s_fe and tau."""
    gaps = np.sort([r.static_gap for r in recs])
    distinct = 1 + int(np.sum(np.diff(gaps) > GAP_TOLERANCE * float(np.median(gaps))))
    if distinct < 2:
        raise FitError(f"a frequency law needs runs at 2 or more static gaps to separate K from "
                       f"s_fe; all {len(recs)} runs are at {1e3 * gaps[0]:.3f} mm")
    if steps.max() < 1:
        raise FitError(f"a frequency law needs 2 or more frequency steps; every run is at "
                       f"{recs[0].f0:.4g} Hz")
    for s in range(steps.max() + 1):
        sel = [r for r, k in zip(recs, steps, strict=True) if k == s]
        ac = max(abs(np.fft.rfft(r.current)[1]) * 2 / r.n for r in sel)
        if not ac > 1e-9 * max(float(np.max(np.abs(r.current))) for r in sel):
            raise FitError(f"the step at {sel[0].f0:.4g} Hz has no current at its fundamental; "
                           "its lag cannot be measured")


def _start(stacks: list[_Stack], recs: list[SteadyRecord], model: FrequencyModel
           ) -> np.ndarray:
    """(K, s_fe, tau) to start from: a grid over s_fe (tau = 0), then over tau, K solved
    linearly each time."""
    g_min = min(float(r.gaps.min()) for r in recs)
    f_max = max(r.f0 for r in recs)
    y = np.concatenate([st.real(st.force) for st in stacks])

    def best(s_fe: float, tau: float) -> tuple[float, float]:
        b = np.concatenate([st.real(_model(st, 1.0, s_fe, _lag_filter(st, model, tau)[0],
                                           [])[0]) for st in stacks])
        k = float(b @ y / (b @ b))
        return float(np.sum((y - k * b) ** 2)), k

    median = float(np.median([r.static_gap for r in recs]))
    sfe = min(np.linspace(-0.5 * g_min, median, 31), key=lambda v: best(float(v), 0.0)[0])
    taus = np.r_[0.0, np.geomspace(1e-3, 3.0, 30) / (_TWO_PI * f_max)] / model.equivalent
    tau = min(taus, key=lambda v: best(float(sfe), float(v))[0])
    return np.array([best(float(sfe), float(tau))[1], sfe, tau])


def _fit_steps(stacks: list[_Stack], recs: list[SteadyRecord], steps: np.ndarray,
               glob: _Fit, weighted: bool, n_obs: int, model: FrequencyModel
               ) -> tuple[FrequencyStep, ...]:
    """The joint fit of K, s_fe and every step's (g, phi) at the fundamental (the model's
    response with its tau held for the harmonics n >= 2), and each step's K(f) and lag(f)
    with their uncertainties."""
    k0, sfe0, tau = glob.x
    n_steps = int(steps.max()) + 1
    freq = np.array([np.mean([r.f0 for r, s in zip(recs, steps, strict=True) if s == j])
                     for j in range(n_steps)])
    h = model.response(_TWO_PI * freq, tau)[0]
    x0 = np.r_[k0, sfe0, np.column_stack([np.abs(h), -np.angle(h)]).ravel()]

    def make(stacks: list[_Stack]) -> Any:
        return lambda x: _steps_residuals(stacks, steps, n_steps, model, tau, x)

    fun = make(stacks)
    g_min = min(float(r.gaps.min()) for r in recs)
    scale = np.r_[abs(k0), float(np.median([r.static_gap for r in recs])),
                  np.tile([0.1, 0.1], n_steps)]
    lo = np.r_[-np.inf, -0.9 * g_min, np.full(2 * n_steps, -np.inf)]
    fit = _with_shared(_solve(fun, x0, scale, lo, weighted, n_obs, "frequency steps"), recs,
                       weighted, make)
    out = []
    for j in range(n_steps):
        gi, pi = 2 + 2 * j, 3 + 2 * j
        k, g = fit.x[0], fit.x[gi]
        grad = np.zeros(fit.x.size)
        grad[0], grad[gi] = g, k
        out.append(FrequencyStep(
            frequency=float(freq[j]), n_runs=int(np.sum(steps == j)), gain=float(g),
            gain_std=float(np.sqrt(fit.cov[gi, gi])), k=float(k * g),
            k_std=float(np.sqrt(max(grad @ fit.cov @ grad, 0.0))),
            lag_deg=float(np.degrees(fit.x[pi])),
            lag_deg_std=float(np.degrees(np.sqrt(fit.cov[pi, pi])))))
    return tuple(out)


def _steps_residuals(stacks: list[_Stack], steps: np.ndarray, n_steps: int,
                     model: FrequencyModel, tau: float, x: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    """The step fit's weighted residuals and Jacobian: K, s_fe, then (g, phi) per step."""
    res, jac = [], []
    for st in stacks:
        step = steps[st.index]
        filt = _lag_filter(st, model, tau)[0]
        h1 = x[2 + 2 * step] * np.exp(-1j * x[3 + 2 * step])
        filt[:, 1] = h1
        dfilt = []
        for j in range(n_steps):
            mask = (step == j)
            for dh in (np.exp(-1j * x[3 + 2 * step]), -1j * h1):
                d = np.zeros_like(filt)
                d[:, 1] = np.where(mask, dh, 0.0)
                dfilt.append(d)
        m, dm = _model(st, x[0], x[1], filt, dfilt)
        res.append(st.real(m - st.force))
        jac.append(st.real(dm))
    return np.concatenate(res), np.concatenate(jac)


def _global_residuals(stacks: list[_Stack], model: FrequencyModel, x: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
    """The global fit's weighted residuals and Jacobian: K, s_fe, tau."""
    res, jac = [], []
    for st in stacks:
        filt, dfilt = _lag_filter(st, model, x[2])
        m, dm = _model(st, x[0], x[1], filt, [dfilt])
        res.append(st.real(m - st.force))
        jac.append(st.real(dm))
    return np.concatenate(res), np.concatenate(jac)


def _with_shared(fit: _Fit, recs: list[SteadyRecord], weighted: bool, make: Any) -> _Fit:
    """The fit with the errors its runs share added to its covariance: each error (one name,
    per standard uncertainty, on every run that has it) moves the data, and the parameters
    by the least-squares response -J^+ (r' - r) at the fit; the sum of those moves' outer
    products."""
    names = sorted({label for r in recs for label, _, _ in r.shared})
    if not names:
        return fit
    base, jac = make(_stacks(recs, weighted))(fit.x)
    back = np.linalg.pinv(jac)
    cov = np.zeros_like(fit.cov)
    for name in names:
        moved = []
        for r in recs:
            change = [(df, dg) for label, df, dg in r.shared if label == name]
            if change:
                df, dg = change[0]
                r = dataclasses.replace(r, force=r.force + df, gaps=r.gaps + dg, shared=())
            moved.append(r)
        dx = -back @ (make(_stacks(moved, weighted))(fit.x)[0] - base)
        cov += np.outer(dx, dx)
    return dataclasses.replace(fit, cov=fit.cov + cov)


def _bounds(recs: list[SteadyRecord], x0: np.ndarray, model: FrequencyModel
            ) -> tuple[np.ndarray, np.ndarray]:
    """The global fit's parameter scales and lower bounds (s_fe above -0.9 of the least gap)."""
    g_min = min(float(r.gaps.min()) for r in recs)
    f_max = max(r.f0 for r in recs)
    scale = np.array([abs(x0[0]), float(np.median([r.static_gap for r in recs])),
                      1.0 / (_TWO_PI * f_max * model.equivalent)])
    return scale, np.array([-np.inf, -0.9 * g_min, -np.inf])


def _fit_model(stacks: list[_Stack], recs: list[SteadyRecord], model: FrequencyModel,
               weighted: bool, n_obs: int) -> _Fit:
    """K, s_fe and tau of one model over all runs, the errors they share in its covariance."""

    def make(sts: list[_Stack]) -> Any:
        return lambda x: _global_residuals(sts, model, x)

    x0 = _start(stacks, recs, model)
    scale, lo = _bounds(recs, x0, model)
    return _with_shared(_solve(make(stacks), x0, scale, lo, weighted, n_obs,
                               f"frequency law ({model.name})"), recs, weighted, make)


def _held_out(recs: list[SteadyRecord], steps: np.ndarray, model: FrequencyModel,
              weighted: bool, x: np.ndarray) -> np.ndarray:
    """Per frequency step, the relative error of its runs' force phasors predicted by the
    model fitted to the other steps (from the whole campaign's fit ``x``):
    ``sqrt(sum |F_model - F|^2 / sum |F|^2)`` over the step's runs and harmonics."""
    out = np.empty(int(steps.max()) + 1)
    for j in range(out.size):
        train = [r for r, k in zip(recs, steps, strict=True) if k != j]
        test = [r for r, k in zip(recs, steps, strict=True) if k == j]
        sts = _stacks(train, weighted)
        scale, lo = _bounds(train, x, model)
        fit = _solve(lambda p, sts=sts: _global_residuals(sts, model, p), x, scale, lo,
                     weighted, _n_values(train, weighted),
                     f"frequency law ({model.name}) without the step at {test[0].f0:.4g} Hz")
        err = total = 0.0
        for st in _stacks(test, weighted):
            pred = _model(st, fit.x[0], fit.x[1], _lag_filter(st, model, fit.x[2])[0], [])[0]
            seen = st.weight > 0
            err += float(np.sum(np.abs(pred - st.force)[seen] ** 2))
            total += float(np.sum(np.abs(st.force)[seen] ** 2))
        out[j] = math.sqrt(err / total)
    return out


def _candidates(stacks: list[_Stack], recs: list[SteadyRecord], steps: np.ndarray,
                names: Sequence[str], weighted: bool, n_obs: int
                ) -> tuple[dict[str, _Fit], list[ModelScore], list[tuple[str, str]]]:
    """Every model fitted (and, when there is a choice and three steps or more, scored on
    the steps left out): the fits by name, their scores and the ``(name, reason)`` of those
    that could not be fitted."""
    fits: dict[str, _Fit] = {}
    scores: list[ModelScore] = []
    skipped: list[tuple[str, str]] = []
    choice = len(names) > 1
    for name in names:
        model = frequency_model(name)
        try:
            fit = _fit_model(stacks, recs, model, weighted, n_obs)
            held = (_held_out(recs, steps, model, weighted, fit.x)
                    if choice and steps.max() >= 2 else None)
        except FitError as exc:
            if not choice:
                raise
            skipped.append((name, str(exc)))
            continue
        fits[name] = fit
        scores.append(ModelScore(model=model, params=fit.x, cov=fit.cov, chi2=fit.chi2,
                                 dof=fit.dof, n_obs=n_obs, held_out_steps=held))
    if not scores:
        raise FitError("no frequency model can be fitted: " + "; ".join(
            f"{name}: {why}" for name, why in skipped))
    return fits, scores, skipped


def fit_frequency_law(records: Iterable[Any], step_tolerance: float = STEP_TOLERANCE,
                      models: Sequence[str] | None = None) -> FrequencyLaw:
    """Fit K, s_fe and tau to a stepped-sine campaign, choosing the core's response, and the
    response of every step.

    Parameters
    ----------
    records : iterable of SteadyRecord or CalibrationSamples
        One per run, at two or more fundamentals and two or more static gaps.
    step_tolerance : float
        Runs whose fundamentals differ by less than this fraction form one step.
    models : sequence of str or None
        The models of the core's response to choose from (names of
        :data:`.frequency_models.FREQUENCY_MODELS`: ``"first-order"``, ``"half-order"``);
        None: all of them. One name fits that model alone.

    Returns
    -------
    FrequencyLaw
        The chosen model's global fit with its covariance, the per-step table, and every
        model's scores (Notes).

    Raises
    ------
    InputError
        When the records are inconsistent (see :class:`SteadyRecord`), or a model is unknown.
    FitError
        When the runs cannot separate the parameters or no model's fit converges.

    Notes
    -----
    *Fit.* The ``n`` instants of a run are not independent observations: they are a Fourier
    series of ``2 H + 1`` real values (H harmonics), and the reconstruction's errors are errors
    of those phasors. The fit is therefore made on the force's phasors: for every run the DFT
    of the current (its instants cover exactly one period) gives I_n, the core's response
    gives I_m,n, the law is evaluated at the instants, and the DFT of the modelled force is
    compared with the measured force's phasors F_0..F_H: Re and Im of every harmonic n >= 1
    and the DC, each divided by its standard uncertainty (``force_std``: Re and Im each, the
    DC real, as :class:`forcecal.forces.estimate.ForceEstimate`'s ``total_std``). K, s_fe and
    tau are fitted over all runs at once by nonlinear least squares (start: a grid over s_fe,
    then over tau, K solved linearly).

    *Uncertainty.* Runs are independent; the harmonics of one run are taken as independent of
    one another (Re and Im of each alike). The covariance is ``c (J^T J)^-1`` with ``J`` the
    Jacobian of the weighted residuals and ``c = max(1, chi2 / dof)``: a misfit of the model
    inflates it, never shrinks it; ``dof`` counts harmonic values, not instants. A harmonic
    a record does not measure (``force_std`` infinite: the reconstruction holds none there,
    as above the scan's band) is left out of the fit and of ``dof``. Without
    ``force_std`` the harmonics are weighted as white noise on the instants would weight them
    (the DC twice, in variance, as precise as Re or Im of a harmonic) and ``c = chi2 / dof``:
    the scatter sets the level. The current and the gaps are taken as exact but for the errors
    runs share (a tare, the scan's shapes, a sensor's scale: ``SteadyRecord.shared``, each a
    change of the force and the gaps per standard uncertainty), which leave no residual when
    they move every run of a step alike: each moves the parameters by the least-squares
    response ``-J^+ (r' - r)`` at the fit, and the outer products of those moves are added to
    the covariance (in both fits).

    *Choice of the model.* With more than one model, each is fitted to the whole campaign and,
    with three steps or more, to the campaign without each step in turn, predicting the left-out
    step's force phasors: its held-out error is the RMS over the steps of their relative error.
    The simplest model whose held-out error is within the margin of the best is chosen (first
    order before half order; :func:`.frequency_selection.choose_model`); every model's
    parameters, AIC, BIC and held-out errors are kept as ``FrequencyLaw.candidates``.

    *Per frequency step.* Runs whose fundamentals agree within ``step_tolerance`` form a step.
    A second fit, with no model of the frequency dependence at the fundamental, frees per step
    the gain ``g`` and the lag ``phi`` of the fundamental of ``i_m``
    (``I_m,1 = g exp(-j phi) I_1``) together with K and s_fe (the DC of every run pins K);
    harmonics n >= 2 of the current keep the chosen model's response with the fitted tau.
    ``K(f) = K g`` (its uncertainty with K's, correlated) and ``lag(f) = phi`` come with their
    standard uncertainties from that fit's covariance, as above.
    """
    names = tuple(FREQUENCY_MODELS) if models is None else tuple(models)
    if not names:
        raise InputError("no frequency model to fit")
    recs = _records(records)
    steps = _steps(np.array([r.f0 for r in recs]), step_tolerance)
    _check_campaign(recs, steps)
    weighted = recs[0].force_std is not None
    stacks = _stacks(recs, weighted)
    n_obs = _n_values(recs, weighted)
    fits, scores, skipped = _candidates(stacks, recs, steps, names, weighted, n_obs)
    chosen, reason = choose_model(scores) if len(names) > 1 else (names[0], "")
    glob = fits[chosen]
    table = _fit_steps(stacks, recs, steps, glob, weighted, n_obs, frequency_model(chosen))
    currents = np.concatenate([r.current for r in recs])
    gaps = np.concatenate([r.gaps.ravel() for r in recs])
    f0 = [r.f0 for r in recs]
    return FrequencyLaw(
        k=float(glob.x[0]), s_fe=float(glob.x[1]), tau=float(glob.x[2]), covariance=glob.cov,
        n_poles=int(recs[0].gaps.shape[1]), frequency_range=(min(f0), max(f0)),
        current_range=(float(currents.min()), float(currents.max())),
        gap_range=(float(gaps.min()), float(gaps.max())), steps=table, chi2=glob.chi2,
        dof=glob.dof, covariance_scale=glob.scale, model=chosen, reason=reason,
        candidates=candidate_rows(scores, skipped) if len(names) > 1 else ())
