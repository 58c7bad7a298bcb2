"""SLDV scans in the Universal File Format (UFF), read and written with pyuff (INTERFACES.md
section 2): the scan of METHOD.md section 3, step 1.

A scan file holds the node coordinates (dataset 2411 or 15) and, for every scan point, two
dataset-58 time records (function type 1) whose response node is that point: the vibration
(velocity, ordinate type 11, or displacement, 8) and the reference, the coil current,
recognised by its id line 2 (``Ref1  Current``). A frequency-domain export holds instead the
complex spectra (function type 12) of both, read as a :class:`~forcecal.records.ScanSpectra`;
a broadband scan may be exported as FRFs (4) of the vibration per ampere with their coherence
(6), read as a :class:`~forcecal.records.ScanFRF`, whose noise the rig's
``acquisition.scan_averages`` states. FRFs without coherence, cross spectra (3) and auto
spectra (2, 9) are refused: an FRF's phase is relative to the reference at each line.

Precision of what pyuff writes: coordinates 17 significant digits (exact in float64); ASCII
record values ``%20.11e`` (12 significant digits); binary (58b) values float64, exact; the
abscissa increment ``%13.5e`` (6 significant digits), from which :func:`read_scan_uff`
recovers the sampling rate exactly whenever it has at most 6 significant digits.

The work is done in the private modules ``_uff_sets``, ``_uff_pairs``, ``_uff_read``,
``_uff_spectra``, ``_uff_frf`` and ``_uff_write``, each named for what it holds.
"""

from __future__ import annotations

from ._uff_read import read_scan_uff
from ._uff_sets import read_uff_geometry
from ._uff_write import write_frf_uff, write_scan_uff

__all__ = ["read_scan_uff", "read_uff_geometry", "write_frf_uff", "write_scan_uff"]
