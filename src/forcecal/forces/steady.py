"""Forces from reactions and inertia (METHOD.md sections 2 and 3, steps 5 and 6).

Per harmonic n >= 1: F_n = Psi^+ (J_n - R_n) (:func:`force_solve`) with the inertia term J_n of
:func:`forcecal.model.inertia.inertia_term`; the DC part has no inertia,
F_0 = -Psi^+ (R_0 - R_0,tare). Which harmonics enter at all is one policy
(:func:`kept_harmonics`), shared by the batch and the streaming estimators. The reactions-only
(static) estimate, -Psi^+ R(t) sample by sample, is returned beside it as the baseline.

:func:`reconstruct` is the batch estimate of one run, written as the method's steps. Standard
uncertainties come from :mod:`forcecal.forces.uncertainty`: linear propagation from the noise
of every channel and from the scan model's shape coefficients.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Iterable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..errors import DataError, InputError
from ..model.inertia import inertia_term
from ..model.relaxation import force_matrix
from ..model.spatial import SpatialModel, check_model_rig
from ..records import Run
from ..rig import Rig
from ..signals.checks import check_clipping, check_record_length
from ..signals.fourier_sums import grid_series
from ..signals.harmonics import (
    HarmonicFit,
    fit_harmonics,
    fundamental_uncertainty,
    refine_fundamental,
)
from ..signals.mains import hum_variance, on_mains
from ..signals.sweeps import swept_drive
from .budget import SolveInputs, pooled_variance, type_b_variance
from .coordinates import Coordinates, deflection, generalized_coordinates
from .crosschecks import NUISANCE, EstimateTerms, flux_notes, pole_notes
from .diagnostics import (
    DRIFT_TOLERANCE,
    dc_vs_ac_notes,
    drift_notes,
    mains_notes,
    probe_misfit_notes,
    pull_only_notes,
    span_notes,
)
from .estimate import ForceEstimate
from .scan_check import scan_notes
from .solve import SPLIT_CONDITION, force_solve, reactions_only
from .uncertainty import (
    combinations,
    gauge_variance,
    inertia_variance_parts,
    shape_operators,
    unresolved_inertia,
    unresolved_inertia_bound,
)
from .weight import current_rms, weight_notes

__all__ = [
    "ForceEstimate",
    "channels_si",
    "kept_harmonics",
    "reconstruct",
    "significant_reactions",
    "solve_inputs",
]

FREQUENCY_MISMATCH = 0.01
"""Relative difference between a run's and the scan's fundamental that draws a warning (the
shapes may not apply); a smaller one beyond the drive's drift draws a note."""
SIGMAS = 5.0
"""Standard uncertainties of the run's fundamental beyond which it differs from the scan's."""
LOOKED_AT = 6
"""Harmonics looked at for content that ``--harmonics`` would leave out, at least."""
SIGNIFICANT_REACTION = 5.0
"""A harmonic without a shape is kept when a gauge shows it above this many noise stds."""


def significant_reactions(reactions: np.ndarray, std: np.ndarray,
                          factor: float = SIGNIFICANT_REACTION) -> np.ndarray:
    """Harmonics that some gauge shows above ``factor`` times its noise.

    Parameters
    ----------
    reactions : (n_gauges, H+1) complex ndarray
        [N] reaction phasors.
    std : (n_gauges, H+1) ndarray
        [N] their standard uncertainties.
    factor : float
        The threshold in noise stds.

    Returns
    -------
    (H+1,) bool ndarray
    """
    significant: np.ndarray = np.any(np.abs(reactions) > factor * std, axis=0)
    return significant


