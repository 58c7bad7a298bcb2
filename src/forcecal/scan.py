"""Scan -> phase-aligned harmonic deflection shapes (METHOD.md section 3, step 1).

For every scan point k the harmonics of the vibration record and of its reference (coil
current) record are fitted by least squares at the fundamental refined from all records
jointly. SLDV velocity becomes displacement, U_n = V_n / (j n w0). Points are measured one after
another, each record starting at its own phase theta_k = arg I_1(k), so harmonic n is aligned by
exp(-j n theta_k) (the corrected eq. 13), and normalized by the record's drive amplitude
|I_1(k)| relative to the mean, which removes a drift of the drive between points.

A scan exported as spectra (:class:`~forcecal.records.ScanSpectra`) gives the same phasors read
off its lines (:mod:`forcecal.scan_spectra`); the conversion, alignment and normalization that
follow are the same, in :func:`aligned_shapes`. A broadband scan's FRFs
(:class:`~forcecal.records.ScanFRF`) are refused: their phases are relative to the reference at
each line.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .checks import check_scan_length
from .errors import DataError, InputError
from .harmonics import fit_harmonics, refine_fundamental
from .records import FRF_PHASE, Scan, ScanFRF, ScanSpectra
from .scan_spectra import spectrum_phasors
from .screening import record_weights

__all__ = ["HarmonicShapes", "aligned_shapes", "harmonic_shapes", "steady_scan"]


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

    def snr(self, keep: np.ndarray | None = None) -> np.ndarray:
        """(n_harm,) RMS shape amplitude over the records divided by the records' median
        noise [1], both judged record by record: the mean square is weighted by each record's
        floored inverse noise variance (:func:`forcecal.screening.record_weights`), so that a
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
        records or as spectra (:func:`forcecal.scan_spectra.spectrum_phasors` says how the
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
        aside, :mod:`forcecal.screening`); spectra whose harmonics are not on lines.
    InputError
        FRFs (a broadband scan's export).
    """
    scan = steady_scan(scan)
    if isinstance(scan, ScanSpectra):
        lines = spectrum_phasors(scan, f0_nominal, n_harmonics)
        return aligned_shapes(scan.points, lines.f0, lines.response, lines.response_std,
                              lines.drive, lines.drive_std, scan.quantity, scan.source)
    check_scan_length(scan, f0_nominal)
    try:
        f0 = refine_fundamental(scan.reference, scan.fs, f0_nominal, n_harmonics)
    except DataError as exc:
        raise DataError(f"scan '{scan.source}': {exc} (the rig's 'acquisition.frequency' is "
                        f"{f0_nominal:g} Hz)") from None
    ref = fit_harmonics(scan.reference, scan.fs, f0, n_harmonics)
    resp = fit_harmonics(scan.response, scan.fs, f0, n_harmonics)
    return aligned_shapes(scan.points, f0, resp.phasors[:, 1:], resp.phasor_std[:, 1:],
                          ref.phasors[:, 1], ref.phasor_std[:, 1], scan.quantity, scan.source)


def aligned_shapes(points: np.ndarray, f0: float, response: np.ndarray,
                   response_std: np.ndarray, drive: np.ndarray, drive_std: np.ndarray,
                   quantity: str, source: str) -> HarmonicShapes:
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
    return HarmonicShapes(points=points, harmonics=n, values=values.T, std=std.T, f0=f0,
                          drive_amplitude=amp, drive_phase=theta, source=source,
                          reference_ok=~weak)
