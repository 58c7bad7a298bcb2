"""Scan -> phase-aligned harmonic deflection shapes (METHOD.md section 3, step 1).

For every scan point k the harmonics of the vibration record and of its reference (coil
current) record are fitted by least squares at the fundamental refined from all records
jointly. SLDV velocity becomes displacement, U_n = V_n / (j n w0). Points are measured one after
another, each record starting at its own phase theta_k = arg I_1(k), so harmonic n is aligned by
exp(-j n theta_k) (the corrected eq. 13), and normalized by the record's drive amplitude
|I_1(k)| relative to the mean, which removes a drift of the drive between points.

A scan exported as spectra (:class:`~forcecal.records.ScanSpectra`) gives the same phasors read
off its lines (:mod:`forcecal.model.scan`); the conversion, alignment and normalization that
follow are the same, in :func:`aligned_shapes`. A broadband scan's FRFs
(:class:`~forcecal.records.ScanFRF`) are refused: their phases are relative to the reference at
each line.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import DataError, InputError
from ..records import FRF_PHASE, Scan, ScanFRF, ScanSpectra
from ..signals.checks import check_scan_length
from ..signals.harmonics import fit_harmonics, refine_fundamental
from ..signals.noise import GUARD, noise_power, noise_windows
from ..signals.sweeps import swept_drive
from .screening import record_weights

__all__ = ["HarmonicShapes", "harmonic_shapes"]


# --- from scan_spectra ---
LINE_TOLERANCE = 0.02
"""Largest offset of a harmonic n f0 from its line, as a share of the line spacing."""
MIN_NOISE_LINES = 4
"""Fewest lines a noise estimate is made from (a harmonic spacing of at least 8 lines)."""
SEARCH = 0.05
"""Half-width of the fundamental's search band, relative to the nominal frequency (as for
time records, :func:`forcecal.signals.harmonics.refine_fundamental`)."""
PEAK_FACTOR = {"peak": 1.0, "rms": float(np.sqrt(2.0))}
"""Multiplier from a convention's line value to the peak phasor."""


@dataclass(frozen=True)
class LinePhasors:
    """The phasors read off a spectrum scan's lines, before alignment.

    Attributes
    ----------
    f0 : float [Hz]
        The fundamental.
    response : (n_points, H) complex array [m/s] or [m]
        Harmonics 1..H of each response, peak phasors, phase referred to each record's start.
    response_std : (n_points, H) array [m/s] or [m]
        Standard uncertainty of Re and of Im of ``response``.
    drive : (n_points,) complex array [A]
        The reference's fundamental I_1 of each record.
    drive_std : (n_points,) array [A]
        Standard uncertainty of Re and of Im of ``drive``.
    offset : float [lines]
        The drive's offset from its line (step 2 of :func:`spectrum_phasors`).
    """

    f0: float
    response: np.ndarray
    response_std: np.ndarray
    drive: np.ndarray
    drive_std: np.ndarray
    offset: float


