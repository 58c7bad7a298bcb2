"""Forces from reactions and inertia (METHOD.md sections 2 and 3, steps 5 and 6).

Per harmonic n >= 1: J_{r,n} = m_{r,n} (-(n w0)^2) Q_n and F_n = Psi^+ (J_n - R_n); the DC part
has no inertia, F_0 = -Psi^+ (R_0 - R_0,tare). The reactions-only (static) estimate,
-Psi^+ R(t) sample by sample, is returned beside it as the baseline.

Standard uncertainties come from :mod:`forcecal.uncertainty`: linear propagation from the noise
of every channel and from the scan model's shape coefficients.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from .coordinates import Coordinates, generalized_coordinates
from .errors import DataError, InputError
from .harmonics import fit_harmonics, fundamental_uncertainty, refine_fundamental
from .io.run_files import check_clipping
from .records import Run
from .relaxation import force_matrix
from .rig import Rig
from .spatial import SpatialModel
from .uncertainty import (
    combinations,
    gauge_variance,
    inertia_variance,
    unresolved_inertia_bound,
)

__all__ = ["ForceEstimate", "channels_si", "implied_phasors", "reconstruct"]

SPLIT_CONDITION = 30.0
"""cond(Psi) above which the split between the forces is flagged as poorly determined."""

FREQUENCY_MISMATCH = 0.01
"""Relative difference between a run's and the scan's fundamental that draws a warning."""


@dataclass(frozen=True)
class ForceEstimate:
    """The forces of one run.

    Attributes
    ----------
    f0 : [Hz] refined fundamental of the run; f0_std : [Hz] its standard uncertainty
    harmonics : (H+1,) int 0..H; phasors follow the convention of :mod:`forcecal.harmonics`
    force : (n_forces, H+1) complex [N]; force_std : (n_forces, H+1) [N] (Re and Im each)
    total : (H+1,) complex [N]; total_std : (H+1,) [N]
    static : (n_forces, H+1) complex [N]: reactions-only phasors
    inertia : (n_gauges, H+1) complex [N]: J_{r,n}
    reactions : (n_gauges, H+1) complex [N]
    with_inertia : (H+1,) bool: harmonics whose inertia came from the scan model
    kept : (H+1,) bool: harmonics the data support (a shape in the model, or reactions above
        five times their noise); the others are set to zero
    time : (n_samples,) [s]; series : (n_forces, n_samples) [N];
    static_series : (n_forces, n_samples) [N] -Psi^+ R(t) sample by sample
    combination_names, combination, combination_std : every force, the total and the
        resultant's first moments (:func:`forcecal.uncertainty.combinations`), phasors
        (n_c, H+1) [N, N m] with their standard uncertainties
    """

    run_name: str
    force_names: tuple[str, ...]
    gauge_names: tuple[str, ...]
    f0: float
    harmonics: np.ndarray
    force: np.ndarray
    force_std: np.ndarray
    total: np.ndarray
    total_std: np.ndarray
    static: np.ndarray
    inertia: np.ndarray
    reactions: np.ndarray
    with_inertia: np.ndarray
    kept: np.ndarray
    coordinates: Coordinates
    time: np.ndarray
    series: np.ndarray
    static_series: np.ndarray
    psi_condition: float
    consistency: np.ndarray
    f0_std: float = 0.0
    combination_names: tuple[str, ...] = ()
    combination: np.ndarray | None = None
    combination_std: np.ndarray | None = None
    dc_observed: bool = True
    notes: tuple[str, ...] = field(default=())

    @property
    def total_series(self) -> np.ndarray:
        """(n_samples,) [N]"""
        return self.series.sum(axis=0)

    @property
    def inertia_share(self) -> float:
        """RMS of the inertia's contribution to the total AC force over the RMS of that force."""
        inertia_total = np.sum(self.inertia_force[:, 1:], axis=0)
        return float(np.sqrt(np.sum(np.abs(inertia_total) ** 2))
                     / np.sqrt(np.sum(np.abs(self.total[1:]) ** 2)))

    @property
    def inertia_force(self) -> np.ndarray:
        """(n_forces, H+1) complex [N]: the inertia's contribution Psi^+ J_n to each force."""
        return self.force - self.static

    @property
    def waveform_std(self) -> float:
        """Standard uncertainty [N] of the total force waveform (RMS over the record, AC part).

        The phasors' uncertainties, plus the fundamental's: an error df in f0 turns harmonic n
        by 2 pi n df (t - t_mid), whose mean square over a record of duration T is
        (2 pi n df)^2 T^2 / 12.
        """
        n = self.harmonics[1:]
        duration = self.time[-1] - self.time[0] if self.time.size > 1 else 0.0
        drift = (2 * np.pi * n * self.f0_std * duration) ** 2 / 12 * np.abs(self.total[1:]) ** 2 / 2
        return float(np.sqrt(np.sum(self.total_std[1:] ** 2) + np.sum(drift)))


