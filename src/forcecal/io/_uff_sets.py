"""Universal File datasets as pyuff reads them: dataset numbers and codes shared by the scan
reader and writer, every dataset of a file, its length unit and its node coordinates.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pyuff

from ..errors import InputError

__all__: list[str] = []

TIME_RESPONSE = 1  # dataset 58 function type "time response"
SPECTRUM = 12  # dataset 58 function type "spectrum" (complex lines over frequency)
QUANTITY_OF_ORDINATE = {11: "velocity", 8: "displacement"}
ORDINATE_OF_QUANTITY = {
    "velocity": (11, "m/s", "Velocity"),
    "displacement": (8, "m", "Displacement"),
}
COORDINATE_SETS = (2411, 15)
TIME_ABSCISSA = 17  # abscissa specific data type "time"
FREQUENCY_ABSCISSA = 18  # abscissa specific data type "frequency"
GENERAL_ORDINATE = 0  # ordinate specific data type "general" (used for the current)
PLUS_Z = 3
RATE_DIGITS = 6  # significant digits of the abscissa increment as a UFF stores it (E13.5)


def read_uff_geometry(path: str | Path) -> dict[int, tuple[float, float, float]]:
    """Node coordinates of a Universal File (datasets 2411 or 15), in metres.

    A units dataset 164 converts the file's length unit to metres (SI = value / factor).

    Parameters
    ----------
    path : str or Path
        The ``.uff``/``.unv`` file.

    Returns
    -------
    dict
        node number -> (x, y, z) [m].

    Raises
    ------
    InputError
        The file is missing, is not a Universal File, has no node coordinates, or gives a
        length unit factor that is not a positive number.
    """
    sets = read_sets(path, "UFF")
    return geometry_of(sets, path, "UFF")


def read_sets(path: str | Path, what: str) -> list[dict]:
    """All datasets of a Universal File as pyuff dictionaries; one-line errors otherwise."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{what} '{path}': file does not exist")
    try:
        # a non-finite value in a complex record makes numpy warn as pyuff assembles it; the
        # readers refuse such a record in one line, naming its node
        with np.errstate(invalid="ignore", over="ignore"):
            sets = pyuff.UFF(str(path)).read_sets()
    except Exception as exc:  # pyuff raises bare Exception on anything malformed
        raise InputError(
            f"{what} '{path}': not a readable Universal File (pyuff: {first_line(exc)})"
        ) from exc
    if isinstance(sets, dict):  # pyuff returns a lone dataset unwrapped
        sets = [sets]
    sets = [s for s in sets if isinstance(s, dict) and set_type(s) > 0]  # 0: garbage block
    if not sets:
        raise InputError(f"{what} '{path}': not a Universal File (no dataset found)")
    return sets


def geometry_of(
    sets: Sequence[dict], path: str | Path, what: str
) -> dict[int, tuple[float, float, float]]:
    """node -> (x, y, z) [m] from every dataset 2411 and 15 (a later one overrides)."""
    factor = length_factor(sets, path)
    geometry: dict[int, tuple[float, float, float]] = {}
    for dataset in sets:
        if set_type(dataset) in COORDINATE_SETS:
            geometry.update(nodes_of(dataset, path, factor))
    if not geometry:
        raise InputError(
            f"{what} '{path}': no node coordinates (dataset 2411 or 15); "
            f"found datasets {type_list(sets)}"
        )
    return geometry


def nodes_of(dataset: dict, path: str | Path, factor: float) -> dict[int, tuple]:
    """Coordinates of one node dataset, converted to metres."""
    try:
        nums = np.asarray(dataset["node_nums"], dtype=float)
        xyz = np.array([dataset[k] for k in ("x", "y", "z")], dtype=float) / factor
    except (KeyError, ValueError) as exc:
        raise InputError(
            f"UFF '{path}': dataset {set_type(dataset)} (nodes) is malformed"
        ) from exc
    if xyz.shape != (3, nums.size) or not np.all(np.isfinite(xyz)):
        raise InputError(f"UFF '{path}': dataset {set_type(dataset)} (nodes) is malformed")
    return {
        int(n): (float(x), float(y), float(z)) for n, (x, y, z) in zip(nums, xyz.T, strict=True)
    }


def length_factor(sets: Sequence[dict], path: str | Path) -> float:
    """Length unit factor of the first dataset 164 (file value / factor = metres), else 1."""
    for dataset in sets:
        if set_type(dataset) == 164:
            factor = float(dataset.get("length", 1.0))
            if not np.isfinite(factor) or factor <= 0:
                raise InputError(
                    f"UFF '{path}': dataset 164 gives length unit factor {factor}; "
                    "expected a positive number"
                )
            return factor
    return 1.0


def set_type(dataset: dict) -> int:
    """A dataset's number (58, 2411, ...), or -1 when pyuff gave none."""
    try:
        return int(dataset.get("type", -1))
    except (TypeError, ValueError):
        return -1


def type_list(sets: Sequence[dict]) -> str:
    """The dataset numbers found, for a message: '15, 58, 164' or 'none'."""
    types = sorted({set_type(s) for s in sets})
    return ", ".join(str(t) for t in types) if types else "none"


def first_line(exc: BaseException) -> str:
    """The first line of an exception's message (its type name when it has none)."""
    text = str(exc).strip() or type(exc).__name__
    return text.splitlines()[0]