def spectrum_phasors(scan: ScanSpectra, f0_nominal: float, n_harmonics: int) -> LinePhasors:
    """Read harmonics 1..H of every response and the fundamental of every reference off the
    lines (the method in the notes below).

    Parameters
    ----------
    scan : ScanSpectra
        The spectra.
    f0_nominal : float
        Nominal drive frequency [Hz] (the rig's ``acquisition.frequency``).
    n_harmonics : int
        H, at least 1.

    Returns
    -------
    LinePhasors

    Raises
    ------
    DataError
        The nominal frequency outside the lines; the drive at the band's edge; a harmonic
        beyond the last line or off its line by more than :data:`LINE_TOLERANCE`; lines too
        coarse for :data:`MIN_NOISE_LINES` noise lines beside a harmonic.

    Notes
    -----
    1. **Amplitude.** Lines in the "rms" convention are multiplied by sqrt 2, so that every line
       holds the one-sided peak phasor of :mod:`forcecal.signals.harmonics` (a unit cosine on a
       line reads 1). The displacement amplitude in metres depends on this; the referencing
       does not.
    2. **Fundamental.** Its line is the peak of the reference power, each record's normalized and
       summed over the records, within +-5 % of the nominal frequency. The drive's offset
       ``delta`` from that line, in lines, is Jacobsen's three-line estimate
       ``Re[(X[k-1] - X[k+1]) / (2 X[k] - X[k-1] - X[k+1])]``, the median over the records whose
       reference shows the drive (exact for the rectangular window of a synchronous export; a Hann
       window reads half the offset). f0 = (first line) + (k + delta) * (line spacing).
    3. **Harmonics on lines.** Harmonic n is the line nearest n f0. It must lie within
       :data:`LINE_TOLERANCE` of a line spacing of n f0, else the scan is refused (DataError): a
       line beside a tone holds neither its amplitude nor, in a zoomed band, its phase, and the
       window that would say by how much is not in the file. Within the tolerance a rectangular or
       Hann window loses at most 0.1 % of the amplitude; the line is multiplied by
       exp(-j pi eps_n), eps_n the offset of n f0 from it, the phase of a symmetric window's kernel
       (from lines starting at 0 Hz this shift is n times the fundamental's and cancels in the
       referencing anyway). What the other harmonics, off their lines, leak onto the line is
       bounded by the rectangular window's kernel, sum_m |A_m sinc(k_n - p_m)| over the other
       harmonics and the images of all at -m f0 (p_m the tone's position in lines), and added to
       the line's uncertainty as a phase-random error (variance bound^2 / 2 in Re and in Im);
       on a line it is zero. Export spectra whose line spacing divides the drive frequency (a
       whole number of periods per record), as SLDV software does with its own generator.
    4. **Noise.** The standard uncertainty of Re and of Im of a harmonic's line, per record and
       harmonic, comes from the noise lines around it: those within half a harmonic spacing of
       the harmonic's line, leaving out :data:`GUARD` lines either side of every harmonic's line
       (a Hann window spreads a tone over +-1 line; a flat-top window spreads it wider and
       inflates the estimate). Noise of locally flat spectrum has at every line
       var Re = var Im = E|X|^2 / 2. E|X|^2 is modelled as the record's level times the
       harmonic's profile (the noise's colour, common to the records), each estimated by the median
       of |X|^2 over its lines divided by the expected median of as many unit exponential
       variables: unbiased for Gaussian noise, hardly moved by a stray line such as the mains, and
       pooled so that a few lines per harmonic still give a steady estimate (as the residual of a
       time record's fit pools the whole record).
    """
    where = f"scan '{scan.source}'"
    factor = PEAK_FACTOR[scan.amplitude]
    ref = scan.reference * factor
    resp = scan.response * factor
    df, first = scan.spacing, float(scan.frequencies[0])
    k1 = _drive_line(ref, scan, f0_nominal)
    spacing = (first + k1 * df) / df  # the harmonics' spacing in lines
    if spacing < 2 * (GUARD + 2):
        raise DataError(f"{where}: the drive near {first + k1 * df:.6g} Hz lies only "
                        f"{spacing:.3g} line spacings ({df:.6g} Hz) above 0 Hz; at least "
                        f"{2 * (GUARD + 2)} are needed to tell the harmonics from the noise "
                        "between them (a finer line spacing: a longer record)")
    windows = _noise_windows(_harmonic_lines(first, first + k1 * df, df, 1), spacing,
                             scan.n_lines, scan.source)
    strong = np.abs(ref[:, k1]) >= 10 * _noise_std(ref, windows)[:, 0]
    delta = _offset(ref[strong] if strong.any() else ref, k1)
    f0 = first + (k1 + delta) * df
    position = (np.arange(1, n_harmonics + 1) * f0 - first) / df
    lines = np.rint(position).astype(int)
    eps = position - lines
    _check_on_lines(scan, f0, lines, eps, delta)
    windows = _noise_windows(_harmonic_lines(first, f0, df, n_harmonics), f0 / df,
                             scan.n_lines, scan.source)
    u = resp[:, lines] * np.exp(-1j * np.pi * eps)
    drive = ref[:, lines[0]] * np.exp(-1j * np.pi * eps[0])
    leak = _leakage(np.abs(u), lines, f0 / df, first / df)
    u_std = np.sqrt(_noise_std(resp, windows) ** 2 + leak**2 / 2)
    return LinePhasors(f0=float(f0), response=u, response_std=u_std, drive=drive,
                       drive_std=_noise_std(ref, windows)[:, 0], offset=float(delta))


