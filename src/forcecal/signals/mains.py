"""Mains hum on a drive harmonic (METHOD.md section 9): read from the tare record.

A drive harmonic n f0 within :data:`~forcecal.signals.noise.GUARD` + 1 lines of one of the
mains' first :data:`MAINS_HARMONICS` harmonics m f_mains shares its frequency with the hum:
the fit cannot tell them apart (:mod:`forcecal.signals.noise` counts tones beside the
harmonics, not on them). The hum's level is not in the run, but a zero-current record of the
same rig (the tare) holds it alone: each channel's hum phasor a_m at m f_mains, fitted with its
own noise sigma_m (:func:`forcecal.signals.harmonics.fit_harmonics` at the fundamental m f_mains),
gives the hum's power |a_m|^2 - 2 sigma_m^2 (the noise's share taken out) where it is heard
above the noise (:data:`HEARD`), zero elsewhere.
The hum is not locked to the drive: in the run it is a tone of unknown phase, and each
channel's phasor at harmonic n gains the variance D^2 (|a_m|^2 - 2 sigma_m^2) / 2 on Re and on
Im, D = |sin(pi g N / fs) / (N sin(pi g / fs))| the run's response (N samples at fs) to a tone
g = |n f0 - m f_mains| away (1 on the harmonic). Each channel's hum has its own phase: the
variance is added to the channel's own, as its noise is.
"""

from __future__ import annotations

import numpy as np

from ..errors import ForcecalError
from .harmonics import fit_harmonics
from .noise import GUARD

__all__ = ["hum_tones", "hum_variance", "near_mains", "on_mains"]

MAINS_HARMONICS = 10
"""The mains harmonics a drive harmonic is checked against."""
HEARD = float(np.log(1e3))
"""A tare's phasor counts as hum when its power exceeds this many times the noise's mean:
noise alone does so once in a thousand (|a|^2 / E|a|^2 is exponential), so a harmonic on a
quiet mains line gains no variance from the tare's own noise."""


def on_mains(mains: float, f0: float, harmonics: np.ndarray | range,
             resolution: float) -> dict[int, tuple[int, float]]:
    """The drive harmonics that lie on a mains harmonic.

    Parameters
    ----------
    mains : float [Hz]
        ``acquisition.mains``.
    f0 : float [Hz]
        The run's fundamental.
    harmonics : iterable of int
        The drive harmonics to check (0 is never on the mains).
    resolution : float [Hz]
        The run's line spacing, fs / n_samples.

    Returns
    -------
    dict
        n -> (m, |n f0 - m mains| [Hz]) for every n within GUARD + 1 lines of a mains harmonic
        m = 1 .. MAINS_HARMONICS.
    """
    reach = (GUARD + 1) * resolution
    out = {}
    for n in harmonics:
        m = int(round(n * f0 / mains))
        gap = abs(n * f0 - m * mains)
        if n >= 1 and 1 <= m <= MAINS_HARMONICS and gap <= reach:
            out[int(n)] = (m, gap)
    return out


def near_mains(frequencies: np.ndarray, mains: float | None, width: float) -> np.ndarray:
    """True at the frequencies [Hz] within ``width`` [Hz] of a harmonic of the mains (all of
    them up to the highest frequency asked); all False without ``mains``.

    Under any drive the hum is a tone in a band the drive fills: its lines are left out where
    a line's size is read as motion (a band's reach, the reactions' transfer, the probes'
    misfit to the shapes), so that the hum does not pass for the structure's response.
    """
    f = np.asarray(frequencies, float)
    if mains is None:
        return np.zeros(f.shape, bool)
    m = np.maximum(np.round(f / mains), 1.0)
    return np.abs(f - m * mains) <= width


def hum_variance(tare: np.ndarray, tare_fs: float, mains: float,
                 pairs: dict[int, tuple[int, float]], n_harmonics: int, n_samples: int,
                 fs: float) -> tuple[np.ndarray, frozenset[int]]:
    """The variance the hum adds to Re and to Im of every channel's phasor at every harmonic.

    Parameters
    ----------
    tare : (n_channels, n_tare) array [SI]
        The channels of the zero-current record.
    tare_fs : float [Hz]
    mains : float [Hz]
    pairs : dict
        :func:`on_mains` of the run.
    n_harmonics : int
        H: the run's harmonics 0..H.
    n_samples, fs : int, float
        The run's record.

    Returns
    -------
    var : (n_channels, H + 1) array [SI^2]
        Zero but at the harmonics of ``pairs``.
    read : frozenset of int
        The harmonics whose hum the tare could be read at (not those where it is too short to
        resolve the mains harmonic, or unusable).
    """
    var = np.zeros((tare.shape[0], n_harmonics + 1))
    read = set()
    for n, (m, gap) in pairs.items():
        if n > n_harmonics:
            continue
        try:
            fit = fit_harmonics(tare, tare_fs, m * mains, 1)
        except ForcecalError:
            continue
        read.add(n)
        power = _heard(fit.phasors[:, 1], fit.phasor_std[:, 1])
        x = np.pi * gap / fs
        leak = 1.0 if gap == 0.0 else abs(np.sin(n_samples * x) / (n_samples * np.sin(x)))
        var[:, n] = leak**2 * power / 2
    return var, frozenset(read)


def _heard(phasor: np.ndarray, std: np.ndarray) -> np.ndarray:
    """A tare's tone power |a|^2 less its noise's share (E|a|^2 of noise alone, 2 std^2) where
    it is heard (:data:`HEARD`), zero elsewhere."""
    noise = 2 * std**2
    return np.where(np.abs(phasor) ** 2 >= HEARD * noise, np.abs(phasor) ** 2 - noise, 0.0)


def hum_tones(tare: np.ndarray, fs: float, mains: float, top: float
              ) -> tuple[np.ndarray, np.ndarray]:
    """Every channel's hum up to ``top`` [Hz] under any drive, from a zero-current record.

    Parameters
    ----------
    tare : (n_channels, n_tare) array [SI]
    fs : float [Hz]
    mains : float [Hz]
    top : float [Hz]

    Returns
    -------
    frequencies : (n_m,) array [Hz]
        The mains' harmonics up to ``top`` (none when the record cannot resolve them).
    power : (n_channels, n_m) array [SI^2]
        Each channel's tone |a_m|^2 (its squared amplitude), zero where not heard.
    """
    h = int(min(top, 0.45 * fs) // mains)
    none = (np.zeros(0), np.zeros((tare.shape[0], 0)))
    if h < 1:
        return none
    try:
        fit = fit_harmonics(tare, fs, mains, h)
    except ForcecalError:
        return none
    return mains * np.arange(1, h + 1), _heard(fit.phasors[:, 1:], fit.phasor_std[:, 1:])