def kept_harmonics(n_harmonics: int, shaped: Iterable[int], significant: np.ndarray,
                   dc: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Which harmonics enter the forces, and which of them with their inertia.

    The policy of both estimators: the DC (when the gauges measure it), every harmonic with a
    shape in the scan model (inertia compensated), and every other harmonic that the reactions
    show (``significant``: its inertia is not compensated and is counted in the uncertainty).

    Parameters
    ----------
    n_harmonics : int
        H.
    shaped : iterable of int
        The harmonics with a shape in the model.
    significant : (H+1,) bool ndarray
        Harmonics the data show (:func:`significant_reactions`).
    dc : bool
        Whether the DC is kept.

    Returns
    -------
    with_inertia : (H+1,) bool ndarray
    kept : (H+1,) bool ndarray
    """
    with_inertia = np.zeros(n_harmonics + 1, dtype=bool)
    for n in shaped:
        if 1 <= n <= n_harmonics:
            with_inertia[n] = True
    kept = with_inertia | np.asarray(significant, dtype=bool)
    kept[0] = dc
    return with_inertia, kept


def channels_si(rig: Rig, run: Run) -> dict[str, np.ndarray]:
    """Gauge, sensor, current and (if any) flux channels in SI with the rig's scales.

    Parameters
    ----------
    rig : Rig
    run : Run

    Returns
    -------
    dict
        Channel name -> (n_samples,) ndarray [N, m, A, Wb].
    """
    out = {g.name: g.scale * run.channel(g.name) for g in rig.gauges}
    out.update({s.name: s.scale * run.channel(s.name) for s in rig.sensors})
    act = rig.actuator
    out[act.current] = act.current_scale * run.channel(act.current)
    if act.flux and act.flux in run.channels:
        out[act.flux] = act.flux_scale * run.channel(act.flux)
    return out


def _times(run: Run) -> np.ndarray:
    """(n_samples,) [s] the run's sample times t0 + k / fs (:attr:`Run.time`), computed in
    place: no temporaries of the record's length."""
    t = np.arange(run.n_samples, dtype=float)
    t /= run.fs
    t += run.t0
    return t


def _series(phasors: np.ndarray, f0: float, run: Run) -> np.ndarray:
    """Evaluate phasors (..., H+1) at the run's sample times -> (..., n_samples), chunk by
    chunk (:func:`forcecal.signals.fourier_sums.grid_series`)."""
    return grid_series(phasors, f0, run.fs, run.t0, run.n_samples)


_SERIES_BLOCK = 1 << 16
"""Samples per block of the reactions-only series [samples]."""


@dataclass(frozen=True)
class _Records:
    """A run's channels in SI, grouped as the method uses them."""

    current: np.ndarray
    sensors: np.ndarray
    gauges: np.ndarray


def _records(rig: Rig, run: Run) -> _Records:
    """Step 0: the channels in SI (as :func:`channels_si`), checked for clipping in its order,
    at least one of them driven. The rows are filled in place and a channel at scale 1 is
    not copied: a long run's channels are held twice over no more than need be."""
    act = rig.actuator
    rec = _Records(current=_in_si(run.channel(act.current), act.current_scale),
                   sensors=_rows(run, [(s.name, s.scale) for s in rig.sensors]),
                   gauges=_rows(run, [(g.name, g.scale) for g in rig.gauges]))
    checked = {**dict(zip(rig.gauge_names, rec.gauges, strict=True)),
               **dict(zip(rig.sensor_names, rec.sensors, strict=True)),
               act.current: rec.current}
    if act.flux and act.flux in run.channels:
        checked[act.flux] = _in_si(run.channel(act.flux), act.flux_scale)
    for name, values in checked.items():
        check_clipping(values, name, run.source, run.fs)
    del checked
    if not _driven(rec):
        raise DataError(f"run '{run.source}': every channel is constant; nothing is driven")
    return rec


def _in_si(raw: np.ndarray, scale: float) -> np.ndarray:
    """``scale * raw``; at scale 1 the raw record itself, read-only (1.0 x is x: no copy)."""
    raw = np.asarray(raw, dtype=float)
    if scale != 1.0:
        return scale * raw
    view = raw.view()
    view.flags.writeable = False
    return view


def _rows(run: Run, scaled: list[tuple[str, float]], start: int = 0,
          stop: int | None = None) -> np.ndarray:
    """(n, stop - start) samples start..stop-1 (default: all) of the channels ``scaled``
    (name, scale) of ``run`` in SI, stacked: each row ``scale * raw`` made in place."""
    stop = run.n_samples if stop is None else stop
    out = np.empty((len(scaled), stop - start))
    for k, (name, scale) in enumerate(scaled):
        np.multiply(run.channel(name)[start:stop], scale, out=out[k])
    return out


def _driven(rec: _Records) -> list[np.ndarray]:
    """The records that are not constant (constant ones say nothing of the fundamental)."""
    return [r for r in (rec.current, *rec.sensors, *rec.gauges)
            if np.std(r) > 1e-9 * (max(float(r.max()), -float(r.min())) + 1e-300)]


def _fundamental(rig: Rig, model: SpatialModel, run: Run, rec: _Records,
                 h: int) -> tuple[float, float, list[str]]:
    """Step 1: the run's refined fundamental, its uncertainty, and a note when it differs from
    the scan model's."""
    check_record_length(run, rig.drive_frequency)
    if rig.drive_frequency >= 0.5 * run.fs:
        raise DataError(f"run '{run.source}': sampled at {run.fs:g} Hz, it cannot hold the "
                        f"drive of rig '{rig.source}' (key 'acquisition.frequency' = "
                        f"{rig.drive_frequency:g} Hz), which lies above its Nyquist frequency "
                        f"{0.5 * run.fs:g} Hz")
    records = _driven(rec)
    try:
        f0 = refined_fundamental(records, run.fs, rig, h, f"run '{run.source}'", t0=run.t0)
    except DataError:
        # a drive that sweeps or drifts within the record defeats one fundamental: say so, not
        # that the nominal frequency is wrong
        sweep = swept_drive([rec.current], run.fs)
        if sweep is not None:
            raise DataError(
                f"run '{run.source}': its coil current '{rig.actuator.current}' sweeps from "
                f"about {sweep.low:g} to {sweep.high:g} Hz {sweep.where}, not a steady drive at "
                f"rig '{rig.source}' key 'acquisition.frequency' = {rig.drive_frequency:g} Hz; "
                "a run under a sweep is reconstructed with acquisition.drive = 'any' (and "
                "acquisition.band, the band its broadband scan covers)") from None
        drift = drift_notes(rec.current, run.fs, rig.drive_frequency, f"run '{run.source}'",
                            t0=run.t0)
        if drift:
            raise DataError(drift[0]) from None
        raise
    notes: list[str] = []
    if abs(f0 / model.f0 - 1) > FREQUENCY_MISMATCH:
        f0, notes = _at_the_scans(records, run, rig, model, h, f0)
    f0_std = fundamental_uncertainty(records, run.fs, f0, h, t0=run.t0)
    off = f0 / model.f0 - 1
    if abs(off) > FREQUENCY_MISMATCH:
        msg = (f"run '{run.source}': drive at {f0:.4g} Hz but the scan model was measured at "
               f"{model.f0:.4g} Hz; its shapes may not apply")
        warnings.warn(msg, stacklevel=4)        # reconstruct's caller
        notes.append(msg)
    elif abs(f0 - model.f0) > max(SIGMAS * f0_std, DRIFT_TOLERANCE * model.f0):
        notes.append(f"run '{run.source}': its fundamental {f0:.6g} Hz differs from the scan "
                     f"model's {model.f0:.6g} Hz by {off:+.3%} ({abs(f0 - model.f0) / f0_std:.3g} "
                     f"standard uncertainties), more than a steady drive drifts "
                     f"({DRIFT_TOLERANCE:.1%}): the run's sampling rate (its time base) or the "
                     "drive's setting differs from the scan's; the shapes are the scan's")
    return f0, f0_std, notes


def _at_the_scans(records: list[np.ndarray], run: Run, rig: Rig, model: SpatialModel, h: int,
                  f0: float) -> tuple[float, list[str]]:
    """A fundamental found far from the scan model's, from the rig's nominal frequency: the
    fundamental refined from the model's instead, when it fits the records better (a short
    record and a wrong nominal frequency lock onto a side lobe), with a note naming the key."""
    try:
        there = refine_fundamental(records, run.fs, model.f0, h, t0=run.t0)
    except DataError:
        return f0, []
    if abs(there / model.f0 - 1) > FREQUENCY_MISMATCH:
        return f0, []
    stacked = np.stack(records)
    miss = [float(np.sum(fit_harmonics(stacked, run.fs, f, h, t0=run.t0).residual_std ** 2))
            for f in (f0, there)]
    if miss[1] >= miss[0]:
        return f0, []
    return there, [f"run '{run.source}': the rig's nominal drive frequency (key "
                   f"'acquisition.frequency' = {rig.drive_frequency:g} Hz, rig "
                   f"'{rig.source}') led to {f0:.6g} Hz, which fits the record worse than "
                   f"{there:.6g} Hz near the scan model's {model.f0:.6g} Hz (residual variance "
                   f"{miss[0] / miss[1]:.3g} times larger): the drive is taken at {there:.6g} Hz; "
                   "the rig's key is likely wrong"]


def _tare_dc(rig: Rig, tare: dict[str, np.ndarray] | None) -> np.ndarray:
    """(n_gauges,) [N] the gauges' DC in a zero-current record's SI channels (zero without)."""
    if tare is None:
        return np.zeros(len(rig.gauges))
    return np.array([tare[g].mean() for g in rig.gauge_names])


def _channel_fits(rig: Rig, run: Run, rec: _Records, f0: float, h: int,
                  tare: Run | None, tare_sig: dict[str, np.ndarray] | None
                  ) -> tuple[HarmonicFit, HarmonicFit, frozenset[int]]:
    """Steps 1 and 1b: the gauges' and the probes' harmonic fits; on the drive harmonics that
    lie on a mains harmonic, the hum the tare record shows added to their phasor variance
    (:mod:`forcecal.signals.mains`); the harmonics it was added to."""
    g_fit = fit_harmonics(rec.gauges, run.fs, f0, h, t0=run.t0)
    s_fit = fit_harmonics(rec.sensors, run.fs, f0, h, t0=run.t0)
    n_samples = rec.gauges.shape[-1]
    if tare is None or tare_sig is None or rig.mains is None:
        return g_fit, s_fit, frozenset()
    pairs = on_mains(rig.mains, f0, range(1, h + 1), run.fs / n_samples)
    if not pairs:
        return g_fit, s_fit, frozenset()
    fits: list[HarmonicFit] = []
    read: set[int] = set()
    for fit, names in ((g_fit, rig.gauge_names), (s_fit, rig.sensor_names)):
        var, heard_at = hum_variance(np.stack([tare_sig[c] for c in names]), tare.fs,
                                     rig.mains, pairs, h, n_samples, run.fs)
        fits.append(dataclasses.replace(fit, phasor_std=np.sqrt(fit.phasor_std**2 + var)))
        read |= heard_at
    return fits[0], fits[1], frozenset(read)


def _inertia(rig: Rig, model: SpatialModel, coords: Coordinates, s_fit: HarmonicFit,
             a_r: np.ndarray, w0: float, h: int
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[int]]:
    """Step 5: J_{r,n} of every shaped harmonic, with its variance in every combination from
    the probes' noise and from the scan's shapes."""
    n_c = a_r.shape[0]
    inertia = np.zeros((len(rig.gauges), h + 1), dtype=complex)
    var_probes = np.zeros((n_c, h + 1, 2))
    var_shapes = np.zeros((n_c, h + 1, 2))
    ops = shape_operators(model, rig)
    shaped = []
    for k, n in enumerate(model.harmonics):
        n = int(n)
        if n > h:
            continue
        members, q, _ = coords.span(k)
        inertia[:, n] = inertia_term(model.member_couplings(k)[:, list(members)], q, n * w0)
        var_probes[:, n, :], var_shapes[:, n, :] = inertia_variance_parts(
            model, ops, k, s_fit, a_r, n * w0, coords)
        shaped.append(n)
    return inertia, var_probes, var_shapes, shaped


def _unresolved(rig: Rig, model: SpatialModel, s_fit: HarmonicFit, a_r: np.ndarray,
                with_inertia: np.ndarray, kept: np.ndarray, w0: float,
                var: np.ndarray) -> list[str]:
    """Harmonics kept without a shape: their uncompensated inertia enters the variance ``var``
    (updated in place): the inertia that the nearest harmonic's shape would give it from the
    probes, as the standard uncertainty of the complex phasor, and never below the whole mass
    moving at the probes' noise; returns a note per harmonic."""
    notes = []
    n_g = len(rig.gauges)
    for n in np.flatnonzero(kept & ~with_inertia):
        if n == 0:
            continue
        bound = unresolved_inertia_bound(rig, s_fit, int(n), w0)
        floor = bound**2 / (2 * n_g) * np.sum(a_r**2, axis=1)
        # the proxy's magnitude is the complex phasor's standard uncertainty: half its
        # square on each of Re and Im
        proxy = np.abs(a_r @ unresolved_inertia(model, rig, s_fit, int(n), w0)) ** 2 / 2
        var[:, n, :] += np.maximum(proxy, floor)[:, None]
        notes.append(f"harmonic {n}: no shape in the scan model "
                     f"({model.dropped.get(int(n), 'not scanned')}); its inertia, up to "
                     f"{bound:.2g} N, is not compensated and is counted in the uncertainty")
    return notes


def reconstruct(rig: Rig, model: SpatialModel, run: Run, n_harmonics: int | None = None,
                tare: Run | None = None, ac_coupled: bool = False) -> ForceEstimate:
    """External forces of one run from its reactions, sensors and the spatial model.

    Parameters
    ----------
    rig : Rig
        The rig.
    model : SpatialModel
        The spatial model from the scan.
    run : Run
        The recording (gauge, sensor and current channels named as in the rig).
    n_harmonics : int, optional
        H: harmonics 0..H are estimated (default: as many as the scan was fitted with).
    tare : Run, optional
        A zero-current record whose gauge DC is subtracted.
    ac_coupled : bool
        The gauges do not measure DC (piezoelectric): the DC force is not estimated.

    Returns
    -------
    ForceEstimate
    """
    _check_arguments(rig, model, run, tare)
    check_model_rig(model, rig)
    h = n_harmonics or len(model.snr)
    est, seen = _from_records(rig, model, run, h, tare, ac_coupled)
    # the records in SI are gone with their fits: the series over the record come now, so
    # that memory holds the run, its series and no more
    flux = flux_notes(rig, run, seen.terms, f"run '{run.source}'")
    flux += pole_notes(rig, run, seen.terms, f"run '{run.source}'")
    if not ac_coupled:                       # AC-coupled gauges read no weight
        flux += weight_notes(rig, tare, current_rms(rig, run), f"run '{run.source}'")
    static_series = _static_series(rig, run, seen.pinv, seen.tare_dc, ac_coupled)
    series = _series(est.force, est.f0, run)
    checks = _self_checks(rig, model, run, est, seen, series, ac_coupled)
    return dataclasses.replace(est, time=_times(run), series=series,
                               static_series=static_series,
                               notes=(*est.notes, *checks, *flux, *seen.dropped))


class _Seen(NamedTuple):
    """What :func:`reconstruct` takes on from :func:`_from_records` besides the estimate."""

    pinv: np.ndarray          # (n_f, n_g) Psi^+
    tare_dc: np.ndarray       # (n_g,) [N] the gauges' zero
    terms: EstimateTerms      # for the flux check
    drift: list[str]          # the current's drift notes
    current: np.ndarray       # (H+1,) the current's phasors
    dropped: list[str]        # the note on harmonics left out


def _from_records(rig: Rig, model: SpatialModel, run: Run, h: int, tare: Run | None,
                  ac_coupled: bool) -> tuple[ForceEstimate, _Seen]:
    """Steps 0 to 7 on the run's records in SI, freed on return: the estimate without its
    series over the record (empty) and its notes up to the self-checks, and what the rest
    of :func:`reconstruct` needs."""
    rec = _records(rig, run)
    f0, f0_std, notes = _fundamental(rig, model, run, rec, h)
    tare_sig = None if tare is None else channels_si(rig, tare)
    g_fit, s_fit, hummed = _channel_fits(rig, run, rec, f0, h, tare, tare_sig)
    coords = _coordinates(rig, model, run, rec, s_fit, f0, h)
    psi = force_matrix(rig)
    pinv, cond = np.linalg.pinv(psi), float(np.linalg.cond(psi))
    tare_dc = _tare_dc(rig, tare_sig)
    reactions = g_fit.phasors.copy()                                 # (n_g, H+1)
    reactions[:, 0] -= tare_dc
    combo_names, combo = combinations(rig)
    a_r = combo @ pinv                                               # (n_c, n_g)
    w0 = 2 * np.pi * f0
    inertia, var_probes, var_shapes, shaped = _inertia(rig, model, coords, s_fit, a_r, w0, h)
    with_inertia, kept = kept_harmonics(
        h, shaped, significant_reactions(reactions, g_fit.phasor_std), dc=True)
    noise = _noise_variances(a_r, g_fit, var_probes, var_shapes)
    notes += mains_notes(rig.mains, f0, kept, run.fs / rec.gauges.shape[-1],
                         f"run '{run.source}'", hummed)
    notes += _unresolved(rig, model, s_fit, a_r, with_inertia, kept, w0,
                         noise["unresolved harmonics"])
    var = sum(noise.values(), start=np.zeros_like(var_probes))
    for a in (reactions, inertia, var, *noise.values()):
        a[:, ~kept] = 0.0
    force, static, std = _solve(pinv, inertia, reactions, var, ac_coupled)
    type_b = _type_b(rig, model, g_fit, s_fit, tare_dc, w0, coords, kept, with_inertia,
                     ac_coupled)
    budget, std, std_re_im = _combined_std(noise, type_b, var, std, ac_coupled)
    terms = _terms(rig, force, std, budget, reactions, inertia, pinv,
                   kept & (np.arange(h + 1) > 0 if ac_coupled else True), w0)
    if not rig.type_b.declared:
        notes.append(f"run '{run.source}': {rig.type_b.describe()}")
    notes += _split_note(rig, cond)
    n_f = len(rig.forces)
    notes += span_notes(model, coords, len(rig.sensors), f"run '{run.source}'")
    dropped = _dropped(rig, model, run, rec, f0, h, pinv, force)
    current = fit_harmonics(rec.current, run.fs, f0, h, t0=run.t0).phasors
    seen = _Seen(pinv, tare_dc, terms,
                 drift_notes(rec.current, run.fs, f0, f"run '{run.source}'", t0=run.t0),
                 current, dropped[0])
    return ForceEstimate(
        run_name=run.name, force_names=tuple(rig.force_names),
        gauge_names=tuple(rig.gauge_names), f0=f0, harmonics=np.arange(h + 1),
        force=force, force_std=std[:n_f], total=force.sum(axis=0), total_std=std[n_f],
        combination_names=combo_names, combination=combo @ force, combination_std=std,
        combination_std_re_im=std_re_im,
        static=static, inertia=inertia, reactions=reactions, with_inertia=with_inertia,
        kept=kept, coordinates=coords, time=np.empty(0), series=np.empty((n_f, 0)),
        static_series=np.empty((n_f, 0)), psi_condition=cond,
        consistency=np.linalg.norm(psi @ force - (inertia - reactions), axis=0),
        dc_observed=not ac_coupled, notes=tuple(notes), f0_std=f0_std, budget=budget,
        type_b=rig.type_b, dropped_rms=dropped[1],
    ), seen


def _static_series(rig: Rig, run: Run, pinv: np.ndarray, tare_dc: np.ndarray,
                   ac_coupled: bool) -> np.ndarray:
    """(n_f, n_samples) [N] the reactions-only forces over the record, -Psi^+ (R(t) - R_tare)
    (less their mean when the gauges are AC-coupled), from the gauges' raw records a block
    at a time: no temporary of the record's length."""
    n = run.n_samples
    out = np.empty((pinv.shape[0], n))
    for a in range(0, n, _SERIES_BLOCK):
        b = min(n, a + _SERIES_BLOCK)
        reactions = _rows(run, [(g.name, g.scale) for g in rig.gauges], a, b)
        reactions -= tare_dc[:, None]
        out[:, a:b] = reactions_only(pinv, reactions)
    if ac_coupled:
        out -= out.mean(axis=1, keepdims=True)
    return out


def _coordinates(rig: Rig, model: SpatialModel, run: Run, rec: _Records, s_fit: HarmonicFit,
                 f0: float, h: int) -> Coordinates:
    """Step 3: the coordinates of every harmonic of the model, those above H too (the
    sensors fitted that far)."""
    top = int(max(model.harmonics))
    fit = s_fit if top <= h else fit_harmonics(rec.sensors, run.fs, f0, top, run.t0)
    return generalized_coordinates(model, rig, fit, run.source)


def _terms(rig: Rig, force: np.ndarray, std: np.ndarray, budget: dict[str, np.ndarray],
           reactions: np.ndarray, inertia: np.ndarray, pinv: np.ndarray, kept: np.ndarray,
           w0: float) -> EstimateTerms:
    """What the cross-checks test (:mod:`forcecal.forces.crosschecks`): the forces with their
    uncertainty less the type-B sources the checks fit as parameters."""
    n_f = len(rig.forces)
    held = sum((budget[k][:n_f] ** 2 for k in NUISANCE if k in budget),
               start=np.zeros_like(std[:n_f]))
    return EstimateTerms(force=force, std=np.sqrt(np.clip(std[:n_f] ** 2 - held, 0.0, None)),
                         reactions=reactions, inertia=inertia, pinv=pinv, kept=kept, w0=w0)


def _dropped(rig: Rig, model: SpatialModel, run: Run, rec: _Records, f0: float, h: int,
             pinv: np.ndarray, force: np.ndarray) -> tuple[list[str], np.ndarray | None]:
    """The harmonics above H (to the model's, at least :data:`LOOKED_AT`) that the reactions
    show above their noise: a note, and the RMS of each force's and the total's share of them
    by the reactions alone (None when none shows)."""
    top = min(max(len(model.snr), LOOKED_AT), int(0.45 * run.fs / f0))
    if h >= top:
        return [], None
    fit = fit_harmonics(rec.gauges, run.fs, f0, top, t0=run.t0)
    shown = significant_reactions(fit.phasors, fit.phasor_std)
    above = [n for n in range(h + 1, top + 1) if shown[n]]
    if not above:
        return [], None
    left = -pinv @ fit.phasors[:, above]                       # reactions only, (n_f, k)
    left = np.vstack([left, left.sum(axis=0)])
    rms = np.sqrt(np.sum(np.abs(left) ** 2, axis=1) / 2)
    kept_rms = np.sqrt(np.sum(np.abs(force.sum(axis=0)[1:]) ** 2) / 2)
    share = rms[-1] / np.hypot(kept_rms, rms[-1])
    which = (f"harmonic {above[0]}" if len(above) == 1
             else f"harmonics {', '.join(map(str, above))}")
    return [f"run '{run.source}': {which} of the reactions stand above their noise and hold "
            f"{share:.2%} of the total force's AC RMS (by the reactions alone); the forces, "
            f"estimated to harmonic {h}, leave them out, and their RMS ({rms[-1]:.3g} N) is "
            "counted in the waveform's uncertainty (a model of more harmonics keeps them: "
            f"scan --harmonics {above[-1]})"], rms


def _noise_variances(a_r: np.ndarray, g_fit: HarmonicFit, var_probes: np.ndarray,
                     var_shapes: np.ndarray) -> dict[str, np.ndarray]:
    """Step 6a: each noise source's variance of Re and of Im in every combination and
    harmonic, (n_c, H+1, 2); the unresolved harmonics' zero, for :func:`_unresolved` to fill."""
    return {"gauge noise": np.repeat(gauge_variance(a_r, g_fit)[:, :, None], 2, axis=2),
            "probe noise": var_probes, "scan shapes": var_shapes,
            "unresolved harmonics": np.zeros_like(var_probes)}


def _combined_std(noise: dict[str, np.ndarray], type_b: dict[str, np.ndarray], var: np.ndarray,
                  std: np.ndarray, ac_coupled: bool
                  ) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray]:
    """Step 6c: the budget (every source's standard uncertainty, (n_c, H+1)), the combined
    standard uncertainty ``std`` (shaped as the noise-only ``std``) and that of Re and of Im
    (n_c, H+1, 2), from the noise variances (``var`` their sum) and the type-B ones."""
    budget = {name: _pooled(v, ac_coupled) for name, v in {**noise, **type_b}.items()}
    std = np.sqrt(sum((b**2 for b in budget.values()), start=np.zeros_like(std)))
    std_re_im = np.sqrt(sum(type_b.values(), start=var))
    if ac_coupled:
        std_re_im[:, 0, :] = 0.0
    return budget, std, std_re_im


