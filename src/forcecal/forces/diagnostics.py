"""Self-checks of an estimate: say so when a result rests on an assumption the data contradict.

Each check is cheap, runs on every batch estimate, and turns into a note (printed by the
command line, kept in the JSON) that says what was found, what it likely means and what to do:

- **probes vs shapes** (:func:`probe_misfit_notes`): the sensors' phasors should lie on the scan
  model's shape at every harmonic; a chi-square beyond its quantile at :data:`FALSE_ALARM` per
  run means the run deflects in another shape than the scan saw (the load pattern changed
  since the scan: a coil, a gap ratio) or a probe is wrong (sign, scale, position);
- **an actuator that pushes** (:func:`pull_only_notes`): an electromagnet only pulls, so every
  force, DC included, must stay >= 0 within its uncertainty; a pushing force means a gauge's
  sign or the tare is wrong;
- **DC against AC** (:func:`dc_vs_ac_notes`): a force growing with i^2 has a DC part that the
  current's own phasors predict from its fundamental, F_0 / |F_1| = P_0 / |P_1| with P the
  harmonics of i^2 (P_0 = I_0^2 + sum |I_n|^2 / 2, P_1 ~ 2 I_0 I_1; gap modulation aside); a DC
  far from it points at a gauge offset, a missing or wrong tare, or a sign slip;
- **a drifting drive** (:func:`drift_notes`): the drive's frequency should hold over a record;
  the current's fundamental phase over the record's quarters shows a drift.
"""

from __future__ import annotations

import numpy as np

from ..model.spatial import SpatialModel
from ..signals.fourier_sums import square_phasors
from ..signals.harmonics import fit_harmonics
from ..signals.mains import on_mains
from ..signals.noise import GUARD
from .coordinates import Coordinates

__all__ = ["FALSE_ALARM"]

FALSE_ALARM = 1e-3
"""Probability per run that a clean run draws a check's note: each check's threshold is its
statistic's quantile at this rate (shared among the harmonics a check tests)."""
PUSH_SIGMAS = 5.0
"""A force below -PUSH_SIGMAS standard uncertainties pushes."""
DC_RATIO_TOLERANCE = 0.3
"""Relative difference between the DC force and the i^2 prediction that draws a note."""
DRIFT_TOLERANCE = 1e-3
"""Relative change of the drive frequency across a record that draws a note."""


def chi_square_limit(dof: int, rate: float = FALSE_ALARM) -> float:
    """The chi-square of ``dof`` degrees of freedom that chance exceeds at ``rate``:
    2 P^-1(dof / 2, 1 - rate) (scipy.special: lighter than .stats)."""
    from scipy.special import gammaincinv  # on use: a steady stream starts without it

    return float(2 * gammaincinv(dof / 2, 1 - rate))


def misfit_limits(coords: Coordinates, n_sensors: int) -> tuple[float, np.ndarray, np.ndarray]:
    """The reduced chi-square of each harmonic's sensor fit above which the probes are noted.

    The quantile of the reduced chi-square with 2 (n_sensors - n_shapes) degrees of freedom at
    :data:`FALSE_ALARM` shared among the harmonics; NaN without a degree of freedom.

    Returns
    -------
    rate : float
        The false-alarm rate per harmonic.
    dof : (n_harmonics,) int ndarray
    limits : (n_harmonics,) ndarray [1]
    """
    from scipy.special import gammaincinv  # on use: a steady stream starts without it

    rate = FALSE_ALARM / max(len(coords.harmonics), 1)
    dof = np.array([2 * (n_sensors - len(coords.span(k)[0]))
                    for k in range(len(coords.harmonics))], dtype=int)
    limits = np.full(dof.shape, np.nan)
    ok = dof > 0
    # the chi-square quantile, 2 P^-1(dof / 2, q) (scipy.special: lighter than .stats)
    limits[ok] = 2 * gammaincinv(dof[ok] / 2, 1 - rate) / dof[ok]
    return rate, dof, limits


