"""SLDV scans in the Universal File Format (UFF), read and written with pyuff.

A scan file holds the node coordinates (dataset 2411 or 15) and, for every scan point, two
dataset-58 time records (function type 1) whose response node is that point: the vibration
(velocity, ordinate type 11, or displacement, ordinate type 8) and the reference, the coil
current, recognised by its id line 2 (``Ref1  Current``). See INTERFACES.md section 2.

A frequency-domain export holds instead, per point, the complex spectra (dataset 58, function
type 12) of the vibration and of the reference, paired and recognised the same way, over one
common set of evenly spaced lines [Hz]; it is read as a :class:`~forcecal.records.ScanSpectra`.
A broadband scan may be exported as FRFs (function type 4) of the vibration per ampere, each
with its coherence (6), paired by response node: it is read as a
:class:`~forcecal.records.ScanFRF`, whose noise the rig's ``acquisition.scan_averages`` states. A
steady drive's model refuses it, and FRFs without coherence, cross spectra (3) and auto spectra
(2, 9) are refused as they are read: an FRF's phase at a line is relative to the reference at
that line, so the harmonics' phases relative to the drive's fundamental (and their amplitudes
relative to each other) cannot be recovered.

Precision of what pyuff writes: coordinates 17 significant digits (exact in float64); ASCII
record values ``%20.11e`` (12 significant digits, relative error at most 5e-12); binary
(58b) record values float64, exact; the abscissa increment ``%13.5e`` (6 significant digits) in
both forms, from which :func:`read_scan_uff` recovers the sampling rate exactly whenever it has
at most 6 significant digits.

The work is done in private modules: ``_uff_sets`` (datasets, codes, units and node
coordinates), ``_uff_pairs`` (records paired by node), ``_uff_read`` (a scan from its time
records; which kind of records a file holds), ``_uff_spectra`` (a scan from its spectra),
``_uff_frf`` (a broadband scan from its FRFs and coherences) and ``_uff_write`` (time records, or
FRFs and coherences).
"""

from __future__ import annotations

from ._uff_read import read_scan_uff
from ._uff_sets import read_uff_geometry
from ._uff_write import write_frf_uff, write_scan_uff

__all__ = ["read_scan_uff", "read_uff_geometry", "write_frf_uff", "write_scan_uff"]