def _pooled(var: np.ndarray, ac_coupled: bool) -> np.ndarray:
    """(n_c, H+1) standard uncertainty from the variances of Re and Im (n_c, H+1, 2): pooled
    for n >= 1, the real DC's for n = 0 (zero when the gauges are AC-coupled)."""
    std = np.sqrt(pooled_variance(var))
    if ac_coupled:
        std[:, 0] = 0.0
    return std


def _type_b(rig: Rig, model: SpatialModel, g_fit: HarmonicFit, s_fit: HarmonicFit,
            tare_dc: np.ndarray, w0: float, coords: Coordinates, kept: np.ndarray,
            with_inertia: np.ndarray, ac_coupled: bool) -> dict[str, np.ndarray]:
    """Step 6b: each type-B source's variance of Re and of Im in every combination and
    harmonic, (n_c, H+1, 2) (:mod:`forcecal.forces.budget`)."""
    inputs = _solve_inputs(model, g_fit, s_fit, tare_dc, w0, coords, kept, with_inertia,
                           ac_coupled)
    return type_b_variance(rig, model, inputs)


def _solve_inputs(model: SpatialModel, g_fit: HarmonicFit, s_fit: HarmonicFit,
                  tare_dc: np.ndarray, w0: float, coords: Coordinates, kept: np.ndarray,
                  with_inertia: np.ndarray, ac_coupled: bool) -> SolveInputs:
    return SolveInputs(
        gauges=g_fit.phasors, tare=tare_dc, sensors=s_fit.phasors,
        sensor_std=s_fit.phasor_std, gauge_std=g_fit.phasor_std, w0=w0,
        members=tuple(coords.span(k)[0] for k in range(len(model.harmonics))),
        kept=kept, with_inertia=with_inertia, ac_coupled=ac_coupled)


