"""Every scan point's frequency response to the drive over a band (a broadband scan).

From time records (or spectra), two estimators, chosen from the reference itself:

- **Periodic drive** (a periodic chirp, a multisine, periodic random: what SLDV software plays
  by default). When the record holds m >= 2 whole periods of the reference, its discrete
  Fourier transform over the whole record (rectangular window) puts the drive on every m-th
  line and nothing on the lines between: H = X / R on the drive's lines is free of leakage
  and of the coherence's bias at a sharp resonance. The noise of X and of R is read per point
  from the lines between (``NOISE_LINES`` near each drive line: a coloured floor is followed);
  Re and Im of H each have the standard uncertainty sqrt((P_X + |H|^2 P_R) / 2) / |R|.
- **Any other drive** (a sweep, random): H1 = S_xr / S_rr from Welch averages (Hann window,
  half overlap) and the coherence; the standard uncertainty of Re and of Im is
  |H| sqrt((1 - coh) / (2 (n_avg - 1) coh)) (Bendat and Piersol, random errors of
  frequency-response estimates, with the coherence's own degrees of freedom: see ``_h1_std``).

FRFs as SLDV software exports them (:class:`~forcecal.records.ScanFRF`) are taken as they are,
their noise by the same formula from their coherence and the number of averages the rig
declares; a coherence within :data:`COHERENCE_RESOLUTION` of 1 is held there (a file's last digit
is not a noise statement).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..errors import InputError
from ..records import Scan, ScanFRF, ScanSpectra

__all__ = ["periods_in_record"]

SEGMENTS = 8
"""Welch segments aimed at per record (half overlap): the frequency resolution is about
``SEGMENTS / (2 T)`` for records of T seconds."""
PERIODIC_SHARE = 0.999
"""A reference is periodic with m periods per record when this share of its power in the band
lies on every m-th line (and m >= 2)."""
NOISE_LINES = 12
"""Lines between the drive's lines averaged, around each drive line, for its noise."""
COHERENCE_RESOLUTION = 1e-9
"""An exported coherence is held at most 1 - this: a line written as 1.0 states no noise."""


@dataclass(frozen=True)
class ScanResponse:
    """Every scan point's frequency response to the drive over the band.

    Attributes
    ----------
    points : (n_points, n_dim) array [m]
        The scan points, as :class:`forcecal.records.Scan` holds them.
    frequencies : (n_lines,) array [Hz]
        The lines in the band.
    values : (n_points, n_lines) complex array [m per unit of the reference]
        H of the displacement.
    std : (n_points, n_lines) array
        Standard uncertainty of Re and of Im of ``values``.
    coherence : (n_points, n_lines) array [1]
        Ordinary coherence of response and reference (periodic drive:
        1 / (1 + P_X / |X|^2 + P_R / |R|^2)).
    source : str
        The scan's file, for messages.
    periods : int
        Periods of the reference per record (0: not periodic, Welch averages).
    """

    points: np.ndarray
    frequencies: np.ndarray
    values: np.ndarray
    std: np.ndarray
    coherence: np.ndarray
    source: str = "<scan>"
    periods: int = 0

    def without_dead(self) -> tuple[ScanResponse, dict[int, str]]:
        """The response without its points that hold no response on any line (a dead
        channel: its zeros would read as a motion known exactly, with no noise), and why each
        of them (by its index) was set aside.

        Raises
        ------
        InputError
            A point with no response on some lines of the band but not on all (a dropout
            within its record): no noise is stated for those zeros.
        """
        zero = np.abs(self.values) == 0
        partial = np.flatnonzero(np.any(zero, axis=1) & ~np.all(zero, axis=1))
        if partial.size:
            k = int(partial[0])
            where = ", ".join(f"{c:.4g}" for c in self.points[k, :3])
            raise InputError(f"scan '{self.source}': record {k + 1} at ({where}) m holds no "
                             f"response on {int(zero[k].sum())} of the band's "
                             f"{zero.shape[1]} lines but holds one on the others (a dropout "
                             "within its record?); measure it again, or leave it out")
        dead = np.flatnonzero(np.all(zero, axis=1))
        if not dead.size:
            return self, {}
        keep = np.ones(len(self.points), bool)
        keep[dead] = False
        why = "no response on any line of the band (a dead channel?)"
        return (replace(self, points=self.points[keep], values=self.values[keep],
                        std=self.std[keep], coherence=self.coherence[keep]),
                {int(k): why for k in dead})