def probe_misfit_notes(coords: Coordinates, sensor_names: list[str], what: str) -> list[str]:
    """A note per harmonic whose probes contradict the model's shape (beyond
    :func:`misfit_limits`).

    Parameters
    ----------
    coords : Coordinates
        With the reduced chi-square of every harmonic's sensor fit.
    sensor_names : list of str
        Named in the note.
    what : str
        The run, at the start of the note.

    Returns
    -------
    list of str
    """
    notes = []
    rate, dofs, limits = misfit_limits(coords, len(sensor_names))
    for n, chi2, dof, limit in zip(coords.harmonics, coords.chi2, dofs, limits, strict=True):
        if dof <= 0:
            continue
        if np.isfinite(chi2) and chi2 > limit:
            notes.append(
                f"{what}: harmonic {int(n)}: the probes {', '.join(sensor_names)} disagree with "
                f"the scan model's shape (reduced chi-square {chi2:.3g}, {dof} degrees of "
                f"freedom; chance exceeds {limit:.3g} at a {rate:.2g} rate): the run deflects in "
                "another "
                "shape than the scan saw (a load pattern changed since the scan: scan under this "
                "load too and build the model from both scans) or a probe's sign, scale or "
                "position is wrong; the uncertainty is inflated accordingly")
    return notes


def span_notes(model: SpatialModel, coords: Coordinates, n_sensors: int,
               what: str) -> list[str]:
    """A note per harmonic whose probes needed several shapes of a multi-scan model.

    Parameters
    ----------
    model : SpatialModel
    coords : Coordinates
        With the members each harmonic used.
    n_sensors : int
    what : str
        The run, at the start of the note.

    Returns
    -------
    list of str
    """
    notes = []
    for k, n in enumerate(coords.harmonics):
        members = coords.span(k)[0]
        if len(members) < 2:
            continue
        names = model.member_names(k)
        text = (f"{what}: harmonic {int(n)}: the run's load differs from every scan's; its "
                f"deflection combines the shapes of scans "
                + ", ".join(f"'{names[j]}'" for j in members))
        if len(members) >= n_sensors:
            text += (" (as many coordinates as probes: none is left to check the shapes "
                     "against at this harmonic; a further probe would)")
        notes.append(text)
    return notes


def pull_only_notes(force_names: list[str], series: np.ndarray, dc: np.ndarray,
                    series_std: np.ndarray, what: str) -> list[str]:
    """A note per force that pushes though an electromagnet can only pull.

    Parameters
    ----------
    force_names : list of str
    series : (n_forces, n_samples) ndarray
        [N] each force over the record.
    dc : (n_forces,) ndarray
        [N] each force's DC.
    series_std : (n_forces,) ndarray
        [N] the standard uncertainty of a force's value at one instant.
    what : str
        The run, at the start of the note.

    Returns
    -------
    list of str
    """
    notes = []
    for k, name in enumerate(force_names):
        low = float(np.min(series[k]))
        top = max(float(np.max(series[k])), -low)           # max |x| without a copy of |x|
        sigma = max(float(series_std[k]), 1e-9 * top)
        if low < -PUSH_SIGMAS * sigma:
            notes.append(
                f"{what}: force '{name}' pushes (down to {low:.3g} N, DC {dc[k]:.3g} N) though "
                "an electromagnet can only pull: a gauge's sign (its 'scale' in the rig), the "
                "tare record or a gauge offset is likely wrong")
    return notes


def dc_vs_ac_notes(force_names: list[str], force: np.ndarray, force_std: np.ndarray,
                   current: np.ndarray, what: str) -> list[str]:
    """A note when the DC force contradicts what the current's harmonics predict for a force
    growing with i^2.

    Parameters
    ----------
    force_names : list of str
    force : (n_forces, H+1) complex ndarray
        [N] force phasors.
    force_std : (n_forces, H+1) ndarray
        [N] their standard uncertainties.
    current : (H+1,) complex ndarray
        [A] the coil current's phasors.
    what : str
        The run, at the start of the note.

    Returns
    -------
    list of str
    """
    i0, i1 = float(np.real(current[0])), abs(complex(current[1]))
    if abs(i0) < 0.05 * i1 or i1 == 0.0:
        return []                      # no DC bias: the force is mostly at 2 w0, F_1 ~ 0
    square = square_phasors(current)
    ratio = float(square[0].real) / abs(complex(square[1]))
    total = force.sum(axis=0)
    total_std = np.sqrt(np.sum(force_std**2, axis=0))
    expected = ratio * abs(complex(total[1]))
    found = float(np.real(total[0]))
    sigma = float(np.hypot(total_std[0], ratio * total_std[1]))
    if abs(found - expected) > max(DC_RATIO_TOLERANCE * expected, 5 * sigma):
        return [f"{what}: the DC force {found:.4g} N (sum of {', '.join(force_names)}) is far "
                f"from the {expected:.4g} N that the current's harmonics predict for a force "
                "growing with i^2 from its AC part: the DC is off (a gauge offset, a missing or "
                "wrong tare record, a gauge's sign) or the AC is (the inertia: a probe's scale "
                "or sign, a mass)"]
    return []