def channels_si(rig: Rig, run: Run) -> dict[str, np.ndarray]:
    """Gauge, sensor, current and (if any) flux channels in SI with the rig's scales."""
    out = {g.name: g.scale * run.channel(g.name) for g in rig.gauges}
    out.update({s.name: s.scale * run.channel(s.name) for s in rig.sensors})
    act = rig.actuator
    out[act.current] = act.current_scale * run.channel(act.current)
    if act.flux and act.flux in run.channels:
        out[act.flux] = act.flux_scale * run.channel(act.flux)
    return out


def _psi_pinv(rig: Rig) -> tuple[np.ndarray, float]:
    psi = force_matrix(rig)
    return np.linalg.pinv(psi), float(np.linalg.cond(psi))


def _series(phasors: np.ndarray, f0: float, t: np.ndarray) -> np.ndarray:
    """Evaluate phasors (..., H+1) at times t -> (..., n_t)."""
    n = np.arange(phasors.shape[-1])
    e = np.exp(1j * 2 * np.pi * f0 * np.outer(n, t))
    return (phasors @ e).real


def reconstruct(rig: Rig, model: SpatialModel, run: Run, n_harmonics: int | None = None,
                tare: Run | None = None, ac_coupled: bool = False) -> ForceEstimate:
    """External forces of one run from its reactions, sensors and the spatial model.

    Parameters
    ----------
    rig : the rig; model : the spatial model from the scan
    run : the recording (gauge, sensor and current channels named as in the rig)
    n_harmonics : H, harmonics 0..H are estimated (default: as many as the scan was fitted with)
    tare : a zero-current record whose gauge DC is subtracted
    ac_coupled : the gauges do not measure DC (piezoelectric): the DC force is not estimated
    """
    if rig.frequency is None:
        raise InputError(f"rig '{rig.source}': key 'acquisition.frequency' is missing")
    sig = channels_si(rig, run)
    for name, values in sig.items():
        check_clipping(values, name, run.source, run.fs)
    h = n_harmonics or len(model.snr)
    current = sig[rig.actuator.current]
    sensors = np.stack([sig[s] for s in rig.sensor_names])
    gauges = np.stack([sig[g] for g in rig.gauge_names])
    records = [r for r in np.vstack([current, sensors, gauges])
               if np.std(r) > 1e-9 * (np.max(np.abs(r)) + 1e-300)]     # constant ones say nothing
    if not records:
        raise DataError(f"run '{run.source}': every channel is constant; nothing is driven")
    check_record_length(run, rig.frequency)
    f0 = refined_fundamental(records, run.fs, rig, h, f"run '{run.source}'", t0=run.t0)
    f0_std = fundamental_uncertainty(records, run.fs, f0, h, t0=run.t0)
    notes = []
    if abs(f0 / model.f0 - 1) > FREQUENCY_MISMATCH:
        msg = (f"run '{run.source}': drive at {f0:.4g} Hz but the scan model was measured at "
               f"{model.f0:.4g} Hz; its shapes may not apply")
        warnings.warn(msg, stacklevel=2)
        notes.append(msg)
    g_fit = fit_harmonics(gauges, run.fs, f0, h, t0=run.t0)
    s_fit = fit_harmonics(sensors, run.fs, f0, h, t0=run.t0)
    coords = generalized_coordinates(model, rig, s_fit, run.source)
    pinv, cond = _psi_pinv(rig)
    psi = force_matrix(rig)
    n_g, n_f = len(rig.gauges), len(rig.forces)

    reactions = g_fit.phasors.copy()                                 # (n_g, H+1)
    if tare is not None:
        t_sig = channels_si(rig, tare)
        tare_dc = np.array([t_sig[g].mean() for g in rig.gauge_names])
        reactions[:, 0] -= tare_dc
    inertia = np.zeros((n_g, h + 1), dtype=complex)
    with_inertia = np.zeros(h + 1, dtype=bool)
    w0 = 2 * np.pi * f0
    combo_names, combo = combinations(rig)
    a_r = combo @ pinv                                               # (n_c, n_g)
    var = np.repeat(gauge_variance(a_r, g_fit)[:, :, None], 2, axis=2)   # (n_c, H+1, Re/Im)
    for k, n in enumerate(model.harmonics):
        n = int(n)
        if n > h:
            continue
        w0n = n * w0
        inertia[:, n] = model.couplings[k] * (-(w0n**2)) * coords.q[k]
        with_inertia[n] = True
        var[:, n, :] += inertia_variance(model, rig, k, s_fit, pinv, combo, w0n,
                                         coords.q_std[k])
    # harmonics the scan could not resolve: kept only where the reactions show them; their
    # inertia is not compensated, and its bound is stated as an uncertainty
    kept = with_inertia.copy()
    kept[0] = True
    for n in range(1, h + 1):
        if with_inertia[n] or not np.any(np.abs(reactions[:, n]) > 5 * g_fit.phasor_std[:, n]):
            continue
        kept[n] = True
        bound = unresolved_inertia_bound(rig, s_fit, n, w0)
        var[:, n, :] += (bound**2 / (2 * n_g) * np.sum(a_r**2, axis=1))[:, None]
        notes.append(f"harmonic {n}: no shape in the scan model "
                     f"({model.dropped.get(n, 'not scanned')}); its inertia, up to {bound:.2g} N, "
                     "is not compensated and is counted in the uncertainty")
    reactions[:, ~kept] = 0.0
    inertia[:, ~kept] = 0.0
    var[:, ~kept, :] = 0.0
    force = pinv @ (inertia - reactions)
    static = pinv @ (-reactions)
    if ac_coupled:
        force[:, 0] = 0.0
        static[:, 0] = 0.0
        var[:, 0, :] = 0.0
    consistency = np.linalg.norm(psi @ force - (inertia - reactions), axis=0)
    std = np.sqrt(var.mean(axis=2))
    std[:, 0] = np.sqrt(var[:, 0, 0])                                # DC is real
    if cond > SPLIT_CONDITION:
        notes.append(f"cond(Psi) = {cond:.3g}: the force points are close together, so the split "
                     f"between {', '.join(rig.force_names)} is poorly determined (see their "
                     "uncertainties); the resultant (total and moments) is well determined")
    t = run.time
    static_series = pinv @ (-gauges)
    if tare is not None:
        static_series = static_series + (pinv @ tare_dc)[:, None]
    if ac_coupled:
        static_series = static_series - static_series.mean(axis=1, keepdims=True)
    return ForceEstimate(
        run_name=run.name, force_names=tuple(rig.force_names),
        gauge_names=tuple(rig.gauge_names), f0=f0, harmonics=np.arange(h + 1),
        force=force, force_std=std[:n_f], total=force.sum(axis=0), total_std=std[n_f],
        combination_names=combo_names, combination=combo @ force, combination_std=std,
        static=static, inertia=inertia, reactions=reactions, with_inertia=with_inertia,
        kept=kept, coordinates=coords, time=t, series=_series(force, f0, t),
        static_series=static_series, psi_condition=cond, consistency=consistency,
        dc_observed=not ac_coupled, notes=tuple(notes), f0_std=f0_std,
    )


