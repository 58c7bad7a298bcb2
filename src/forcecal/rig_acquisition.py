"""The rig file's ``[acquisition]`` table: how the scan and the runs were taken (INTERFACES.md
section 1): the drive's nominal frequency, the runs' group, the ambient temperature, the mains
frequency, and for a broadband scan its band, the drive's kind and the averages behind its FRFs.
"""

from __future__ import annotations

from typing import Any

from ._toml import TableReader

__all__ = ["DRIVES", "read_acquisition"]


def read_acquisition(r: TableReader, acq: dict[str, Any]) -> dict[str, Any]:
    """The ``[acquisition]`` keys as :class:`forcecal.rig.Rig` fields.

    Returns
    -------
    dict
        ``frequency``, ``run_group``, ``temperature``, ``mains``, ``band``, ``drive`` and
        ``scan_averages`` (None where a key is absent; ``drive`` "steady").

    Raises
    ------
    RigError
        A key out of its range or inconsistent with another, named.
    """
    keys: dict[str, Any] = {
        "frequency": r.number(acq, "frequency", "acquisition", required=False, positive=True),
        "run_group": r.text(acq, "group", "acquisition", required=False, default=None),
        "temperature": _temperature(r, acq),
        "mains": r.number(acq, "mains", "acquisition", required=False, positive=True)}
    mains = keys["mains"]
    if mains is not None and not 10.0 <= mains <= 1000.0:
        raise r.fail("acquisition.mains", f"= {mains!r} Hz is not a mains frequency (50 or 60)")
    keys["band"], keys["drive"] = _drive_band(r, acq)
    keys["scan_averages"] = _scan_averages(r, acq, keys["band"])
    return keys


DRIVES = ("steady", "any")
"""What ``acquisition.drive`` may say."""


def _drive_band(r: TableReader, acq: dict[str, Any]) -> tuple[tuple[float, float] | None, str]:
    """``acquisition.band`` [Hz] (None when absent) and ``acquisition.drive``."""
    drive = r.text(acq, "drive", "acquisition", required=False, default="steady")
    if drive not in DRIVES:
        raise r.fail("acquisition.drive", f"= {drive!r} is not one of {', '.join(DRIVES)}")
    band = None
    if "band" in acq:
        lo, hi = r.vector(acq, "band", "acquisition", 2, "a band (low, high) in Hz")
        if not 0.0 <= lo < hi:
            raise r.fail("acquisition.band", f"= [{lo!r}, {hi!r}] Hz is not a band "
                         "(0 <= low < high)")
        band = (float(lo), float(hi))
    if drive == "any" and band is None:
        raise r.fail("acquisition.drive", "= 'any' needs 'acquisition.band', the band a "
                     "broadband scan covered")
    return band, drive


def _scan_averages(r: TableReader, acq: dict[str, Any], band: tuple[float, float] | None
                   ) -> int | None:
    """``acquisition.scan_averages``: a whole number of averages, for a broadband scan."""
    n = r.number(acq, "scan_averages", "acquisition", required=False, positive=True)
    if n is None:
        return None
    if n != int(n) or n > 1e6:
        raise r.fail("acquisition.scan_averages", f"= {n!r} is not a number of averages (a "
                     "whole number, 2 to 1e6)")
    if n < 2:
        raise r.fail("acquisition.scan_averages", f"= {int(n)}: the coherence of one average is "
                     "1 on every line and states no noise; FRFs need 2 or more averages")
    if band is None:
        raise r.fail("acquisition.scan_averages", "serves a broadband scan's FRFs; give "
                     "'acquisition.band' too")
    return int(n)


_TEMPERATURE_RANGE_C = (-100.0, 200.0)
"""Ambient temperatures ``acquisition.temperature`` may give [°C]; beyond is probably kelvin."""


def _temperature(r: TableReader, acq: dict[str, Any]) -> float | None:
    """``acquisition.temperature`` [°C], or None when absent."""
    value = r.number(acq, "temperature", "acquisition", required=False)
    lo, hi = _TEMPERATURE_RANGE_C
    if value is not None and not lo <= value <= hi:
        raise r.fail("acquisition.temperature", f"= {value!r} °C is not an ambient temperature "
                     f"between {lo:g} and {hi:g} °C (23.0 for 23 °C; not in kelvin)")
    return value