def solve_inputs(rig: Rig, model: SpatialModel, run: Run, estimate: ForceEstimate,
                 tare: Run | None = None) -> SolveInputs:
    """What the force solve of an estimate used, for :func:`forcecal.forces.budget.monte_carlo`.

    Parameters
    ----------
    rig, model, run : as for :func:`reconstruct`
    estimate : ForceEstimate
        ``reconstruct(rig, model, run, ...)``.
    tare : Run, optional
        The tare the estimate subtracted.

    Returns
    -------
    SolveInputs
    """
    rec = _records(rig, run)
    h = len(estimate.harmonics) - 1
    tare_sig = None if tare is None else channels_si(rig, tare)
    g_fit, s_fit, _ = _channel_fits(rig, run, rec, estimate.f0, h, tare, tare_sig)
    return _solve_inputs(model, g_fit, s_fit, _tare_dc(rig, tare_sig), 2 * np.pi * estimate.f0,
                         estimate.coordinates, estimate.kept, estimate.with_inertia,
                         not estimate.dc_observed)


def _check_arguments(rig: object, model: object, run: object, tare: object) -> None:
    """InputError, not an AttributeError, when a library caller passes the wrong objects."""
    for name, value, kind in (("rig", rig, Rig), ("model", model, SpatialModel),
                              ("run", run, Run), ("tare", tare, (Run, type(None)))):
        if not isinstance(value, kind):
            raise InputError(f"reconstruct: '{name}' must be a {getattr(kind, '__name__', 'Run')}"
                             f" (from forcecal.load_rig, build_spatial_model or read_run); got "
                             f"{type(value).__name__}")