def drift_notes(current: np.ndarray, fs: float, f0: float, what: str,
                t0: float = 0.0) -> list[str]:
    """A note when the drive's frequency drifts within the record.

    The current's fundamental is fitted at ``f0`` in each quarter of the record; a steady
    drive keeps its phase, a drift turns it by 2 pi df t. The frequency of every quarter
    follows from the phase advance between quarters.

    Parameters
    ----------
    current : (n_samples,) ndarray
        [A] the coil current.
    fs : float
        [Hz] sampling rate.
    f0 : float
        [Hz] the record's refined fundamental.
    what : str
        The run, at the start of the note.
    t0 : float
        [s] time of the first sample.

    Returns
    -------
    list of str
    """
    n = len(current) // 4
    if n < 5 * fs / f0:
        return []                                         # quarters shorter than 5 periods
    phases, stds = [], []
    for q in range(4):
        fit = fit_harmonics(current[q * n:(q + 1) * n], fs, f0, 1, t0=t0 + q * n / fs)
        x1 = complex(fit.phasors[1])
        phases.append(np.angle(x1))
        stds.append(float(fit.phasor_std[1]) / max(abs(x1), 1e-300))
    advance = np.diff(np.unwrap(np.array(phases)))         # [rad] per quarter
    freq = advance / (2 * np.pi * n / fs)                 # [Hz] offset from f0 per step
    spread = float(np.max(freq) - np.min(freq))
    sigma = float(np.sqrt(2) * max(stds)) / (2 * np.pi * n / fs)
    if spread > max(DRIFT_TOLERANCE * f0, 5 * sigma):
        return [f"{what}: the drive drifts within the record (its frequency moves by "
                f"{spread:.3g} Hz, {spread / f0:.2%}, between the record's quarters); the "
                "batch estimate assumes a steady drive: follow it with 'forcecal stream' or cut "
                "the record into steady pieces"]
    return []


def mains_notes(mains: float | None, f0: float, kept: np.ndarray, resolution: float,
                what: str, counted: frozenset[int] = frozenset()) -> list[str]:
    """A kept harmonic n f0 within :data:`~forcecal.signals.noise.GUARD` + 1 lines of one of the
    first :data:`~forcecal.signals.mains.MAINS_HARMONICS` harmonics of the mains: hum there is one
    with the harmonic, in its estimate; in its uncertainty only when a tare record gave its
    level (:mod:`forcecal.signals.mains`; :mod:`forcecal.signals.noise` sees tones only beside
    the harmonics).

    Parameters
    ----------
    mains : float or None [Hz]
        ``acquisition.mains``; None: nothing to check.
    f0 : float [Hz]
    kept : (H+1,) bool array
    resolution : float [Hz]
        The record's line spacing, fs / n_samples.
    what : str
        The run, for the note.
    counted : frozenset of int
        The harmonics whose hum the tare record gave and the uncertainty counts.

    Returns
    -------
    list of str
    """
    if mains is None:
        return []
    notes = []
    for n, (m, gap) in on_mains(mains, f0, np.flatnonzero(kept), resolution).items():
        where = (f"{what}: harmonic {n} ({n * f0:.6g} Hz) lies {gap:.3g} Hz from the mains' "
                 f"harmonic {m} ({m * mains:g} Hz), within {(GUARD + 1) * resolution:.3g} Hz "
                 f"({GUARD + 1} lines of the record): hum there cannot be told from the force")
        if n in counted:
            notes.append(where + "; its level, read from the tare record, is counted in the "
                         "channels' noise (drive at a frequency whose harmonics keep clear of "
                         "the mains' to be rid of it)")
        else:
            notes.append(where + " and is not in its uncertainty (give a tare record, or drive "
                         "at a frequency whose harmonics keep clear of the mains')")
    return notes