def implied_phasors(rig: Rig, model: SpatialModel, run: Run,
                    estimate: ForceEstimate) -> dict[str, np.ndarray]:
    """The channel phasors (H+1,) [SI] that an estimate implies, by channel name.

    Gauges: the reactions used by the estimate; sensors: their DC as measured and, per
    harmonic, phi_n(l_j) Q_n (the model's view of the motion); the current: its own fit. A run
    built from these phasors is one the estimate explains exactly (synthetic runs, checks).
    """
    from .coordinates import sensor_rows

    h = len(estimate.harmonics) - 1
    sig = channels_si(rig, run)
    out = {g: estimate.reactions[k].copy() for k, g in enumerate(rig.gauge_names)}
    probes = fit_harmonics(np.stack([sig[s] for s in rig.sensor_names]), run.fs, estimate.f0,
                           h, t0=run.t0).phasors
    for j, s in enumerate(rig.sensor_names):
        x = np.zeros(h + 1, dtype=complex)
        x[0] = probes[j, 0]
        for k, n in enumerate(model.harmonics):
            x[n] = sensor_rows(model, rig, int(n))[j] * estimate.coordinates.q[k]
        out[s] = x
    cur = rig.actuator.current
    out[cur] = fit_harmonics(sig[cur], run.fs, estimate.f0, h, t0=run.t0).phasors
    return out


def check_record_length(run: Run, f0: float) -> None:
    """DataError when a record holds fewer than five periods of the drive."""
    periods = run.n_samples / run.fs * f0
    if periods < 5:
        raise DataError(f"run '{run.source}': the record holds {periods:.1f} periods of "
                        f"{f0:.4g} Hz; at least 5 are needed")


def refined_fundamental(records, fs: float, rig: Rig, n_harmonics: int, what: str,
                        t0: float = 0.0) -> float:
    """:func:`refine_fundamental` with errors that name the file and the rig's key."""
    try:
        return refine_fundamental(records, fs, rig.frequency, n_harmonics, t0=t0)
    except DataError as exc:
        raise DataError(f"{what}: {exc} (rig '{rig.source}', key 'acquisition.frequency' = "
                        f"{rig.frequency:g} Hz)") from None