def unusable_spectra(scan: ScanSpectra, reference_ok: np.ndarray) -> dict[int, str]:
    """Records set aside before any fit: those whose reference shows no drive (the lines were
    checked finite on reading; clipping cannot be told from a spectrum).

    Parameters
    ----------
    scan : ScanSpectra
    reference_ok : (n_points,) bool ndarray
        Whether each record's reference shows the drive.

    Returns
    -------
    dict
        Record index -> reason, worded as :func:`forcecal.model.screening.unusable_records` does.
    """
    return {int(k): "its reference shows no drive (the record's phase is unknown)"
            for k in np.flatnonzero(~np.asarray(reference_ok))}


def _drive_line(ref: np.ndarray, scan: ScanSpectra, f0_nominal: float) -> int:
    """Index of the line of largest summed normalized reference power near ``f0_nominal``."""
    f = scan.frequencies
    band = np.flatnonzero(np.abs(f - f0_nominal) <= SEARCH * f0_nominal)
    if band.size == 0:
        raise DataError(f"scan '{scan.source}': the spectra's lines ({f[0]:.6g} to {f[-1]:.6g} "
                        f"Hz every {scan.spacing:.6g} Hz) hold none within {100 * SEARCH:g} % of "
                        f"the drive's nominal {f0_nominal:g} Hz (the rig's "
                        "'acquisition.frequency')")
    power = np.abs(ref[:, band]) ** 2
    total = power.sum(axis=1, keepdims=True)
    k = int(band[np.argmax(np.sum(power / np.where(total > 0, total, 1.0), axis=0))])
    if not 0 < k < scan.n_lines - 1:
        raise DataError(f"scan '{scan.source}': the drive's line ({f[k]:.6g} Hz) is the "
                        "spectra's first or last line; export a band that holds it inside")
    return k


def _offset(ref: np.ndarray, k: int) -> float:
    """Median over the records of Jacobsen's offset [lines] of the tone near line ``k``."""
    lo, mid, hi = ref[:, k - 1], ref[:, k], ref[:, k + 1]
    den = 2 * mid - lo - hi
    ok = den != 0
    if not ok.any():
        return 0.0
    delta = np.real((lo[ok] - hi[ok]) / den[ok])
    return float(np.clip(np.median(delta), -0.5, 0.5))


def _check_on_lines(scan: ScanSpectra, f0: float, lines: np.ndarray, eps: np.ndarray,
                    delta: float) -> None:
    """DataError when a harmonic lies beyond the last line or between lines."""
    where = f"scan '{scan.source}'"
    df = scan.spacing
    beyond = np.flatnonzero(lines > scan.n_lines - 1)
    if beyond.size:
        n = int(beyond[0]) + 1
        raise DataError(f"{where}: harmonic {n} at {n * f0:.6g} Hz lies beyond the spectra's "
                        f"last line ({scan.frequencies[-1]:.6g} Hz); export a wider band or ask "
                        f"for fewer harmonics (--harmonics {n - 1})")
    off = np.flatnonzero(np.abs(eps) > LINE_TOLERANCE)
    if off.size:
        n = int(off[0]) + 1
        raise DataError(f"{where}: the drive at {f0:.6g} Hz lies {abs(delta):.3g} of a line "
                        f"spacing ({df:.6g} Hz) from its line, so harmonic {n} at "
                        f"{n * f0:.6g} Hz falls {abs(eps[n - 1]):.3g} of a spacing between "
                        f"lines (at most {LINE_TOLERANCE:g} accepted), where a line holds neither "
                        "its amplitude nor its phase; export spectra whose line spacing divides "
                        "the drive frequency (a whole number of periods per record), or the "
                        "time records")