def periods_in_record(reference: np.ndarray, fs: float, band: tuple[float, float]) -> int:
    """Whole periods of a periodic reference per record (0 when it is not periodic).

    Parameters
    ----------
    reference : (n_points, N) array
    fs : float [Hz]
    band : (low, high) [Hz]

    Returns
    -------
    int
        The largest m >= 2 (at most 64) with at least :data:`PERIODIC_SHARE` of every record's
        reference power in the band on lines k m, or 0.
    """
    n = reference.shape[-1]
    f = np.fft.rfftfreq(n, 1.0 / fs)
    power = np.abs(np.fft.rfft(reference - reference.mean(axis=-1, keepdims=True),
                               axis=-1)) ** 2
    return _periods_on_lines(power, f, np.arange(len(f)), band)


def _periods_on_lines(power: np.ndarray, f: np.ndarray, lines: np.ndarray,
                      band: tuple[float, float]) -> int:
    """The largest m >= 2 (at most 64) with at least :data:`PERIODIC_SHARE` of every
    record's reference ``power`` (n_points, n_lines) in the band on the lines whose index
    from 0 Hz (``lines``) is a multiple of m, or 0."""
    in_band = (f >= band[0]) & (f <= band[1]) & (lines > 0)
    total = power[:, in_band].sum(axis=-1)
    if np.any(total <= 0):
        return 0
    for m in range(min(64, int(lines[-1]) // 2), 1, -1):
        on = in_band & (lines % m == 0)
        if np.count_nonzero(on) >= 3 and np.all(power[:, on].sum(axis=-1)
                                                >= PERIODIC_SHARE * total):
            return m
    return 0


def scan_response(scan: Scan | ScanSpectra | ScanFRF, band: tuple[float, float],
                  averages: int | None = None) -> ScanResponse:
    """Each record's frequency response over ``band`` (leakage-free for a periodic drive).

    Parameters
    ----------
    scan : Scan, ScanSpectra or ScanFRF
        Time records under a broadband drive, the coil current as reference; or their spectra
        as SLDV software exports them (one acquisition a point: the drive must be periodic,
        m >= 2 periods a record, for the lines between to give the noise); or their FRFs and
        coherences.
    band : (low, high) [Hz]
        The band the drive covered.
    averages : int, optional
        For FRFs: the number of averages they were estimated from (required, at least 2).

    Returns
    -------
    ScanResponse

    Raises
    ------
    InputError
        Records too short to resolve the band, a band without a line, spectra of a drive
        that is not periodic in their record, or FRFs without their number of averages.
    """
    m = 0
    if isinstance(scan, ScanFRF):
        f, h, std, coh = _from_frfs(scan, band, averages)
    elif isinstance(scan, ScanSpectra):
        f, h, std, coh, m = _from_spectra(scan, band)
    else:
        if band[1] >= scan.fs / 2:
            raise InputError(f"scan '{scan.source}': the band's top {band[1]:g} Hz is not "
                             f"below the Nyquist frequency {scan.fs / 2:g} Hz")
        m = periods_in_record(scan.reference, scan.fs, band)
        if m:
            f = np.fft.rfftfreq(scan.response.shape[-1], 1.0 / scan.fs)
            f, h, std, coh = _periodic(f, np.arange(len(f)),
                                       np.fft.rfft(scan.response, axis=-1),
                                       np.fft.rfft(scan.reference, axis=-1), band, m,
                                       scan.source)
        else:
            f, h, std, coh = _welch(scan, band)
    if scan.quantity == "velocity":
        jw = 2j * np.pi * f
        h, std = h / jw, std / np.abs(jw)
    return ScanResponse(points=scan.points, frequencies=f, values=h, std=std, coherence=coh,
                        source=scan.source, periods=m)


def _from_frfs(scan: ScanFRF, band: tuple[float, float], averages: int | None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Exported FRFs on their lines in the band, their noise from coherence and averages."""
    if averages is None or averages < 2:
        raise InputError(f"scan '{scan.source}': FRFs state their noise only with the number of "
                         "averages they were estimated from, which the file does not hold")
    f = scan.frequencies
    spacing = float(np.max(np.diff(f)))
    if band[1] - f[-1] > spacing * (1 + 1e-6) or f[0] - band[0] > spacing * (1 + 1e-6):
        raise InputError(f"scan '{scan.source}': the FRFs' lines cover {f[0]:g}-{f[-1]:g} Hz, "
                         f"not the band {band[0]:g}-{band[1]:g} Hz (within a line spacing)")
    lines = (f >= band[0]) & (f <= band[1]) & (f > 0)
    if np.count_nonzero(lines) < 3:
        raise InputError(f"scan '{scan.source}': {np.count_nonzero(lines)} line(s) of the FRFs "
                         f"in the band {band[0]:g}-{band[1]:g} Hz")
    h = scan.values[:, lines]
    coh = np.clip(scan.coherence[:, lines], 1e-12, 1.0 - COHERENCE_RESOLUTION)
    return f[lines], h, _h1_std(h, coh, averages), coh


def _h1_std(h: np.ndarray, coh: np.ndarray, n_avg: int) -> np.ndarray:
    """Standard uncertainty of Re and of Im of an H1 estimate from ``n_avg`` averages, given
    its estimated coherence ``coh``: Bendat and Piersol's |H| sqrt((1 - coh) / (2 n coh)) with
    n - 1 for n. The coherence is estimated from the same averages, and the response's part
    the reference explains takes one of their degrees of freedom: with the noise on the
    response, 1 - coh is (1 - coherence) chi^2_{2(n-1)} / (2 n), low by (n - 1) / n on average,
    so n - 1 makes the variance unbiased (4 averages of a test system: the observed error's
    variance over the stated 1.04, 1.39 with n; the RMS of error over stated per line 1.22,
    the t-like spread of a variance estimated on 6 degrees of freedom, 1.40 with n)."""
    return np.abs(h) * np.sqrt((1.0 - coh) / (2.0 * max(n_avg - 1, 1) * coh))


def _from_spectra(scan: ScanSpectra, band: tuple[float, float]
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """The periodic estimator on exported spectra: their lines are those of the record's
    transform (the amplitude convention, common to response and reference, cancels in H)."""
    f = scan.frequencies
    step = float(f[1] - f[0]) if len(f) > 1 else 0.0
    lines = np.rint(f / step).astype(int) if step > 0 else np.zeros(len(f), int)
    if step <= 0 or np.any(np.abs(f - lines * step) > 1e-6 * step):
        raise InputError(f"scan '{scan.source}': the spectra's lines are not multiples of "
                         "their spacing from 0 Hz, as a record's transform puts them")
    if band[1] > f[-1] or band[0] < f[0]:
        raise InputError(f"scan '{scan.source}': the spectra cover {f[0]:g}-{f[-1]:g} Hz, "
                         f"not the band {band[0]:g}-{band[1]:g} Hz")
    m = _periods_on_lines(np.abs(scan.reference) ** 2, f, lines, band)
    if not m:
        raise InputError(f"scan '{scan.source}': spectra hold one acquisition a point, so "
                         "their noise can only be read between the lines of a periodic drive "
                         "(m >= 2 periods a record), and this reference does not repeat two "
                         "or more whole times in its record; export the time records")
    return (*_periodic(f, lines, scan.response, scan.reference, band, m, scan.source), m)


def _periodic(f: np.ndarray, lines: np.ndarray, x: np.ndarray, r: np.ndarray,
              band: tuple[float, float], m: int, source: str
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """H on the drive's lines (every ``m``-th from 0 Hz; ``lines`` the index of each of ``f``
    from 0 Hz) of the response's and the reference's spectra ``x`` and ``r``, noise from the
    lines between."""
    in_band = (f >= band[0]) & (f <= band[1]) & (lines > 0)
    on = np.flatnonzero(in_band & (lines % m == 0))
    between = np.flatnonzero((lines % m != 0) & (lines > 0))
    if len(on) < 3 or len(between) == 0:
        raise InputError(f"scan '{source}': {len(on)} line(s) of the periodic drive in the "
                         f"band {band[0]:g}-{band[1]:g} Hz"
                         + ("" if len(between) else ", and no line between them to read "
                            "the noise on"))
    import scipy.ndimage  # on use: a steady stream starts without it

    # each drive line's noise, the response's and the reference's: the mean over the nearest
    # NOISE_LINES lines between
    width = min(NOISE_LINES, len(between))
    near = np.clip(np.searchsorted(between, on), 0, len(between) - 1)
    p, p_r = (scipy.ndimage.uniform_filter1d(np.abs(y[:, between]) ** 2, size=width, axis=-1,
                                             mode="nearest")[:, near] for y in (x, r))
    tiny = np.finfo(float).tiny
    r_on = np.maximum(np.abs(r[:, on]), tiny)
    h = x[:, on] / r[:, on]
    # H = X / R errs by (n_X - H n_R) / R: the reference's noise counts in proportion to the
    # response, most at a mode (where the response's own is a small part of it)
    std = np.sqrt((p + np.abs(h) ** 2 * p_r) / 2.0) / r_on
    noise_to_signal = p / np.maximum(np.abs(x[:, on]) ** 2, tiny) + p_r / r_on**2
    coh = np.clip(1.0 / (1.0 + noise_to_signal), 1e-12, 1.0)
    return f[on], h, std, coh


def _welch(scan: Scan, band: tuple[float, float]
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """H1 and its coherence from Welch averages."""
    import scipy.signal  # on use: a steady stream starts without it

    n = scan.response.shape[1]
    nperseg = int(2 * n // (SEGMENTS + 1))
    if nperseg < 16 or scan.fs / nperseg > (band[1] - band[0]) / 4:
        raise InputError(f"scan '{scan.source}': records of {n} samples resolve "
                         f"{scan.fs / max(nperseg, 1):.3g} Hz, too coarse for the band "
                         f"{band[0]:g}-{band[1]:g} Hz")
    kw = {"fs": scan.fs, "nperseg": nperseg, "window": "hann", "detrend": "constant"}
    f, s_rr = scipy.signal.welch(scan.reference, axis=-1, **kw)
    _, s_xx = scipy.signal.welch(scan.response, axis=-1, **kw)
    _, s_rx = scipy.signal.csd(scan.reference, scan.response, axis=-1, **kw)
    lines = (f >= max(band[0], f[1])) & (f <= band[1])
    if not np.any(lines):
        raise InputError(f"scan '{scan.source}': no spectral line in the band "
                         f"{band[0]:g}-{band[1]:g} Hz")
    f, s_rr, s_xx, s_rx = f[lines], s_rr[:, lines], s_xx[:, lines], s_rx[:, lines]
    tiny = np.finfo(float).tiny
    h = s_rx / np.maximum(s_rr, tiny)
    coh = np.clip(np.abs(s_rx) ** 2 / np.maximum(s_rr * s_xx, tiny), 1e-12, 1.0)
    n_avg = max((n - nperseg) // (nperseg // 2) + 1, 1)
    return f, h, _h1_std(h, coh, n_avg), coh