def _self_checks(rig: Rig, model: SpatialModel, run: Run, est: ForceEstimate, seen: _Seen,
                 series: np.ndarray, ac_coupled: bool) -> list[str]:
    """Step 7: the estimate's self-checks (:mod:`forcecal.forces.diagnostics`), those of the
    current's record made by :func:`_from_records` (``seen``)."""
    what = f"run '{run.source}'"
    notes = probe_misfit_notes(est.coordinates, rig.sensor_names, what)
    notes += scan_notes(model, est.coordinates, seen.current, rig.sensor_names, what)
    notes += seen.drift
    if not ac_coupled:
        instant = np.sqrt(np.sum(est.force_std**2, axis=1))
        notes += pull_only_notes(rig.force_names, series, est.force[:, 0].real, instant, what)
        notes += dc_vs_ac_notes(rig.force_names, est.force, est.force_std, seen.current, what)
    return notes


def _solve(pinv: np.ndarray, inertia: np.ndarray, reactions: np.ndarray, var: np.ndarray,
           ac_coupled: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Step 6: the forces, the reactions-only forces and the combinations' standard
    uncertainties (Re and Im averaged; the DC is real); no DC when the gauges are AC-coupled."""
    force = force_solve(pinv, inertia, reactions)
    static = reactions_only(pinv, reactions)
    if ac_coupled:
        force[:, 0] = 0.0
        static[:, 0] = 0.0
        var[:, 0, :] = 0.0
    std = np.sqrt(var.mean(axis=2))
    std[:, 0] = np.sqrt(var[:, 0, 0])
    return force, static, std


def _split_note(rig: Rig, cond: float) -> list[str]:
    """A note when close force points make the split between the forces poorly determined."""
    if cond <= SPLIT_CONDITION:
        return []
    return [f"cond(Psi) = {cond:.3g}: the force points are close together, so the split "
            f"between {', '.join(rig.force_names)} is poorly determined (see their "
            "uncertainties); the resultant (total and moments) is well determined"]


def implied_phasors(rig: Rig, model: SpatialModel, run: Run,
                    estimate: ForceEstimate) -> dict[str, np.ndarray]:
    """The channel phasors (H+1,) [SI] that an estimate implies, by channel name.

    Gauges: the reactions used by the estimate; sensors: their DC as measured and, per
    harmonic, phi_n(l_j) Q_n (the model's view of the motion); the current: its own fit. A run
    built from these phasors is one the estimate explains exactly (synthetic runs, checks).

    Parameters
    ----------
    rig : Rig
    model : SpatialModel
    run : Run
    estimate : ForceEstimate

    Returns
    -------
    dict
        Channel name -> (H+1,) complex ndarray.
    """
    h = len(estimate.harmonics) - 1
    sig = channels_si(rig, run)
    out = {g: estimate.reactions[k].copy() for k, g in enumerate(rig.gauge_names)}
    probes = fit_harmonics(np.stack([sig[s] for s in rig.sensor_names]), run.fs, estimate.f0,
                           h, t0=run.t0).phasors
    at = rig.structure.coordinates(rig.sensor_points)
    model_view = np.zeros((len(rig.sensor_names), h + 1), dtype=complex)
    for k, n in enumerate(model.harmonics):
        model_view[:, n] = deflection(model, estimate.coordinates, k, at)
    for j, s in enumerate(rig.sensor_names):
        x = model_view[j].copy()
        x[0] = probes[j, 0]
        out[s] = x
    cur = rig.actuator.current
    out[cur] = fit_harmonics(sig[cur], run.fs, estimate.f0, h, t0=run.t0).phasors
    return out


def refined_fundamental(records: list[np.ndarray], fs: float, rig: Rig, n_harmonics: int,
                        what: str, t0: float = 0.0) -> float:
    """:func:`refine_fundamental` with errors that name the file and the rig's key.

    Parameters
    ----------
    records : list of ndarray
        Driven records of the run.
    fs : float
        [Hz] sampling rate.
    rig : Rig
        Its ``frequency`` is the nominal drive frequency.
    n_harmonics : int
        H.
    what : str
        Named in messages.
    t0 : float
        [s] time of the first sample.

    Returns
    -------
    float [Hz]
    """
    nominal = rig.drive_frequency
    try:
        return refine_fundamental(records, fs, nominal, n_harmonics, t0=t0)
    except DataError as exc:
        raise DataError(f"{what}: {exc} (rig '{rig.source}', key 'acquisition.frequency' = "
                        f"{nominal:g} Hz)") from None