def _leakage(amplitude: np.ndarray, lines: np.ndarray, f0_lines: float, first_lines: float
             ) -> np.ndarray:
    """(n_records, H) bound of what the other harmonics (and the images of all, at -n f0) put
    on every harmonic's line when they lie off their lines: sum_m |A_m sinc(k_n - p_m)|, p_m
    the position of tone m in lines (step 3 of :func:`spectrum_phasors`; the rectangular
    window's kernel, whose sidelobes no common window exceeds).

    Parameters
    ----------
    amplitude : (n_records, H) array
        |A_m| of every harmonic of every record.
    lines : (H,) int array
        The harmonics' lines.
    f0_lines : float
        f0 in line spacings.
    first_lines : float
        The first line's frequency in line spacings.
    """
    n = np.arange(1, lines.size + 1)
    tones = np.concatenate([n * f0_lines - first_lines, -n * f0_lines - first_lines])
    kernel = np.abs(np.sinc(lines[:, None] - tones[None, :]))       # (H, 2H)
    kernel[np.arange(lines.size), np.arange(lines.size)] = 0.0      # a tone's own line
    bound: np.ndarray = np.concatenate([amplitude, amplitude], axis=1) @ kernel.T
    return bound


def _harmonic_lines(first: float, f0: float, df: float, n_harmonics: int) -> np.ndarray:
    """Lines nearest 0 Hz and every harmonic 1..H+1 (the noise estimates keep clear of them)."""
    return np.rint((np.arange(n_harmonics + 2) * f0 - first) / df).astype(int)


def _noise_windows(harmonics: np.ndarray, spacing: float, n_lines: int, source: str
                   ) -> list[np.ndarray]:
    """The noise lines of harmonics 1..H (:func:`forcecal.signals.noise.noise_windows`: within
    half a harmonic spacing, clear of 0 Hz and of harmonics 1..H+1 by :data:`GUARD` lines);
    fewer than :data:`MIN_NOISE_LINES` beside a harmonic is a DataError naming the scan
    ``source``. ``harmonics`` holds the lines of 0 Hz and of harmonics 1..H+1
    (:func:`_harmonic_lines`), ``spacing`` is f0 / df."""
    windows = noise_windows(harmonics[1:-1], harmonics, spacing, n_lines)
    for n, noise in enumerate(windows, start=1):
        if noise.size < MIN_NOISE_LINES:
            raise DataError(f"scan '{source}': harmonic {n} has {noise.size} lines of noise "
                            f"beside it, at least {MIN_NOISE_LINES} are needed (a finer line "
                            "spacing, or a band reaching half a harmonic spacing beyond the last "
                            "harmonic)")
    return windows


def _noise_std(lines: np.ndarray, windows: list[np.ndarray]) -> np.ndarray:
    """(n_records, H) standard uncertainty of Re and of Im of every record's line of every
    harmonic, from the noise lines ``windows`` (step 4 of :func:`spectrum_phasors`)."""
    std: np.ndarray = np.sqrt(noise_power(np.abs(lines) ** 2, windows) / 2)
    return std


