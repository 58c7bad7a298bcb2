"""The virtual SLDV's FRF export: a broadband scan's time records turned into the FRFs and
coherences SLDV software writes when asked for them, and the number of averages behind them.

The software averages the cross and auto spectra of response and reference over segments of the
record: over the drive's whole periods with no window when the drive is periodic in the record
(a periodic chirp, periodic random), else over Hann windows of 1 / ``SEGMENT`` of the record
overlapping by half (15 averages). H1 = S_rx / S_rr and the ordinary coherence
|S_rx|^2 / (S_rr S_xx) are exported on every line from the first above 0 Hz up to ``top``.
"""

from __future__ import annotations

import numpy as np
import scipy.signal

from ..model.frf import periods_in_record
from ..records import Scan, ScanFRF

__all__: list[str] = []

SEGMENT = 8
"""A drive not periodic in the record is averaged over Hann segments of 1 / SEGMENT of it."""


def frf_export(scan: Scan, band: tuple[float, float], top: float) -> tuple[ScanFRF, int]:
    """The FRFs and coherences of a broadband scan, as SLDV software exports them.

    Parameters
    ----------
    scan : Scan
        Time records under a broadband drive, the coil current as reference.
    band : (low, high) [Hz]
        The drive's band (a periodic drive is found from the reference's lines in it).
    top : float [Hz]
        The highest line exported.

    Returns
    -------
    frfs : ScanFRF
        Per point H1 of the vibration (the scan's quantity) per ampere, and its coherence.
    averages : int
        The segments averaged.
    """
    n = scan.n_samples
    periods = periods_in_record(scan.reference, scan.fs, band)
    if periods:
        segment, window, overlap = n // periods, "boxcar", 0
    else:
        segment, window = n // SEGMENT, "hann"
        overlap = segment // 2
    kw = {"fs": scan.fs, "nperseg": segment, "noverlap": overlap, "window": window,
          "detrend": "constant", "axis": -1}
    f, s_rr = scipy.signal.welch(scan.reference, **kw)
    _, s_xx = scipy.signal.welch(scan.response, **kw)
    _, s_rx = scipy.signal.csd(scan.reference, scan.response, **kw)
    lines = (f > 0) & (f <= top)
    tiny = np.finfo(float).tiny
    s_rr, s_xx, s_rx = s_rr[:, lines], s_xx[:, lines], s_rx[:, lines]
    frfs = ScanFRF(points=scan.points, frequencies=f[lines],
                   values=s_rx / np.maximum(s_rr, tiny),
                   coherence=np.clip(np.abs(s_rx) ** 2 / np.maximum(s_rr * s_xx, tiny), 0, 1),
                   quantity=scan.quantity, source=scan.source)
    return frfs, (n - segment) // (segment - overlap) + 1