# --- from scan ---
@dataclass(frozen=True)
class HarmonicShapes:
    """Measured harmonic deflection shapes at the scan points.

    Attributes
    ----------
    points : (n_points, n_dim) array [m]
        The scan points (n_dim = 6 for a body's located records).
    harmonics : (n_harm,) int array
        The harmonic numbers 1..H.
    values : (n_harm, n_points) complex array [m]
        Displacement phasor of harmonic n at each point, phase referred to the drive's
        fundamental, scaled to the mean drive amplitude.
    std : (n_harm, n_points) array [m]
        Standard uncertainty of Re and of Im of ``values``.
    f0 : float [Hz]
        The fundamental refined from the scan.
    drive_amplitude : (n_points,) array [A]
        |I_1| of each record's reference.
    drive_phase : (n_points,) array [rad]
        theta_k, the phase of each record's reference fundamental.
    source : str
        Where the scan was read from, for messages.
    """

    points: np.ndarray
    harmonics: np.ndarray
    values: np.ndarray
    std: np.ndarray
    f0: float
    drive_amplitude: np.ndarray
    drive_phase: np.ndarray
    source: str = "<scan>"
    reference_ok: np.ndarray | None = None
    drive: np.ndarray | None = None
    """(H+1,) complex [A]: the coil current's harmonics 0..H, each record's aligned and scaled
    as its shapes, averaged over the records that show the drive (the fundamental real); None
    where the scan gave the reference's fundamental only (spectra)."""

    def snr(self, keep: np.ndarray | None = None) -> np.ndarray:
        """(n_harm,) RMS shape amplitude over the records divided by the records' median
        noise [1], both judged record by record: the mean square is weighted by each record's
        floored inverse noise variance (:func:`forcecal.model.screening.record_weights`), so that a
        spiky record neither drowns a harmonic in noise nor makes one out of its own spike.

        Parameters
        ----------
        keep : (n_points,) bool ndarray, optional
            The records to judge by (default: those whose reference shows the drive).
        """
        sel = self.reference_ok if keep is None else keep
        values = self.values if sel is None else self.values[:, sel]
        std = self.std if sel is None else self.std[:, sel]
        weights = np.stack([record_weights(row) for row in std])
        signal = np.sqrt(np.sum(weights * np.abs(values) ** 2, axis=1) / np.sum(weights, axis=1))
        noise = np.median(std, axis=1) * np.sqrt(2)
        ratio: np.ndarray = signal / noise
        return ratio


def steady_scan(scan: Scan | ScanSpectra | ScanFRF) -> Scan | ScanSpectra:
    """The scan, when a steady drive's harmonics can be read from it.

    Raises
    ------
    InputError
        FRFs: their phases are relative to the reference at each line.
    """
    if isinstance(scan, ScanFRF):
        raise InputError(f"scan '{scan.source}': holds FRFs (function type 4), {FRF_PHASE}; a "
                         "steady drive's model is read from the time records or the complex "
                         "spectra of the response and of the reference (FRFs serve a broadband "
                         "scan: a rig with 'acquisition.band')")
    return scan


def harmonic_shapes(scan: Scan | ScanSpectra | ScanFRF, f0_nominal: float,
                    n_harmonics: int = 6) -> HarmonicShapes:
    """Fit (or read off the lines), convert and phase-align the harmonics of every scan record.

    Parameters
    ----------
    scan : Scan or ScanSpectra
        The SLDV scan (velocity or displacement records plus current references), as time
        records or as spectra (:func:`forcecal.model.scan.spectrum_phasors` says how the
        lines are read).
    f0_nominal : float
        Nominal drive frequency [Hz]; the fundamental is refined from the references.
    n_harmonics : int
        H: harmonics 1..H are returned.

    Returns
    -------
    HarmonicShapes
        The aligned displacement phasors of harmonics 1..H at every point.

    Raises
    ------
    DataError
        Records shorter than 5 periods, references whose fundamental cannot be refined, or
        more than half of the reference records without the drive (a record whose reference
        shows no drive is kept and flagged in ``reference_ok``; the spatial model sets it
        aside, :mod:`forcecal.model.screening`); spectra whose harmonics are not on lines.
    InputError
        FRFs (a broadband scan's export).
    """
    scan = steady_scan(scan)
    if isinstance(scan, ScanSpectra):
        lines = spectrum_phasors(scan, f0_nominal, n_harmonics)
        return aligned_shapes(scan.points, lines.f0, lines.response, lines.response_std,
                              lines.drive, lines.drive_std, scan.quantity, scan.source)
    check_scan_length(scan, f0_nominal)
    f0 = _refined(scan, f0_nominal, n_harmonics)
    ref = fit_harmonics(scan.reference, scan.fs, f0, n_harmonics)
    resp = fit_harmonics(scan.response, scan.fs, f0, n_harmonics)
    return aligned_shapes(scan.points, f0, resp.phasors[:, 1:], resp.phasor_std[:, 1:],
                          ref.phasors[:, 1], ref.phasor_std[:, 1], scan.quantity, scan.source,
                          reference=ref.phasors)


def _refined(scan: Scan, f0_nominal: float, n_harmonics: int) -> float:
    """The fundamental [Hz] refined from the references; DataError naming the rig's
    frequency, or the band the references sweep through when they do."""
    try:
        return refine_fundamental(scan.reference, scan.fs, f0_nominal, n_harmonics)
    except DataError as exc:
        sweep = swept_drive(scan.reference, scan.fs)
        if sweep is not None:
            raise DataError(
                f"scan '{scan.source}': its reference (the coil current) sweeps from about "
                f"{sweep.low:g} to {sweep.high:g} Hz {sweep.where}, not a steady drive at the "
                f"rig's 'acquisition.frequency' = {f0_nominal:g} Hz; declare the band the scan "
                f"covers with 'acquisition.band = {sweep.band}' (and acquisition.drive = 'any' "
                "for runs under that drive)") from None
        raise DataError(f"scan '{scan.source}': {exc} (the rig's 'acquisition.frequency' is "
                        f"{f0_nominal:g} Hz)") from None


def aligned_shapes(points: np.ndarray, f0: float, response: np.ndarray,
                   response_std: np.ndarray, drive: np.ndarray, drive_std: np.ndarray,
                   quantity: str, source: str,
                   reference: np.ndarray | None = None) -> HarmonicShapes:
    """The harmonic shapes from every record's measured phasors: velocity to displacement,
    U_n = V_n / (j n w0); aligned, U_n exp(-j n theta_k) with theta_k = arg I_1(k); scaled by
    mean |I_1| / |I_1(k)| (eq. 11-13).

    Parameters
    ----------
    points : (n_points, n_dim) array [m]
        The scan points.
    f0 : float [Hz]
        The fundamental.
    response : (n_points, H) complex array [m/s] or [m]
        Harmonics 1..H of every response record.
    response_std : (n_points, H) array [m/s] or [m]
        Standard uncertainty of Re and of Im of ``response``.
    drive : (n_points,) complex array [A]
        I_1, the fundamental of every reference record.
    drive_std : (n_points,) array [A]
        Standard uncertainty of Re and of Im of ``drive``.
    quantity : {"velocity", "displacement"}
        What ``response`` holds.
    source : str
        The scan, for messages.
    reference : (n_points, H+1) complex array [A], optional
        Harmonics 0..H of every reference record: aligned and scaled alike, their mean over
        the records showing the drive is :attr:`HarmonicShapes.drive` (its DC unscaled).

    Returns
    -------
    HarmonicShapes

    Raises
    ------
    DataError
        More than half of the references show no drive (|I_1| below 10 times its noise).
    """
    n_harmonics = response.shape[1]
    amp = np.abs(drive)
    weak = ~(amp >= 10 * drive_std)
    if np.count_nonzero(weak) > 0.5 * len(weak):
        k = int(np.flatnonzero(weak)[0])
        raise DataError(
            f"scan '{source}': {np.count_nonzero(weak)} of {len(weak)} reference records "
            f"show no drive at {f0:.4g} Hz, the first of point {k + 1} (x = "
            f"{points[k, 0]:.4g} m: |I_1| = {amp[k]:.3g} A, noise "
            f"{drive_std[k]:.2g} A); check the reference label and channel")
    n = np.arange(1, n_harmonics + 1)
    u = response
    u_std = response_std
    if quantity == "velocity":
        jw = 1j * n * 2 * np.pi * f0
        u = u / jw
        u_std = u_std / np.abs(jw)
    theta = np.angle(drive)
    # records whose reference shows no drive are kept (with their phase unknown) so that the
    # screening lists them; their scale is 1
    scale = np.where(weak, 1.0, amp[~weak].mean() / np.where(weak, 1.0, amp))
    values = u * np.exp(-1j * np.outer(theta, n)) * scale[:, None]
    std = u_std * scale[:, None]
    mean_drive = None
    if reference is not None:
        turns = np.exp(-1j * np.outer(theta[~weak], np.arange(reference.shape[1])))
        mean_drive = (reference[~weak] * turns * scale[~weak, None]).mean(axis=0)
        mean_drive[0] = reference[~weak, 0].real.mean()
    return HarmonicShapes(points=points, harmonics=n, values=values.T, std=std.T, f0=f0,
                          drive_amplitude=amp, drive_phase=theta, source=source,
                          reference_ok=~weak, drive=mean_drive)
